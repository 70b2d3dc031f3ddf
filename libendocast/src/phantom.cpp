// Synthetic skull CT phantom: an ellipsoidal braincase inside an ellipsoidal bone shell, with
// diploic voids, foramina, a crack, scalp and neck, rendered with analytic partial volume.
#include "endocast/phantom.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <vector>

namespace endocast {

namespace {

constexpr double kPi = 3.14159265358979323846;

// ---- Hounsfield units -------------------------------------------------------------------------
constexpr double kAir = -1000.0;
constexpr double kBrain = 35.0;
constexpr double kSoftTissue = 30.0;
constexpr double kBoneHu = 1400.0;
constexpr double kDiploeWet = 200.0;   // marrow-filled diploic void (Human, Macaque)
constexpr double kDiploeDry = -400.0;  // air-filled diploic void (Dry), below the Dry iso (200)
constexpr double kNoiseSigma = 20.0;
constexpr double kBlurVoxels = 0.6;
constexpr double kBandSigmas = 4.0;    // blending happens within +-4 sigma of an interface
constexpr double kMarginMm = 10.0;     // automatic grid: air margin around the head

// ---- small vector helpers ---------------------------------------------------------------------
Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 mul(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
Vec3 normalized(const Vec3& a) { return mul(a, 1.0 / norm(a)); }
Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// ---- random numbers: splitmix64, identical on every platform -------------------------------
uint64_t splitmix64_mix(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

struct SplitMix64 {
    uint64_t state;
    uint64_t next() { return splitmix64_mix(state += 0x9E3779B97F4A7C15ULL); }
    double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
};

/// Standard normal deviate that depends only on (key, voxel index): Marsaglia's polar method
/// fed by a counter-based splitmix64 stream.
double voxel_gaussian(uint64_t key, uint64_t index) {
    uint64_t state = key ^ splitmix64_mix(index * 0xD1B54A32D192ED03ULL + 0x8CB92BA72F3D8DD7ULL);
    for (int attempt = 0; attempt < 32; ++attempt) {
        const uint64_t r = splitmix64_mix(state += 0x9E3779B97F4A7C15ULL);
        const double u = (static_cast<double>(r >> 32) + 0.5) * (2.0 / 4294967296.0) - 1.0;
        const double v =
            (static_cast<double>(r & 0xFFFFFFFFULL) + 0.5) * (2.0 / 4294967296.0) - 1.0;
        const double s = u * u + v * v;
        if (s < 1.0 && s > 0.0) return u * std::sqrt(-2.0 * std::log(s) / s);
    }
    return 0.0;
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
enum class FeatureKind { Void, Capsule, Box, HalfCylinder };

struct Feature {
    FeatureKind kind = FeatureKind::Void;
    Vec3 c{0, 0, 0};       // centre (Void, Box); start (Capsule); axis point (HalfCylinder)
    Vec3 u{0, 0, 1};       // Void: symmetry axis; Capsule: unit axis; Box: first axis
    Vec3 v{0, 0, 0};       // Box: second axis
    Vec3 w{0, 0, 0};       // Box: third axis
    Vec3 half{0, 0, 0};    // Box half sizes; Void: (rn, rt, -)
    double length = 0;     // Capsule length
    double radius = 0;     // Capsule / HalfCylinder radius
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
        }
        return std::numeric_limits<double>::infinity();
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
};

PresetSpec preset_spec(PhantomPreset p) {
    switch (p) {
        case PhantomPreset::Human:
            return {{65, 82, 60}, 6.0, 5.0, 45.0, kBrain, kDiploeWet, 1.0, 1.0, 14.0, 1.0, 40};
        case PhantomPreset::Dry:
            return {{65, 82, 60}, 6.0, 0.0, 0.0, kAir, kDiploeDry, 1.0, 1.0, 14.0, 1.0, 40};
        case PhantomPreset::Macaque:
            return {{26, 34, 24}, 2.5, 2.0, 18.0, kBrain, kDiploeWet, 0.5, 0.4, 5.5, 0.5, 30};
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

std::string fmt(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

struct RowFeature {
    const Feature* f;
    int64_t x0, x1;  // voxel range of the row that can be affected
};

}  // namespace

PhantomPreset parse_phantom_preset(const std::string& s) {
    std::string l = s;
    std::transform(l.begin(), l.end(), l.begin(), [](unsigned char ch) { return std::tolower(ch); });
    if (l == "human") return PhantomPreset::Human;
    if (l == "dry") return PhantomPreset::Dry;
    if (l == "macaque") return PhantomPreset::Macaque;
    throw InvalidParameter("phantom preset '" + s + "' is unknown, expected human, dry or macaque");
}

std::string to_string(PhantomPreset p) {
    switch (p) {
        case PhantomPreset::Human: return "human";
        case PhantomPreset::Dry: return "dry";
        case PhantomPreset::Macaque: return "macaque";
    }
    return "unknown";
}

PhantomResult generate_phantom(const PhantomParams& p) {
    const PresetSpec spec = preset_spec(p.preset);
    const bool has_soft = p.preset != PhantomPreset::Dry && p.scalp;

    // ---- validation ----------------------------------------------------------------------
    Vec3 spacing = p.spacing;
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
    }

    // ---- geometry in the phantom frame ---------------------------------------------------
    const Vec3 inner = spec.inner;
    const double T = spec.thickness;
    const Vec3 outer = add_scalar(inner, T);
    const Vec3 scalp_axes = add_scalar(outer, spec.scalp);
    const double s = spec.scale;
    const double tilt = p.tilt_deg * kPi / 180.0;
    const double cs = std::cos(tilt), sn = std::sin(tilt);
    // world = centre + R * q, R = rotation about x; q = R^T * (world - centre).
    auto to_world_dir = [&](const Vec3& q) -> Vec3 {
        return {q[0], cs * q[1] - sn * q[2], sn * q[1] + cs * q[2]};
    };

    const double vox = std::cbrt(spacing[0] * spacing[1] * spacing[2]);
    Step step;
    if (p.blur) {
        step.sigma = kBlurVoxels * vox;
        step.band = kBandSigmas * step.sigma;
        step.inv = 1.0 / (std::sqrt(2.0) * step.sigma);
    }
    const double band = step.band;

    // ---- grid --------------------------------------------------------------------------------
    const Vec3 head_axes = has_soft ? scalp_axes : outer;
    const Vec3 head_half = rotated_half_extent(head_axes, cs, sn);
    const Vec3 skull_half = rotated_half_extent(outer, cs, sn);
    Dims dims{};
    for (int a = 0; a < 3; ++a) {
        if (p.size[a] > 0) {
            dims[a] = p.size[a];
            const double avail = 0.5 * static_cast<double>(dims[a] - 1) * spacing[a];
            if (avail < skull_half[a])
                throw InvalidParameter(
                    "phantom size[" + std::to_string(a) + "] is " + std::to_string(p.size[a]) +
                    " voxels (" + fmt(avail * 2) + " mm), too small for the skull (needs " +
                    std::to_string(static_cast<int64_t>(
                        std::ceil(2.0 * skull_half[a] / spacing[a])) + 1) +
                    " voxels)");
        } else {
            dims[a] = static_cast<int64_t>(
                          std::ceil(2.0 * (head_half[a] + kMarginMm) / spacing[a])) + 1;
        }
    }
    const double count = static_cast<double>(dims[0]) * static_cast<double>(dims[1]) *
                         static_cast<double>(dims[2]);
    if (count >= 2147483648.0)
        throw InvalidParameter("phantom size " + std::to_string(dims[0]) + "x" +
                               std::to_string(dims[1]) + "x" + std::to_string(dims[2]) +
                               " has too many voxels, expected fewer than 2^31");

    Geometry geom;
    geom.dims = dims;
    geom.spacing = spacing;
    geom.origin = p.origin;
    const Vec3 centre = geom.index_to_world(0.5 * static_cast<double>(dims[0] - 1),
                                            0.5 * static_cast<double>(dims[1] - 1),
                                            0.5 * static_cast<double>(dims[2] - 1));

    // ---- openings ---------------------------------------------------------------------------
    const double content = spec.content;
    const double fill = content;  // what fills openings through the shell
    std::vector<Feature> openings;
    const double fm_y = -15.0 * s;
    const Vec3 fm_inner{0.0, fm_y, -inner[2] * std::sqrt(1.0 - (fm_y / inner[1]) * (fm_y / inner[1]))};
    if (p.foramen_magnum) {
        Feature f;
        f.kind = FeatureKind::HalfCylinder;
        f.c = {0.0, fm_y, 0.0};
        f.radius = spec.fm_radius;
        f.z_top = 0.0;
        f.bound_r = std::numeric_limits<double>::infinity();
        openings.push_back(f);
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
        for (const Hole& h : holes) {
            const Vec3 pi = ellipsoid_point(h.dir, inner);
            const Vec3 n = ellipsoid_normal(pi, inner);
            Feature f;
            f.kind = FeatureKind::Capsule;
            f.c = sub(pi, mul(n, 3.0 * s));
            f.u = n;
            f.length = T + 6.0 * s;
            f.radius = h.r * s;
            f.bound_c = add(f.c, mul(n, 0.5 * f.length));
            f.bound_r = 0.5 * f.length + f.radius + band;
            openings.push_back(f);
        }
    }
    if (p.crack) {
        const Vec3 pi = ellipsoid_point({0.25, -0.20, 1.0}, inner);
        const Vec3 n = ellipsoid_normal(pi, inner);
        const Vec3 t = normalized(cross(n, normalized(Vec3{1.0, 0.6, 0.0})));
        Feature f;
        f.kind = FeatureKind::Box;
        f.u = t;
        f.v = cross(n, t);
        f.w = n;
        f.half = {15.0 * s, 0.5 * spec.crack_width, 0.5 * T + 3.0 * s};
        f.c = add(pi, mul(n, 0.5 * T));
        f.bound_c = f.c;
        f.bound_r = norm(f.half) + band;
        openings.push_back(f);
    }
    auto opening_sd = [&](const Vec3& q) {
        double d = std::numeric_limits<double>::infinity();
        for (const Feature& f : openings) d = std::min(d, f.sd(q));
        return d;
    };

    // ---- diploic voids (seeded) -----------------------------------------------------------
    std::vector<Feature> voids;
    if (p.diploic_voids) {
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
            const double lo = margin + rn, hi = T - margin - rn;
            if (hi <= lo) continue;
            const Vec3 c = add(pi, mul(n, lo + depth * (hi - lo)));
            // The whole void (its largest radius) must stay clear of both surfaces...
            if (ellipsoid_sd(c, inner) < rn + margin) continue;
            if (ellipsoid_sd(c, outer) > -(rn + margin)) continue;
            // ... of the openings ...
            if (opening_sd(c) < rt + 2.0 * s) continue;
            // ... and of the other voids.
            bool clear = true;
            for (const Feature& o : voids)
                if (norm(sub(c, o.c)) < rt + o.half[1] + 1.0 * s) { clear = false; break; }
            if (!clear) continue;
            Feature f;
            f.kind = FeatureKind::Void;
            f.c = c;
            f.u = n;
            f.half = {rn, rt, 0.0};
            f.bound_c = c;
            f.bound_r = rt + band + 1e-6;
            voids.push_back(f);
        }
    }

    // ---- rendering ------------------------------------------------------------------------
    PhantomResult res;
    res.ct = Volume<int16_t>(geom);
    int16_t* out = res.ct.data();
    const double diploe = spec.diploe;
    const double soft = kSoftTissue;
    const uint64_t noise_key = splitmix64_mix(p.seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL);
    const bool noise = p.noise;
    const double neck_r = has_soft ? spec.neck_radius : 0.0;
    const int64_t nx = dims[0], ny = dims[1], nz = dims[2];

#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t k = 0; k < nz; ++k) {
        std::vector<RowFeature> row_features;
        row_features.reserve(voids.size() + openings.size());
        for (int64_t j = 0; j < ny; ++j) {
            // Row in the phantom frame: q(i) = (wx(i) - cx, qy, qz); world x is the rotation axis.
            const Vec3 w0 = geom.index_to_world(0.0, static_cast<double>(j), static_cast<double>(k));
            const Vec3 rel = sub(w0, centre);
            const double qy = cs * rel[1] + sn * rel[2];
            const double qz = -sn * rel[1] + cs * rel[2];
            const double qx0 = rel[0];
            row_features.clear();
            auto collect = [&](const Feature& f) {
                if (!std::isfinite(f.bound_r)) {
                    row_features.push_back({&f, 0, nx - 1});
                    return;
                }
                const double dy = qy - f.bound_c[1], dz = qz - f.bound_c[2];
                const double r2 = f.bound_r * f.bound_r - dy * dy - dz * dz;
                if (r2 < 0) return;
                const double h = std::sqrt(r2);
                const int64_t x0 = static_cast<int64_t>(std::floor((f.bound_c[0] - h - qx0) / spacing[0]));
                const int64_t x1 = static_cast<int64_t>(std::ceil((f.bound_c[0] + h - qx0) / spacing[0]));
                if (x1 < 0 || x0 > nx - 1) return;
                row_features.push_back({&f, std::max<int64_t>(x0, 0), std::min(x1, nx - 1)});
            };
            for (const Feature& f : voids) collect(f);
            const size_t n_voids = row_features.size();
            for (const Feature& f : openings) collect(f);

            int16_t* row = out + nx * (j + ny * k);
            for (int64_t i = 0; i < nx; ++i) {
                const Vec3 q{qx0 + static_cast<double>(i) * spacing[0], qy, qz};
                const double d_in = ellipsoid_sd(q, inner);
                double v;
                if (step.sigma > 0 ? d_in <= -band : d_in < 0) {
                    v = content;
                } else {
                    const double s_in = step(d_in);
                    const double d_out = ellipsoid_sd(q, outer);
                    const double s_out = step(d_out);
                    double shell = kBoneHu;
                    if (s_out > 0.0 && s_in < 1.0) {
                        double dv = std::numeric_limits<double>::infinity();
                        double dop = dv;
                        for (size_t f = 0; f < row_features.size(); ++f) {
                            const RowFeature& rf = row_features[f];
                            if (i < rf.x0 || i > rf.x1) continue;
                            const double d = rf.f->sd(q);
                            if (f < n_voids) dv = std::min(dv, d);
                            else dop = std::min(dop, d);
                        }
                        if (dv < std::numeric_limits<double>::infinity())
                            shell = mix(shell, diploe, step(dv));
                        if (dop < std::numeric_limits<double>::infinity())
                            shell = mix(shell, fill, step(dop));
                    }
                    double outside = kAir;
                    if (s_out < 1.0 && has_soft) {
                        double d_soft = ellipsoid_sd(q, scalp_axes);
                        if (neck_r > 0) {
                            const double dy = q[1] - fm_y;
                            const double d_neck =
                                std::max(std::sqrt(q[0] * q[0] + dy * dy) - neck_r, q[2]);
                            d_soft = std::min(d_soft, d_neck);
                        }
                        outside = mix(kAir, soft, step(d_soft));
                    }
                    v = mix(outside, shell, s_out);
                    v = mix(v, content, s_in);
                }
                if (noise) {
                    const uint64_t idx = static_cast<uint64_t>(i + nx * (j + ny * k));
                    v += kNoiseSigma * voxel_gaussian(noise_key, idx);
                }
                v = std::floor(v + 0.5);
                v = std::clamp(v, -32768.0, 32767.0);
                row[i] = static_cast<int16_t>(v);
            }
        }
    }

    // ---- result -------------------------------------------------------------------------------
    res.true_ecv_ml = 4.0 / 3.0 * kPi * inner[0] * inner[1] * inner[2] / 1000.0;
    res.suggested_iso = 0.5 * (content + kBoneHu);
    res.cavity_centre_world = centre;
    res.cavity_semi_axes_mm = inner;
    res.foramen_magnum_world = add(centre, to_world_dir(fm_inner));
    res.foramen_magnum_radius_mm = p.foramen_magnum ? spec.fm_radius : 0.0;
    res.shell_thickness_mm = T;
    res.sigma_mm = step.sigma;

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
    res.description = d.str();
    return res;
}

}  // namespace endocast
