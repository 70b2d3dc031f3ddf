// Synthetic skull CT phantom: an ellipsoidal braincase inside an ellipsoidal bone shell, with
// diploic voids, foramina, a crack, scalp and neck, and optionally a cervical spine, a frontal sinus
// with the nasal cavity, orbits with optic canals, shoulders and a CT couch in a large field of
// view, or a volume cropped at the skull base; rendered with analytic partial volume.
//
// Rendering: each voxel is composed in three layers, each blended with the Gaussian-blurred step
// (erfc) of its signed distance: (1) what lies outside the skull (air, couch, soft tissue, spine,
// clavicles), (2) the skull (outer ellipsoid plus the facial bone) with its carvings (diploic voids,
// openings, sinus and nasal air, orbits), (3) the braincase content inside the inner ellipsoid.
// Layer 3 is painted last and every carving keeps clear of its blur band except the openings, so
// the isovalue crossing of the inner surface is the ellipsoid wherever there is no opening.
#include "endocast/phantom.h"
#include "phantom/phantom_internal.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <vector>

namespace endocast {

namespace {

using namespace phantom_detail;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- Hounsfield units (the shared ones are in phantom/phantom_internal.h) ---------------------
constexpr double kBodyTissue = 40.0;   // shoulders and chest
constexpr double kEye = 10.0;          // vitreous
constexpr double kCouchSkin = 400.0;   // carbon-fibre skins of the couch
constexpr double kCouchCore = 280.0;   // couch core
constexpr double kDiploeWet = 200.0;   // marrow-filled diploic void (Human, Macaque)
constexpr double kDiploeDry = -400.0;  // air-filled diploic void (Dry), below the Dry iso (200)

struct SplitMix64 {
    uint64_t state;
    uint64_t next() { return splitmix64_mix(state += 0x9E3779B97F4A7C15ULL); }
    double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
};

// ---- exact point-to-ellipse/ellipsoid distance (Eberly 2013) ------------------------------
// Points in the first quadrant/octant, semi-axes sorted e0 >= e1 (>= e2). The closest point
// x_i = r_i y_i / (s + r_i) is found by bisection on s of F(s) = sum (r_i z_i / (s + r_i))^2 - 1,
// which is monotone; bisection stops when the midpoint equals an end (full double precision).

double robust_length(double a, double b) {
    const double m = std::max(std::fabs(a), std::fabs(b));
    if (m == 0) return 0;
    return m * std::sqrt((a / m) * (a / m) + (b / m) * (b / m));
}
double robust_length(double a, double b, double c) {
    const double m = std::max({std::fabs(a), std::fabs(b), std::fabs(c)});
    if (m == 0) return 0;
    return m * std::sqrt((a / m) * (a / m) + (b / m) * (b / m) + (c / m) * (c / m));
}

double root2(double r0, double z0, double z1, double g) {
    const double n0 = r0 * z0;
    double s0 = z1 - 1.0, s1 = g < 0 ? 0.0 : robust_length(n0, z1) - 1.0, s = 0;
    for (int it = 0; it < 2200; ++it) {
        s = 0.5 * (s0 + s1);
        if (s == s0 || s == s1) break;
        const double a = n0 / (s + r0), b = z1 / (s + 1.0);
        const double f = a * a + b * b - 1.0;
        if (f > 0) s0 = s;
        else if (f < 0) s1 = s;
        else break;
    }
    return s;
}

/// Distance from (y0, y1) >= 0 to the ellipse with semi-axes e0 >= e1 > 0; closest point in x.
double dist_ellipse_q(double e0, double e1, double y0, double y1, double& x0, double& x1) {
    if (y1 > 0) {
        if (y0 > 0) {
            const double z0 = y0 / e0, z1 = y1 / e1, g = z0 * z0 + z1 * z1 - 1.0;
            if (g != 0) {
                const double r0 = (e0 / e1) * (e0 / e1);
                const double sb = root2(r0, z0, z1, g);
                x0 = r0 * y0 / (sb + r0);
                x1 = y1 / (sb + 1.0);
                return std::hypot(x0 - y0, x1 - y1);
            }
            x0 = y0;
            x1 = y1;
            return 0.0;
        }
        x0 = 0;
        x1 = e1;
        return std::fabs(y1 - e1);
    }
    const double numer0 = e0 * y0, denom0 = e0 * e0 - e1 * e1;
    if (numer0 < denom0) {
        const double xde0 = numer0 / denom0;
        x0 = e0 * xde0;
        x1 = e1 * std::sqrt(std::max(0.0, 1.0 - xde0 * xde0));
        return std::hypot(x0 - y0, x1);
    }
    x0 = e0;
    x1 = 0;
    return std::fabs(y0 - e0);
}

double root3(double r0, double r1, double z0, double z1, double z2, double g) {
    const double n0 = r0 * z0, n1 = r1 * z1;
    double s0 = z2 - 1.0, s1 = g < 0 ? 0.0 : robust_length(n0, n1, z2) - 1.0, s = 0;
    for (int it = 0; it < 2200; ++it) {
        s = 0.5 * (s0 + s1);
        if (s == s0 || s == s1) break;
        const double a = n0 / (s + r0), b = n1 / (s + r1), c = z2 / (s + 1.0);
        const double f = a * a + b * b + c * c - 1.0;
        if (f > 0) s0 = s;
        else if (f < 0) s1 = s;
        else break;
    }
    return s;
}

/// Distance from y >= 0 (componentwise) to the ellipsoid e0 >= e1 >= e2 > 0; closest point in x.
double dist_ellipsoid_q(const double e[3], const double y[3], double x[3]) {
    if (y[2] > 0) {
        if (y[1] > 0) {
            if (y[0] > 0) {
                const double z0 = y[0] / e[0], z1 = y[1] / e[1], z2 = y[2] / e[2];
                const double g = z0 * z0 + z1 * z1 + z2 * z2 - 1.0;
                if (g != 0) {
                    const double r0 = (e[0] / e[2]) * (e[0] / e[2]);
                    const double r1 = (e[1] / e[2]) * (e[1] / e[2]);
                    const double sb = root3(r0, r1, z0, z1, z2, g);
                    x[0] = r0 * y[0] / (sb + r0);
                    x[1] = r1 * y[1] / (sb + r1);
                    x[2] = y[2] / (sb + 1.0);
                    return robust_length(x[0] - y[0], x[1] - y[1], x[2] - y[2]);
                }
                x[0] = y[0];
                x[1] = y[1];
                x[2] = y[2];
                return 0.0;
            }
            x[0] = 0;
            return dist_ellipse_q(e[1], e[2], y[1], y[2], x[1], x[2]);
        }
        if (y[0] > 0) {
            x[1] = 0;
            return dist_ellipse_q(e[0], e[2], y[0], y[2], x[0], x[2]);
        }
        x[0] = x[1] = 0;
        x[2] = e[2];
        return std::fabs(y[2] - e[2]);
    }
    const double denom0 = e[0] * e[0] - e[2] * e[2], denom1 = e[1] * e[1] - e[2] * e[2];
    const double numer0 = e[0] * y[0], numer1 = e[1] * y[1];
    if (numer0 < denom0 && numer1 < denom1) {
        const double xde0 = numer0 / denom0, xde1 = numer1 / denom1;
        const double discr = 1.0 - xde0 * xde0 - xde1 * xde1;
        if (discr > 0) {
            x[0] = e[0] * xde0;
            x[1] = e[1] * xde1;
            x[2] = e[2] * std::sqrt(discr);
            return robust_length(x[0] - y[0], x[1] - y[1], x[2]);
        }
    }
    x[2] = 0;
    return dist_ellipse_q(e[0], e[1], y[0], y[1], x[0], x[1]);
}

/// Unsigned distance from (p0, p1) to the curve of the ellipse with semi-axes a0, a1 (any order).
double ellipse_curve_distance(double a0, double a1, double p0, double p1) {
    const bool swap = a1 > a0;
    const double e0 = swap ? a1 : a0, e1 = swap ? a0 : a1;
    const double y0 = std::fabs(swap ? p1 : p0), y1 = std::fabs(swap ? p0 : p1);
    double x0, x1;
    return dist_ellipse_q(e0, e1, y0, y1, x0, x1);
}

// ---- signed distances (negative inside) ---------------------------------------------------
/// Approximate signed distance to an axis-aligned ellipsoid centred at 0 with semi-axes r; its zero
/// set is exactly the ellipsoid and it is first-order exact near the surface.
double ellipsoid_sd(const Vec3& p, const Vec3& r) {
    const double qx = p[0] / r[0], qy = p[1] / r[1], qz = p[2] / r[2];
    const double k0 = std::sqrt(qx * qx + qy * qy + qz * qz);
    const double wx = qx / r[0], wy = qy / r[1], wz = qz / r[2];
    const double k1 = std::sqrt(wx * wx + wy * wy + wz * wz);
    if (k1 < 1e-12) return -std::min({r[0], r[1], r[2]});
    return k0 * (k0 - 1.0) / k1;
}

/// The same for an axis-aligned ellipse (x, y) centred at 0 with semi-axes (rx, ry).
double ellipse_sd(double x, double y, double rx, double ry) {
    const double qx = x / rx, qy = y / ry;
    const double k0 = std::sqrt(qx * qx + qy * qy);
    const double wx = qx / rx, wy = qy / ry;
    const double k1 = std::sqrt(wx * wx + wy * wy);
    if (k1 < 1e-12) return -std::min(rx, ry);
    return k0 * (k0 - 1.0) / k1;
}

/// Spheroid with symmetry axis n: semi-axis rn along n, rt across.
double spheroid_sd(const Vec3& q, const Vec3& n, double rn, double rt) {
    const double a = dot(q, n);
    const double t2 = std::max(0.0, dot(q, q) - a * a);
    const double k0 = std::sqrt(t2 / (rt * rt) + a * a / (rn * rn));
    const double k1 = std::sqrt(t2 / (rt * rt * rt * rt) + a * a / (rn * rn * rn * rn));
    if (k1 < 1e-12) return -std::min(rn, rt);
    return k0 * (k0 - 1.0) / k1;
}

/// Smooth indicator of "inside" (d < 0): the Gaussian blur of a planar edge, or a hard step.
struct Step {
    double sigma = 0;  // 0: hard step
    double band = 0;
    double inv = 0;
    double operator()(double d) const {
        if (sigma <= 0) return d < 0 ? 1.0 : (d > 0 ? 0.0 : 0.5);
        if (d <= -band) return 1.0;
        if (d >= band) return 0.0;
        return 0.5 * std::erfc(d * inv);
    }
};

double mix(double a, double b, double t) { return a + (b - a) * t; }

// ---- features carved into the shell ---------------------------------------------------------
enum class FeatureKind { Void, Capsule, Box, HalfCylinder, Cone, Ellipsoid };

/// What a carving puts into the skull: a diploic void, an opening of the braincase (content),
/// air (sinus, nasal cavity) or orbital content.
enum class Carve { Void, Opening, Air, Orbit };

struct Feature {
    FeatureKind kind = FeatureKind::Void;
    Carve carve = Carve::Void;
    Vec3 c{0, 0, 0};       // centre (Void, Box, Ellipsoid); start (Capsule); apex (Cone);
                           // axis point (HalfCylinder)
    Vec3 u{0, 0, 1};       // Void: symmetry axis; Capsule, Cone: unit axis; Box: first axis
    Vec3 v{0, 0, 0};       // Box: second axis
    Vec3 w{0, 0, 0};       // Box: third axis
    Vec3 half{0, 0, 0};    // Box, Ellipsoid half sizes; Void: (rn, rt, -)
    double length = 0;     // Capsule, Cone length
    double radius = 0;     // Capsule / HalfCylinder radius; Cone: radius at `length`
    double z_top = 0;      // HalfCylinder: exists for z <= z_top (axis along z)
    Vec3 bound_c{0, 0, 0}; // bounding sphere (already widened by the blend band)
    double bound_r = 0;    // infinite for HalfCylinder

    double sd(const Vec3& p) const {
        const Vec3 q = sub(p, c);
        switch (kind) {
            case FeatureKind::Void:
                return spheroid_sd(q, u, half[0], half[1]);
            case FeatureKind::Capsule: {
                const double t = std::clamp(dot(q, u), 0.0, length);
                return norm(sub(q, mul(u, t))) - radius;
            }
            case FeatureKind::Box:
                return std::max({std::fabs(dot(q, u)) - half[0], std::fabs(dot(q, v)) - half[1],
                                 std::fabs(dot(q, w)) - half[2]});
            case FeatureKind::HalfCylinder: {
                const double rho = std::sqrt(q[0] * q[0] + q[1] * q[1]);
                return std::max(rho - radius, p[2] - z_top);
            }
            case FeatureKind::Cone: {
                // Distance to the lateral surface (exact near it), capped by the base plane.
                const double a = dot(q, u);
                const double rho = std::sqrt(std::max(0.0, dot(q, q) - a * a));
                const double l = std::hypot(length, radius);
                const double side = (rho * length - a * radius) / l;
                return std::max({side, -a, a - length});
            }
            case FeatureKind::Ellipsoid:
                return ellipsoid_sd(q, half);
        }
        return kInf;
    }
};

struct PresetSpec {
    Vec3 inner;                 // braincase semi-axes, mm
    double thickness;           // skull, mm
    double scalp;               // soft tissue around the skull, mm (0: none)
    double neck_radius;         // 0: no neck
    double content;             // HU inside the braincase
    double diploe;              // HU of diploic voids
    double spacing;             // default mm
    double scale;               // size of openings / voids relative to the human ones
    double fm_radius;           // foramen magnum radius, mm
    double crack_width;         // mm
    int void_count;
    double canal_radius;        // spinal canal, mm
    double optic_radius;        // default optic canal radius, mm
};

PresetSpec preset_spec(PhantomPreset p) {
    switch (p) {
        case PhantomPreset::Human:
            return {{65, 82, 60}, 6.0, 5.0, 45.0, kBrain, kDiploeWet, 1.0, 1.0, 14.0, 1.0, 40,
                    8.0, 7.0};
        case PhantomPreset::Dry:
            return {{65, 82, 60}, 6.0, 0.0, 0.0, kAir, kDiploeDry, 1.0, 1.0, 14.0, 1.0, 40,
                    8.0, 7.0};
        case PhantomPreset::Macaque:
            return {{26, 34, 24}, 2.5, 2.0, 18.0, kBrain, kDiploeWet, 0.5, 0.4, 5.5, 0.5, 30,
                    3.5, 3.5};
        case PhantomPreset::Mouse:  // only the anatomical mouse phantom (phantom/rodent.cpp)
            break;
    }
    throw InvalidParameter("unknown phantom preset");
}

/// Point of the ellipsoid with semi-axes r on the ray from 0 along dir.
Vec3 ellipsoid_point(const Vec3& dir, const Vec3& r) {
    const Vec3 d = normalized(dir);
    const double k = std::sqrt((d[0] / r[0]) * (d[0] / r[0]) + (d[1] / r[1]) * (d[1] / r[1]) +
                               (d[2] / r[2]) * (d[2] / r[2]));
    return mul(d, 1.0 / k);
}

Vec3 ellipsoid_normal(const Vec3& p, const Vec3& r) {
    return normalized({p[0] / (r[0] * r[0]), p[1] / (r[1] * r[1]), p[2] / (r[2] * r[2])});
}

Vec3 add_scalar(const Vec3& a, double s) { return {a[0] + s, a[1] + s, a[2] + s}; }

/// Half extents (world axes) of an axis-aligned ellipsoid rotated by tilt about x.
Vec3 rotated_half_extent(const Vec3& r, double cs, double sn) {
    return {r[0], std::sqrt(cs * cs * r[1] * r[1] + sn * sn * r[2] * r[2]),
            std::sqrt(sn * sn * r[1] * r[1] + cs * cs * r[2] * r[2])};
}


struct RowFeature {
    const Feature* f;
    int64_t x0, x1;  // voxel range of the row that can be affected
};

/// Volume (mm^3) of the part of the ellipsoid (semi-axes a, rotated by tilt about x) above the
/// world plane z = h (relative to the centre): the ellipsoid is the affine image of the unit ball,
/// the plane cuts it at t = h / (half height); the cut-off cap has height 1 + t.
double ellipsoid_volume_above(const Vec3& a, double cs, double sn, double h) {
    const double half = std::sqrt(sn * sn * a[1] * a[1] + cs * cs * a[2] * a[2]);
    const double t = std::clamp(h / half, -1.0, 1.0);
    const double H = 1.0 + t;
    return a[0] * a[1] * a[2] * (4.0 / 3.0 * kPi - kPi * H * H * (3.0 - H) / 3.0);
}

}  // namespace

PhantomPreset parse_phantom_preset(const std::string& s) {
    std::string l = s;
    std::transform(l.begin(), l.end(), l.begin(), [](unsigned char ch) { return std::tolower(ch); });
    if (l == "human") return PhantomPreset::Human;
    if (l == "dry") return PhantomPreset::Dry;
    if (l == "macaque") return PhantomPreset::Macaque;
    if (l == "mouse" || l == "rodent") return PhantomPreset::Mouse;
    throw InvalidParameter("phantom preset '" + s +
                           "' is unknown, expected human, dry, macaque or mouse (alias rodent)");
}

std::string to_string(PhantomPreset p) {
    switch (p) {
        case PhantomPreset::Human: return "human";
        case PhantomPreset::Dry: return "dry";
        case PhantomPreset::Macaque: return "macaque";
        case PhantomPreset::Mouse: return "mouse";
    }
    return "unknown";
}

PhantomParams human_full_phantom_params() {
    PhantomParams p;
    p.preset = PhantomPreset::Human;
    p.spine = true;
    p.frontal_sinus = true;
    p.orbits = true;
    return p;
}

double ellipsoid_signed_distance(const Vec3& p, const Vec3& semi, Vec3* closest) {
    for (int a = 0; a < 3; ++a)
        if (!(semi[a] > 0) || !std::isfinite(semi[a]))
            throw InvalidParameter("ellipsoid semi-axis " + std::to_string(a) + " is " +
                                   fmt(semi[a]) + ", expected > 0");
    // Sort the axes by decreasing length, reflect into the first octant.
    int order[3] = {0, 1, 2};
    std::sort(order, order + 3, [&](int i, int j) { return semi[i] > semi[j]; });
    double e[3], y[3], x[3];
    for (int i = 0; i < 3; ++i) {
        e[i] = semi[order[i]];
        y[i] = std::fabs(p[order[i]]);
    }
    const double d = dist_ellipsoid_q(e, y, x);
    const double g = (p[0] / semi[0]) * (p[0] / semi[0]) + (p[1] / semi[1]) * (p[1] / semi[1]) +
                     (p[2] / semi[2]) * (p[2] / semi[2]);
    if (closest)
        for (int i = 0; i < 3; ++i)
            (*closest)[order[i]] = p[order[i]] < 0 ? -x[i] : x[i];
    return g < 1.0 ? -d : d;
}

double phantom_cavity_signed_distance(const PhantomResult& r, const Vec3& world) {
    if (r.skull_base) return r.skull_base->signed_distance(r.skull_base->to_phantom(world));
    const auto& R = r.cavity_rotation;
    const Vec3 w = sub(world, r.cavity_centre_world);
    // q = R^T w (phantom frame); distances are the same in both frames.
    const Vec3 q{R[0] * w[0] + R[3] * w[1] + R[6] * w[2], R[1] * w[0] + R[4] * w[1] + R[7] * w[2],
                 R[2] * w[0] + R[5] * w[1] + R[8] * w[2]};
    const Vec3& a = r.cavity_semi_axes_mm;
    Vec3 x{0, 0, 0};
    const double dE = ellipsoid_signed_distance(q, a, &x);
    if (!r.cropped) return dE;
    // Half-space H: world z >= plane, i.e. n.q >= h with n = R^T e_z (third row of R).
    const Vec3 n{R[6], R[7], R[8]};
    const double h = r.crop_plane_z_mm - r.cavity_centre_world[2];
    const double dp = dot(n, q) - h;  // > 0 inside H
    if (dE <= 0 && dp >= 0) return -std::min(-dE, dp);
    double best = kInf;
    // (a) the nearest point of the ellipsoid, when it lies in H.
    if (dE > 0 && dot(n, x) >= h) best = std::min(best, dE);
    // (b) the flat cap: the projection onto the plane, when it lies in the ellipsoid.
    if (dp < 0) {
        const Vec3 pr = sub(q, mul(n, dp));
        const double g = (pr[0] / a[0]) * (pr[0] / a[0]) + (pr[1] / a[1]) * (pr[1] / a[1]) +
                         (pr[2] / a[2]) * (pr[2] / a[2]);
        if (g <= 1.0) best = std::min(best, -dp);
    }
    // (c) the rim: the ellipse E ∩ plane. In-plane basis e1 = x, e2 = n x e1; points of the plane
    // h n + X e1 + Y e2 satisfy X^2/a0^2 + alpha Y^2 + 2 beta Y + gamma = 1.
    const Vec3 e1{1, 0, 0};
    const Vec3 e2 = cross(n, e1);
    const Vec3 c0 = mul(n, h);
    auto quad = [&](const Vec3& v) {  // v^T D^-2 v
        return (v[0] / a[0]) * (v[0] / a[0]) + (v[1] / a[1]) * (v[1] / a[1]) +
               (v[2] / a[2]) * (v[2] / a[2]);
    };
    auto bil = [&](const Vec3& u, const Vec3& v) {
        return u[0] * v[0] / (a[0] * a[0]) + u[1] * v[1] / (a[1] * a[1]) +
               u[2] * v[2] / (a[2] * a[2]);
    };
    const double alpha = quad(e2), beta = bil(c0, e2), gamma = quad(c0);
    // e1 is an axis of the ellipsoid and orthogonal to n: no X*Y or X terms.
    const double rho = 1.0 - gamma + beta * beta / alpha;
    if (rho > 0) {
        const double Y0 = -beta / alpha;
        const double AX = a[0] * std::sqrt(rho), AY = std::sqrt(rho / alpha);
        const double X = dot(q, e1), Y = dot(q, e2) - Y0;
        const double d2 = ellipse_curve_distance(AX, AY, X, Y);
        best = std::min(best, std::hypot(d2, dp));
    }
    return best;
}

bool phantom_near_opening(const PhantomResult& r, const Vec3& world, double margin_mm) {
    for (const PhantomOpening& o : r.openings) {
        const Vec3 v = sub(world, o.centre_world);
        const double h = dot(v, o.axis_world);
        const double radial = norm(sub(v, mul(o.axis_world, h)));
        const double out = std::max(0.0, radial - o.radius_mm);
        if (std::hypot(h, out) <= margin_mm) return true;
    }
    return false;
}

namespace {

/// A row of voxels (fixed j, k) in the phantom frame, with the features that can reach it.
struct Row {
    Vec3 rel{0, 0, 0};  // world position of voxel 0, relative to the cavity centre
    double qx0 = 0, qy = 0, qz = 0, row_r2 = 0;
    std::vector<RowFeature> features;
    double sy = 0;          // y distance from the spinal canal's axis
    bool spine_row = false;
    double ring_dz = kInf;  // signed distance of the row from the spine's rings along z
    bool couch_row = false, chest_row = false, clavicle_row = false;
    int16_t* out = nullptr;
};

/// What the skull layers (2 and 3) give a voxel: pure content, or the blend weights and the shell.
struct SkullSample {
    double v = 0;
    bool inside = false;
    double s_in = 0.0, s_bone = 0.0, shell = kBoneHu;
};

/// The ellipsoidal braincase phantom of generate_phantom, built in steps: validation, geometry in
/// the phantom frame, the grid, the openings and carvings, the diploic voids, rendering, result.
struct BraincasePhantom {
    const PhantomParams& p;
    PresetSpec spec;
    bool has_soft;
    Vec3 spacing;

    // Geometry in the phantom frame.
    Vec3 inner, outer, scalp_axes, inner_half;
    double T = 0, s = 0, cs = 0, sn = 0;
    bool crop = false;
    Step step;
    double band = 0;
    bool face = false;
    Vec3 face_c, face_axes, face_soft_axes;
    double fm_y = 0, canal_r = 0, wall = 0, ring_h = 0, ring_gap = 0, period = 0, ring_top = 0;
    double body_r = 0, body_y = 0, pillar_x = 0, pillar_r = 0, spine_reach = 0;
    int automatic_rings = 7;
    double couch_R = 0, couch_T = 0, couch_half_w = 0, couch_skin = 0, couch_top = 0;
    double couch_sag = 0, couch_axis_y = 0, chest_y = 0, chest_cap_z = 0, clavicle_r = 0;
    Vec3 chest_axes;

    // The grid.
    Vec3 lo, hi;
    Dims dims{};
    Geometry geom;
    Vec3 centre;

    // Openings and carvings.
    double content = 0, fill = 0;
    std::vector<Feature> openings;  // Carve::Opening, then Carve::Air and Carve::Orbit
    std::vector<PhantomOpening> listed;
    Vec3 fm_inner;
    std::vector<Feature> nostrils;
    struct Eye { Vec3 c; double r; };
    std::vector<Eye> eyes;
    double optic_r = 0;
    std::vector<Feature> voids;

    // Rendering.
    PhantomResult res;
    bool slabs = false;      ///< rendered by generate_phantom_slabs (the size limit)
    int16_t* out = nullptr;  ///< the voxels of slice k_base onwards (render's dst)
    int64_t k_base = 0;
    double diploe = 0, soft = 0, orbit_fill = 0;
    uint64_t noise_key = 0;
    bool noise = false;
    double neck_r = 0;
    int64_t nx = 0, ny = 0, nz = 0;
    double skull_far2 = 0, head_far2 = 0, spine_far = 0;
    std::vector<Feature> clavicles;

    explicit BraincasePhantom(const PhantomParams& params)
        : p(params), spec(preset_spec(params.preset)),
          has_soft(params.preset != PhantomPreset::Dry && params.scalp) {}

    // world = centre + R * q, R = rotation about x; q = R^T * (world - centre).
    Vec3 to_world_dir(const Vec3& q) const { return {q[0], cs * q[1] - sn * q[2], sn * q[1] + cs * q[2]}; }

    // Checks the parameters and fills in the default spacing.
    void validate() {
        spacing = p.spacing;
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(spacing[a]) || spacing[a] < 0)
                throw InvalidParameter("phantom spacing[" + std::to_string(a) + "] is " +
                                       fmt(spacing[a]) + " mm, expected > 0 (or 0 for the default)");
            if (spacing[a] == 0) spacing[a] = spec.spacing;
        }
        if (!std::isfinite(p.tilt_deg) || p.tilt_deg < -90.0 || p.tilt_deg > 90.0)
            throw InvalidParameter("phantom tilt is " + fmt(p.tilt_deg) +
                                   " degrees, expected within [-90, 90]");
        for (int a = 0; a < 3; ++a) {
            if (p.size[a] < 0)
                throw InvalidParameter("phantom size[" + std::to_string(a) + "] is " +
                                       std::to_string(p.size[a]) + ", expected >= 0 (0 = automatic)");
            if (!std::isfinite(p.origin[a]))
                throw InvalidParameter("phantom origin[" + std::to_string(a) + "] is not finite");
            if (p.grid_centre_mm[a] != 0.0)
                throw InvalidParameter("phantom grid centre: only for the skull-base and mouse phantoms "
                                       "(the ellipsoid phantoms centre an explicit size on the cavity)");
        }
        if (!std::isfinite(p.optic_canal_radius_mm) || p.optic_canal_radius_mm < 0)
            throw InvalidParameter("phantom optic canal radius is " + fmt(p.optic_canal_radius_mm) +
                                   " mm, expected >= 0 (0 = preset default)");
        if (p.body && !has_soft)
            throw InvalidParameter(
                "phantom body (shoulders, chest, couch) needs soft tissue: not with the dry preset or "
                "without scalp");
    }

    // The skull, the tilt, the crop of the base, the blur and the facial bone (phantom frame).
    void skull_geometry() {
        inner = spec.inner;
        T = spec.thickness;
        outer = add_scalar(inner, T);
        scalp_axes = add_scalar(outer, spec.scalp);
        s = spec.scale;
        const double tilt = p.tilt_deg * kPi / 180.0;
        cs = std::cos(tilt);
        sn = std::sin(tilt);
        inner_half = rotated_half_extent(inner, cs, sn);
        if (!std::isfinite(p.crop_base_mm) || p.crop_base_mm < 0 ||
            p.crop_base_mm >= 2.0 * inner_half[2])
            throw InvalidParameter("phantom crop of the base is " + fmt(p.crop_base_mm) +
                                   " mm, expected 0 (off) or within (0, " + fmt(2.0 * inner_half[2]) +
                                   ") mm, the cavity's height");
        crop = p.crop_base_mm > 0;

        const double vox = std::cbrt(spacing[0] * spacing[1] * spacing[2]);
        if (p.blur) {
            step.sigma = kBlurVoxels * vox;
            step.band = kBandSigmas * step.sigma;
            step.inv = 1.0 / (std::sqrt(2.0) * step.sigma);
        }
        band = step.band;

        // Facial bone (glabella, orbits, nasal cavity): an ellipsoid of bone in front of and below
        // the braincase, joined to the skull; only with the sinus or the orbits.
        face = p.frontal_sinus || p.orbits;
        face_c = mul(Vec3{0, 60, -48}, s);
        face_axes = mul(Vec3{60, 50, 42}, s);
        face_soft_axes = add_scalar(face_axes, spec.scalp);
    }

    // The cervical spine, the shoulders, the chest and the CT couch.
    void spine_and_body_geometry() {
        // Spine: canal along the vertical line through the foramen magnum's centre.
        fm_y = -15.0 * s;
        canal_r = spec.canal_radius;
        wall = 5.0 * s;
        ring_h = 15.0 * s;
        ring_gap = 4.0 * s;
        period = ring_h + ring_gap;
        const double z_outer_canal = -outer[2] * std::sqrt(1.0 - (fm_y / outer[1]) * (fm_y / outer[1]));
        ring_top = z_outer_canal - 2.0 * s;
        body_r = 9.0 * s;
        body_y = fm_y + canal_r + wall + body_r - 2.0 * s;
        pillar_x = canal_r + 1.2 * wall;
        pillar_r = 0.8 * wall;
        spine_reach = std::max(canal_r + wall, pillar_x + pillar_r);

        // Body and couch (world frame, relative to the cavity centre).
        const double head_post = rotated_half_extent(has_soft ? scalp_axes : outer, cs, sn)[1];
        couch_R = 500.0 * s;
        couch_T = 25.0 * s;
        couch_half_w = 210.0 * s;
        couch_skin = 3.0 * s;
        couch_top = -head_post + 1.0 * s;  // pressed 1 mm into the scalp
        couch_sag = couch_R - std::sqrt(couch_R * couch_R - couch_half_w * couch_half_w);
        couch_axis_y = couch_top + couch_R;
        chest_axes = mul(Vec3{170, 100, 60}, s);
        chest_y = couch_top + chest_axes[1];  // the back rests on the couch
        chest_cap_z = -190.0 * s;
        clavicle_r = 7.0 * s;
    }

    // Widens the automatic box [lo, hi] to hold the box centred at c with the given half sizes.
    void include_box(const Vec3& c, const Vec3& half, double margin) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], c[a] - half[a] - margin);
            hi[a] = std::max(hi[a], c[a] + half[a] + margin);
        }
    }

    // The automatic box [lo, hi] around everything, relative to the cavity centre.
    void automatic_box() {
        const Vec3 head_axes = has_soft ? scalp_axes : outer;
        const Vec3 head_half = rotated_half_extent(head_axes, cs, sn);
        for (int a = 0; a < 3; ++a) {
            hi[a] = head_half[a] + kMarginMm;
            lo[a] = -hi[a];
        }
        if (face)
            include_box(to_world_dir(face_c),
                        rotated_half_extent(has_soft ? face_soft_axes : face_axes, cs, sn), kMarginMm);
        if (p.spine) {
            // Down to the bottom of the 7th ring; the canal and the rings reach the lower border.
            const double zb = ring_top - automatic_rings * period + ring_gap;
            const Vec3 bottom = to_world_dir({0.0, fm_y, zb});
            const double reach = body_y - fm_y + body_r;
            lo[2] = std::min(lo[2], bottom[2]);
            lo[1] = std::min(lo[1], bottom[1] - reach - kMarginMm);
            hi[1] = std::max(hi[1], bottom[1] + reach + kMarginMm);
        }
        if (p.body) {
            const double y0 = couch_top - couch_T - 20.0 * s;
            include_box({0.0, y0 + 160.0 * s, 0.0}, {215.0 * s, 160.0 * s, 0.0}, 0.0);
            lo[2] = std::min(lo[2], -195.0 * s);
        }
        if (crop) lo[2] = -inner_half[2] + p.crop_base_mm + 0.5 * spacing[2];
    }

    // The grid (given sizes or the automatic box), checked to hold the skull, and the cavity centre.
    void grid() {
        const Vec3 skull_half = rotated_half_extent(outer, cs, sn);
        Vec3 centre_index{};
        for (int a = 0; a < 3; ++a) {
            const bool symmetric = lo[a] == -hi[a];
            if (p.size[a] > 0) {
                dims[a] = p.size[a];  // the cavity centre at the grid's centre
                centre_index[a] = 0.5 * static_cast<double>(dims[a] - 1);
            } else {
                dims[a] = static_cast<int64_t>(std::ceil((hi[a] - lo[a]) / spacing[a])) + 1;
                centre_index[a] = symmetric ? 0.5 * static_cast<double>(dims[a] - 1) : -lo[a] / spacing[a];
            }
            if (a == 2 && crop) centre_index[a] = -lo[a] / spacing[a];
            const double below = centre_index[a] * spacing[a];
            const double above = (static_cast<double>(dims[a] - 1) - centre_index[a]) * spacing[a];
            const bool fits = (below >= skull_half[a] || (a == 2 && crop)) && above >= skull_half[a];
            if (!fits)
                throw InvalidParameter(
                    "phantom size[" + std::to_string(a) + "] is " + std::to_string(p.size[a]) +
                    " voxels (" + fmt(below + above) + " mm), too small for the skull (needs " +
                    std::to_string(static_cast<int64_t>(std::ceil(2.0 * skull_half[a] / spacing[a])) + 1) +
                    " voxels)");
        }
        phantom_detail::check_phantom_voxels(dims, slabs);

        geom.dims = dims;
        geom.spacing = spacing;
        geom.origin = p.origin;
        centre = geom.index_to_world(centre_index[0], centre_index[1], centre_index[2]);
    }

    // Lists an opening of the braincase (phantom frame point and axis) in world coordinates.
    void list_opening(const std::string& name, const Vec3& c, const Vec3& axis, double r) {
        listed.push_back({name, add(centre, to_world_dir(c)), to_world_dir(normalized(axis)), r});
    }

    // Gives a carving its bounding sphere and adds it to the openings.
    void finish(Feature f) {
        switch (f.kind) {
            case FeatureKind::Capsule:
                f.bound_c = add(f.c, mul(f.u, 0.5 * f.length));
                f.bound_r = 0.5 * f.length + f.radius + band;
                break;
            case FeatureKind::Cone:
                f.bound_c = add(f.c, mul(f.u, 0.5 * f.length));
                f.bound_r = std::hypot(0.5 * f.length, f.radius) + band;
                break;
            case FeatureKind::Void:
                f.bound_c = f.c;
                f.bound_r = std::max(f.half[0], f.half[1]) + band;
                break;
            default:
                f.bound_c = f.c;
                f.bound_r = norm(f.half) + band;
        }
        openings.push_back(f);
    }

    // A capsule from a to b with radius r (no bounding sphere yet).
    static Feature capsule(Carve carve, const Vec3& a, const Vec3& b, double r) {
        Feature f;
        f.kind = FeatureKind::Capsule;
        f.carve = carve;
        f.c = a;
        f.u = normalized(sub(b, a));
        f.length = norm(sub(b, a));
        f.radius = r;
        return f;
    }

    // The openings of the braincase: the foramen magnum, the small foramina and the crack.
    void braincase_openings() {
        content = spec.content;
        fill = content;  // what fills openings through the shell (and the spinal canal)
        fm_inner = {0.0, fm_y, -inner[2] * std::sqrt(1.0 - (fm_y / inner[1]) * (fm_y / inner[1]))};
        if (p.foramen_magnum) {
            Feature f;
            f.kind = FeatureKind::HalfCylinder;
            f.carve = Carve::Opening;
            f.c = {0.0, fm_y, 0.0};
            f.radius = spec.fm_radius;
            f.z_top = 0.0;
            f.bound_r = kInf;
            openings.push_back(f);
            list_opening("foramen_magnum", fm_inner, {0, 0, -1}, spec.fm_radius);
        }
        if (p.small_foramina) {
            struct Hole { Vec3 dir; double r; };
            const Hole holes[] = {
                {{-0.35, 0.30, -0.90}, 2.0},  // base, left (foramen ovale-like)
                {{0.35, 0.30, -0.90}, 1.5},   // base, right
                {{0.0, 0.75, -0.65}, 2.5},    // anterior base (optic-like)
                {{-0.95, 0.10, -0.30}, 3.0},  // left side
                {{0.90, -0.35, -0.25}, 1.8},  // right side, posterior
            };
            int index = 0;
            for (const Hole& h : holes) {
                const Vec3 pi = ellipsoid_point(h.dir, inner);
                const Vec3 n = ellipsoid_normal(pi, inner);
                Feature f;
                f.kind = FeatureKind::Capsule;
                f.carve = Carve::Opening;
                f.c = sub(pi, mul(n, 3.0 * s));
                f.u = n;
                f.length = T + 6.0 * s;
                f.radius = h.r * s;
                f.bound_c = add(f.c, mul(n, 0.5 * f.length));
                f.bound_r = 0.5 * f.length + f.radius + band;
                openings.push_back(f);
                list_opening("foramen_" + std::to_string(++index), pi, n, f.radius);
            }
        }
        if (p.crack) {
            const Vec3 pi = ellipsoid_point({0.25, -0.20, 1.0}, inner);
            const Vec3 n = ellipsoid_normal(pi, inner);
            const Vec3 t = normalized(cross(n, normalized(Vec3{1.0, 0.6, 0.0})));
            Feature f;
            f.kind = FeatureKind::Box;
            f.carve = Carve::Opening;
            f.u = t;
            f.v = cross(n, t);
            f.w = n;
            f.half = {15.0 * s, 0.5 * spec.crack_width, 0.5 * T + 3.0 * s};
            f.c = add(pi, mul(n, 0.5 * T));
            f.bound_c = f.c;
            f.bound_r = norm(f.half) + band;
            openings.push_back(f);
            list_opening("crack", pi, n, std::hypot(f.half[0], f.half[1]));
        }
    }

    // The frontal sinus, its duct, the nasal cavity and the nostrils (air).
    void frontal_sinus() {
        if (!p.frontal_sinus) return;
        // Sinus: bone between it and the inner surface: 3.5 mm, and at least two blend bands (so
        // that the skull is pure bone throughout the inner surface's band).
        const double gap = std::max(3.5 * s, 2.0 * band);
        const Vec3 ps = ellipsoid_point({0.0, 1.0, -0.32}, inner);
        const Vec3 n = ellipsoid_normal(ps, inner);
        const double rn = 6.0 * s, rt = 12.0 * s;
        Feature sinus;
        sinus.kind = FeatureKind::Void;  // spheroid
        sinus.carve = Carve::Air;
        sinus.u = n;
        sinus.half = {rn, rt, 0.0};
        sinus.c = add(ps, mul(n, gap + rn));  // the inner surface lies behind its tangent plane
        finish(sinus);
        const Vec3 t2{0.0, -n[2], n[1]};     // in the sagittal plane, across n, pointing up
        const Vec3 duct_top = sub(sinus.c, mul(t2, 0.6 * rt));
        const Vec3 nasal_c = mul(Vec3{0, 78, -68}, s);
        const Vec3 nasal_half = mul(Vec3{9, 17, 14}, s);
        finish(capsule(Carve::Air, duct_top, {0.0, nasal_c[1], nasal_c[2] + nasal_half[2] - 3.0 * s},
                       2.0 * s));
        Feature nasal;
        nasal.kind = FeatureKind::Box;
        nasal.carve = Carve::Air;
        nasal.c = nasal_c;
        nasal.u = {1, 0, 0};
        nasal.v = {0, 1, 0};
        nasal.w = {0, 0, 1};
        nasal.half = nasal_half;
        finish(nasal);
        for (double side : {-1.0, 1.0}) {
            Feature f = capsule(Carve::Air, mul(Vec3{5.0 * side, 88, -76}, s),
                                mul(Vec3{5.0 * side, 118, -94}, s), 4.0 * s);
            finish(f);
            nostrils.push_back(openings.back());
        }
    }

    // The orbits (cones from the apex behind to the opening in front), the eyes and the optic canals.
    void orbits() {
        optic_r = p.optic_canal_radius_mm > 0 ? p.optic_canal_radius_mm : spec.optic_radius;
        if (!p.orbits) return;
        for (double side : {-1.0, 1.0}) {
            const Vec3 apex = mul(Vec3{17.0 * side, 60, -47}, s);
            const Vec3 base = mul(Vec3{34.0 * side, 104, -40}, s);
            const Vec3 d = normalized(sub(base, apex));
            Feature cone;
            cone.kind = FeatureKind::Cone;
            cone.carve = Carve::Orbit;
            cone.c = apex;
            cone.u = d;
            cone.length = norm(sub(base, apex));
            cone.radius = 20.0 * s;
            finish(cone);
            // The apex widened to the canal's radius, so that the canal opens into the orbit.
            finish(capsule(Carve::Orbit, apex, add(apex, mul(d, 2.5 * optic_r)), optic_r));
            if (p.preset != PhantomPreset::Dry)
                eyes.push_back({sub(base, mul(d, 13.0 * s)), 12.0 * s});
            // Optic canal: from the apex to 3 mm inside the braincase, towards the nearest point.
            Vec3 x{0, 0, 0};
            ellipsoid_signed_distance(apex, inner, &x);
            const Vec3 u_in = normalized(sub(x, apex));
            Feature canal = capsule(Carve::Opening, apex, add(x, mul(u_in, 3.0 * s)), optic_r);
            finish(canal);
            list_opening(side < 0 ? "optic_canal_left" : "optic_canal_right", x, mul(u_in, -1.0),
                         optic_r);
        }
    }

    // Signed distance to the nearest opening or carving.
    double opening_sd(const Vec3& q) const {
        double d = kInf;
        for (const Feature& f : openings) d = std::min(d, f.sd(q));
        return d;
    }

    // The diploic voids, seeded, each clear of both surfaces, of the carvings and of each other.
    void diploic_voids() {
        if (!p.diploic_voids) return;
        SplitMix64 rng{p.seed ^ 0x5DEECE66DULL};
        const double margin = 1.0 * s;  // bone kept between a void and either surface
        for (int attempt = 0; attempt < 20000 && static_cast<int>(voids.size()) < spec.void_count;
             ++attempt) {
            // Uniform direction.
            const double z = rng.uniform(-1.0, 1.0), phi = rng.uniform(0.0, 2.0 * kPi);
            const double rxy = std::sqrt(std::max(0.0, 1.0 - z * z));
            const Vec3 dir{rxy * std::cos(phi), rxy * std::sin(phi), z};
            const double rt = rng.uniform(1.0, 2.5) * s;
            const double rn = std::min(rt, rng.uniform(1.0, 2.0) * s);
            const Vec3 pi = ellipsoid_point(dir, inner);
            const Vec3 n = ellipsoid_normal(pi, inner);
            const double depth = rng.uniform(0.0, 1.0);
            const double lo_d = margin + rn, hi_d = T - margin - rn;
            if (hi_d <= lo_d) continue;
            const Vec3 c = add(pi, mul(n, lo_d + depth * (hi_d - lo_d)));
            // The whole void (its largest radius) must stay clear of both surfaces...
            if (ellipsoid_sd(c, inner) < rn + margin) continue;
            if (ellipsoid_sd(c, outer) > -(rn + margin)) continue;
            // ... of the openings and carvings ...
            if (opening_sd(c) < rt + 2.0 * s) continue;
            // ... and of the other voids.
            bool clear = true;
            for (const Feature& o : voids)
                if (norm(sub(c, o.c)) < rt + o.half[1] + 1.0 * s) { clear = false; break; }
            if (!clear) continue;
            Feature f;
            f.kind = FeatureKind::Void;
            f.carve = Carve::Void;
            f.c = c;
            f.u = n;
            f.half = {rn, rt, 0.0};
            f.bound_c = c;
            f.bound_r = rt + band + 1e-6;
            voids.push_back(f);
        }
    }

    // Beyond this radius (phantom frame, from the cavity centre) the approximate signed distance
    // of the ellipsoid centred at c with semi-axes ax is >= the blend band: sd >= (rmin/rmax)^2
    // (|q| - rmax).
    double far_radius(const Vec3& c, const Vec3& ax) const {
        const double rmax = std::max({ax[0], ax[1], ax[2]}), rmin = std::min({ax[0], ax[1], ax[2]});
        return norm(c) + rmax + (band + 1.0) * (rmax * rmax) / (rmin * rmin);
    }

    // The volume, the values and far radii the rendering uses, and the clavicles.
    void render_setup() {
        res.geometry = geom;
        diploe = spec.diploe;
        soft = kSoftTissue;
        orbit_fill = p.preset == PhantomPreset::Dry ? kAir : kFat;
        noise_key = phantom_detail::noise_key(p.seed);
        noise = p.noise;
        neck_r = has_soft ? spec.neck_radius : 0.0;
        nx = dims[0];
        ny = dims[1];
        nz = dims[2];
        double skull_far = far_radius({0, 0, 0}, outer);
        if (face) skull_far = std::max(skull_far, far_radius(face_c, face_axes));
        double head_far = far_radius({0, 0, 0}, scalp_axes);
        if (face) head_far = std::max(head_far, far_radius(face_c, face_soft_axes));
        for (const Feature& f : nostrils) head_far = std::max(head_far, norm(f.bound_c) + f.bound_r);
        skull_far2 = skull_far * skull_far;
        head_far2 = head_far * head_far;
        spine_far = spine_reach + 2.0 * body_r + band + 1.0;
        if (p.body)
            for (double side : {-1.0, 1.0})
                clavicles.push_back(capsule(Carve::Void, {25.0 * s * side, chest_y + 52.0 * s, -168.0 * s},
                                            {140.0 * s * side, chest_y + 7.0 * s, -172.0 * s},
                                            clavicle_r));
        for (Feature& f : clavicles) {
            f.bound_c = add(f.c, mul(f.u, 0.5 * f.length));
            f.bound_r = 0.5 * f.length + f.radius + band;
        }
    }

    // Adds f to the row's features with the voxel range its bounding sphere covers, if any.
    void collect(const Feature& f, Row& row) const {
        if (!std::isfinite(f.bound_r)) {
            row.features.push_back({&f, 0, nx - 1});
            return;
        }
        const double dy = row.qy - f.bound_c[1], dz = row.qz - f.bound_c[2];
        const double r2 = f.bound_r * f.bound_r - dy * dy - dz * dz;
        if (r2 < 0) return;
        const double h = std::sqrt(r2);
        const int64_t x0 = static_cast<int64_t>(std::floor((f.bound_c[0] - h - row.qx0) / spacing[0]));
        const int64_t x1 = static_cast<int64_t>(std::ceil((f.bound_c[0] + h - row.qx0) / spacing[0]));
        if (x1 < 0 || x0 > nx - 1) return;
        row.features.push_back({&f, std::max<int64_t>(x0, 0), std::min(x1, nx - 1)});
    }

    // Row (j, k): its phantom-frame coordinates, its features, and which of the spine, couch,
    // chest and clavicles it crosses.
    void setup_row(int64_t j, int64_t k, Row& row) const {
        // Row in the phantom frame: q(i) = (wx(i) - cx, qy, qz); world x is the rotation axis.
        const Vec3 w0 = geom.index_to_world(0.0, static_cast<double>(j), static_cast<double>(k));
        row.rel = sub(w0, centre);
        const Vec3& rel = row.rel;
        row.qy = cs * rel[1] + sn * rel[2];
        row.qz = -sn * rel[1] + cs * rel[2];
        row.qx0 = rel[0];
        row.row_r2 = row.qy * row.qy + row.qz * row.qz;
        row.features.clear();
        if (row.row_r2 <= skull_far2) {
            for (const Feature& f : voids) collect(f, row);
            for (const Feature& f : openings) collect(f, row);
        }
        // Spine: radial distance of the row from the canal's axis (phantom frame).
        row.sy = row.qy - fm_y;
        row.spine_row = p.spine && row.qz <= band && std::fabs(row.sy) <= spine_far + body_r;
        row.ring_dz = kInf;
        if (row.spine_row) {
            const double zl = ring_top - row.qz;  // depth below the top of the first ring
            if (zl < 0) {
                row.ring_dz = -zl;
            } else {
                const double m = std::fmod(zl, period);
                row.ring_dz = m <= ring_h ? -std::min(m, ring_h - m)
                                          : std::min(m - ring_h, period - m);
            }
        }

        // Body rows: the couch's y range, the chest below its top, the clavicles' spheres.
        row.couch_row = p.body && rel[1] >= couch_top - couch_T - band &&
                        rel[1] <= couch_top + couch_sag + band;
        row.chest_row = p.body && rel[2] <= chest_cap_z + chest_axes[2] + band + 1.0;
        row.clavicle_row = false;
        for (const Feature& f : clavicles)
            row.clavicle_row = row.clavicle_row ||
                               std::hypot(rel[1] - f.bound_c[1], rel[2] - f.bound_c[2]) <= f.bound_r;
        row.out = out + nx * (j + ny * (k - k_base));
    }

    // The shell at voxel i, q of a row: bone with the diploic voids, orbits, air and openings.
    double carved_shell(const Row& row, int64_t i, const Vec3& q) const {
        double shell = kBoneHu;
        double dv = kInf, dop = kInf, dair = kInf, dorb = kInf;
        for (const RowFeature& rf : row.features) {
            if (i < rf.x0 || i > rf.x1) continue;
            const double d = rf.f->sd(q);
            switch (rf.f->carve) {
                case Carve::Void: dv = std::min(dv, d); break;
                case Carve::Opening: dop = std::min(dop, d); break;
                case Carve::Air: dair = std::min(dair, d); break;
                case Carve::Orbit: dorb = std::min(dorb, d); break;
            }
        }
        if (dv < kInf) shell = mix(shell, diploe, step(dv));
        if (dorb < kInf) {
            const double so = step(dorb);
            if (so > 0.0) {
                double ov = orbit_fill;
                for (const Eye& e : eyes)
                    ov = mix(ov, kEye, step(norm(sub(q, e.c)) - e.r));
                shell = mix(shell, ov, so);
            }
        }
        if (dair < kInf) shell = mix(shell, kAir, step(dair));
        if (dop < kInf) shell = mix(shell, fill, step(dop));
        return shell;
    }

    // Layers 2 and 3 at voxel i, q of a row: pure content deep inside, else the blend weights of
    // the braincase content and the bone, and the carved shell.
    SkullSample skull_layers(const Row& row, int64_t i, const Vec3& q, double r2) const {
        SkullSample sample;
        if (r2 <= skull_far2) {
            const double d_in = ellipsoid_sd(q, inner);
            if (step.sigma > 0 ? d_in <= -band : d_in < 0) {
                sample.v = content;
                sample.inside = true;
            } else {
                sample.s_in = step(d_in);
                double d_bone = ellipsoid_sd(q, outer);
                if (face) d_bone = std::min(d_bone, ellipsoid_sd(sub(q, face_c), face_axes));
                sample.s_bone = step(d_bone);
                if (sample.s_bone > 0.0 && sample.s_in < 1.0) sample.shell = carved_shell(row, i, q);
            }
        }
        return sample;
    }

    // The couch blended into outside at w (world, relative to the centre).
    double add_couch(double outside, const Vec3& w) const {
        const double rr = std::hypot(w[0], w[1] - couch_axis_y);
        const double ax = std::fabs(w[0]);
        const double d_couch = std::max({couch_R - rr, rr - couch_R - couch_T, ax - couch_half_w});
        const double sc = step(d_couch);
        if (sc > 0.0) {
            const double d_core = std::max({couch_R + couch_skin - rr, rr - couch_R - couch_T + couch_skin,
                                            ax - couch_half_w + couch_skin});
            outside = mix(outside, mix(kCouchSkin, kCouchCore, step(d_core)), sc);
        }
        return outside;
    }

    // The scalp, the facial soft tissue and the neck blended into outside at q.
    double add_soft_tissue(double outside, const Vec3& q, double r2) const {
        double d_soft = kInf;
        if (r2 <= head_far2) {
            d_soft = ellipsoid_sd(q, scalp_axes);
            if (face) d_soft = std::min(d_soft, ellipsoid_sd(sub(q, face_c), face_soft_axes));
        }
        if (neck_r > 0) {
            const double dy = q[1] - fm_y;
            const double d_neck = std::max(std::sqrt(q[0] * q[0] + dy * dy) - neck_r, q[2]);
            d_soft = std::min(d_soft, d_neck);
        }
        return mix(outside, soft, step(d_soft));
    }

    // The vertebrae (rings, bodies, pillars) and the spinal canal blended into outside at q.
    double add_spine(double outside, const Row& row, const Vec3& q) const {
        const double rho = std::hypot(q[0], row.sy);
        const double d_ring = std::max(std::max(rho - canal_r - wall, canal_r - rho), row.ring_dz);
        const double d_body = std::max(std::hypot(q[0], q[1] - body_y) - body_r, row.ring_dz);
        const double d_pillar = std::max(std::hypot(std::fabs(q[0]) - pillar_x, row.sy) - pillar_r, q[2]);
        const double d_vert = std::min({d_ring, d_body, d_pillar});
        outside = mix(outside, kSpineBoneHu, step(d_vert));
        return mix(outside, fill, step(std::max(rho - canal_r, q[2])));
    }

    // Layer 1 at q of a row: air, couch, soft tissue, chest, clavicles, spine, eyes, nostrils.
    double outside_layer(const Row& row, const Vec3& q, double r2) const {
        double outside = kAir;
        const Vec3 w{q[0], row.rel[1], row.rel[2]};  // world, relative to the centre
        if (row.couch_row) outside = add_couch(outside, w);
        if (has_soft) outside = add_soft_tissue(outside, q, r2);
        if (row.chest_row) {
            const double by = w[1] - chest_y;
            const double d_chest = w[2] > chest_cap_z
                                       ? ellipsoid_sd({w[0], by, w[2] - chest_cap_z}, chest_axes)
                                       : ellipse_sd(w[0], by, chest_axes[0], chest_axes[1]);
            outside = mix(outside, kBodyTissue, step(d_chest));
        }
        if (row.clavicle_row) {
            double d_cl = kInf;
            for (const Feature& f : clavicles) d_cl = std::min(d_cl, f.sd(w));
            outside = mix(outside, kSpineBoneHu, step(d_cl));
        }
        if (row.spine_row && std::fabs(q[0]) <= spine_far) outside = add_spine(outside, row, q);
        if (r2 <= head_far2) {
            for (const Eye& e : eyes)
                outside = mix(outside, kEye, step(norm(sub(q, e.c)) - e.r));
            for (const Feature& f : nostrils)
                outside = mix(outside, kAir, step(f.sd(q)));
        }
        return outside;
    }

    // The value of voxel i of row (j, k): the three layers, the noise, rounded to int16.
    int16_t voxel(const Row& row, int64_t i, int64_t j, int64_t k) const {
        const Vec3 q{row.qx0 + static_cast<double>(i) * spacing[0], row.qy, row.qz};
        const double r2 = q[0] * q[0] + row.row_r2;
        const SkullSample sk = skull_layers(row, i, q, r2);
        double v = sk.v;
        if (!sk.inside) {
            const double outside = sk.s_bone < 1.0 ? outside_layer(row, q, r2) : kAir;
            v = mix(outside, sk.shell, sk.s_bone);
            v = mix(v, content, sk.s_in);
        }
        if (noise) {
            const uint64_t idx = static_cast<uint64_t>(i + nx * (j + ny * k));
            v += kNoiseSigma * voxel_gaussian(noise_key, idx);
        }
        v = std::floor(v + 0.5);
        v = std::clamp(v, -32768.0, 32767.0);
        return static_cast<int16_t>(v);
    }

    // Renders slices [k0, k1) into dst (their voxels, x fastest), slices in parallel.
    void render(int64_t k0, int64_t k1, int16_t* dst) {
        out = dst;
        k_base = k0;
#pragma omp parallel for schedule(dynamic, 1)
        for (int64_t k = k0; k < k1; ++k) {
            Row row;
            row.features.reserve(voids.size() + openings.size());
            for (int64_t j = 0; j < ny; ++j) {
                setup_row(j, k, row);
                for (int64_t i = 0; i < nx; ++i) row.out[i] = voxel(row, i, j, k);
            }
        }
    }

    // The truth values of the result: the volume, the cavity, the openings and the radii.
    void truth() {
        const double ellipsoid_ml = 4.0 / 3.0 * kPi * inner[0] * inner[1] * inner[2] / 1000.0;
        res.true_ecv_ml = ellipsoid_ml;
        res.true_ecv_slice_centres_ml = ellipsoid_ml;
        res.crop_plane_z_mm = -kInf;
        if (crop) {
            const double h = -inner_half[2] + p.crop_base_mm;  // the lower face of the volume
            res.cropped = true;
            res.crop_plane_z_mm = centre[2] + h;
            res.true_ecv_ml = ellipsoid_volume_above(inner, cs, sn, h) / 1000.0;
            res.true_ecv_slice_centres_ml =
                ellipsoid_volume_above(inner, cs, sn, h + 0.5 * spacing[2]) / 1000.0;
        }
        res.true_ecv_error_ml = 1e-12 * res.true_ecv_ml;
        res.suggested_iso = 0.5 * (content + kBoneHu);
        res.cavity_centre_world = centre;
        res.cavity_semi_axes_mm = inner;
        res.cavity_rotation = {1, 0, 0, 0, cs, -sn, 0, sn, cs};
        res.foramen_magnum_world = add(centre, to_world_dir(fm_inner));
        res.foramen_magnum_axis = to_world_dir({0, 0, -1});
        res.foramen_magnum_radius_mm = p.foramen_magnum ? spec.fm_radius : 0.0;
        res.spinal_canal_radius_mm = p.spine ? canal_r : 0.0;
        res.optic_canal_radius_mm = p.orbits ? optic_r : 0.0;
        res.shell_thickness_mm = T;
        res.sigma_mm = step.sigma;
        res.openings = listed;
    }

    // The one-line description of the result.
    void describe() {
        std::ostringstream d;
        d << to_string(p.preset) << " phantom " << dims[0] << "x" << dims[1] << "x" << dims[2]
          << " voxels at " << fmt(spacing[0]) << "x" << fmt(spacing[1]) << "x" << fmt(spacing[2])
          << " mm, tilt " << fmt(p.tilt_deg) << " deg, ECV " << fmt(res.true_ecv_ml) << " mL, iso "
          << fmt(res.suggested_iso) << " HU, seed " << p.seed << "; features:";
        if (p.noise) d << " noise";
        if (p.blur) d << " blur";
        if (!voids.empty()) d << " voids(" << voids.size() << ")";
        if (p.crack) d << " crack";
        if (p.small_foramina) d << " foramina(5)";
        if (p.foramen_magnum) d << " foramen-magnum";
        if (has_soft) d << " scalp+neck";
        if (p.spine) d << " spine";
        if (p.frontal_sinus) d << " frontal-sinus";
        if (p.orbits) d << " orbits(optic canal r " << fmt(optic_r) << " mm)";
        if (p.body) d << " body+couch";
        if (crop) d << " cropped-base(" << fmt(p.crop_base_mm) << " mm)";
        res.description = d.str();
    }
};

PhantomResult generate(const PhantomParams& p, int64_t slab_voxels, const PhantomSlabSink& sink) {
    if (p.preset == PhantomPreset::Mouse) return generate_rodent_phantom(p, slab_voxels, sink);
    if (p.skull_base) return generate_skull_base_phantom(p, slab_voxels, sink);
    BraincasePhantom b(p);
    b.slabs = bool(sink);
    b.validate();
    b.skull_geometry();
    b.spine_and_body_geometry();
    b.automatic_box();
    b.grid();
    b.braincase_openings();
    b.frontal_sinus();
    b.orbits();
    b.diploic_voids();
    b.render_setup();
    render_phantom_ct(b.geom, slab_voxels, sink, b.res,
                      [&](int64_t k0, int64_t k1, int16_t* dst) { b.render(k0, k1, dst); });
    b.truth();
    b.describe();
    return std::move(b.res);
}

}  // namespace

namespace phantom_detail {

void check_phantom_voxels(const Dims& dims, bool slabs) {
    const double count = static_cast<double>(dims[0]) * static_cast<double>(dims[1]) * static_cast<double>(dims[2]);
    const double limit = slabs ? 1099511627776.0 : 2147483648.0;
    if (count >= limit)
        throw InvalidParameter("phantom size " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                               std::to_string(dims[2]) + " has too many voxels, expected fewer than " +
                               (slabs ? "2^40" : "2^31 (larger ones are rendered in slabs: generate_phantom_slabs)"));
}

void render_phantom_ct(const Geometry& geom, int64_t slab_voxels, const PhantomSlabSink& sink, PhantomResult& res,
                       const std::function<void(int64_t, int64_t, int16_t*)>& render) {
    res.geometry = geom;
    if (!sink) {
        res.ct = Volume<int16_t>(geom);
        render(0, geom.dims[2], res.ct.data());
        return;
    }
    const int64_t per_slice = geom.dims[0] * geom.dims[1];
    const int64_t slices = std::max<int64_t>(1, slab_voxels / std::max<int64_t>(1, per_slice));
    for (int64_t z0 = 0; z0 < geom.dims[2]; z0 += slices) {
        Geometry g = geom;
        g.dims[2] = std::min(slices, geom.dims[2] - z0);
        g.origin = geom.index_to_world(0, 0, static_cast<double>(z0));
        Volume<int16_t> slab(g);
        render(z0, z0 + g.dims[2], slab.data());
        sink(geom, z0, slab);
    }
}

}  // namespace phantom_detail

PhantomResult generate_phantom(const PhantomParams& p) { return generate(p, 0, {}); }

PhantomResult generate_phantom_slabs(const PhantomParams& p, int64_t slab_voxels, const PhantomSlabSink& sink) {
    if (slab_voxels < 1 || !sink)
        throw InvalidParameter("phantom slabs of " + std::to_string(slab_voxels) +
                               " voxels, expected >= 1 voxel and a sink for them");
    return generate(p, slab_voxels, sink);
}

}  // namespace endocast
