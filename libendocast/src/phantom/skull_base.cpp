// The anatomical skull-base phantom (PhantomParams::skull_base): a braincase whose inner table is
// the zero set of one implicit function f (phantom frame, mm; cavity = {f < 0}), built as smooth
// unions (polynomial smooth-min, Quilez) of ellipsoids and capsules - cerebrum cut flat over the
// anterior fossa, olfactory groove, sella, middle-fossa pockets, cerebellar lobes, brainstem and
// the basin above the foramen magnum - minus smooth subtractions for the structures that stick into
// it (sphenoid wings over the temporal poles, petrous ridges, dorsum sellae).
//
// Bone lies outside the cavity up to a thickness field (vault 6 mm, squamous temporal and middle
// fossa floor ~2.5-3.5 mm) joined to solid base blocks (sphenoid body and clivus, petrous bones,
// face); soft regions are carved into it: orbits whose roofs are 0.5-1 mm below the anterior fossa
// floor, a nasal cavity 1 mm below the cribriform plate, and straight canals (foramina, fissure,
// foramen magnum) that start at the inner table and lead out of the skull. Rendering: each region
// is blended by the erfc of its signed distance (Gaussian scanner blur of a planar interface), the
// cavity's and the soft regions' fractions are added and bone takes the rest, which is the exact
// blur of a thin plate between two parallel interfaces (0.5 mm of bone peaks at 32 % of its
// contrast at sigma 0.6 mm, 1 mm at 60 %).
//
// Truth: the volume of {f < 0} by an adaptive octree (cells classified by a Lipschitz bound of f,
// leaves of 0.25 mm with the exact volume of a cube cut by the linearised f), error bounded by
// the difference to the same integration with 0.5 mm leaves; the signed distance by Newton
// projection onto {f = 0} and a descent of |q - x| along the surface (foot point).
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "phantom_internal.h"

namespace endocast {

using namespace phantom_detail;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Beyond this distance (mm; |f| > lipschitz times it) the signed distance returns the estimate
/// f / max(|grad f|, 1).
constexpr double kExactBandMm = 6.0;
/// Beyond this distance (mm) of the first foot point, 14 more starts look for a nearer one.
constexpr double kMultiStartMm = 0.5;

/// Polynomial smooth minimum of (a, ga) and (b, gb) with blend radius k (> 0): exactly min(a, b)
/// when |a - b| >= k, at most k/4 below it; its gradient is the same convex combination.
double smooth_min(double a, const Vec3& ga, double b, const Vec3& gb, double k, Vec3& g) {
    const double h = std::clamp(0.5 + 0.5 * (b - a) / k, 0.0, 1.0);
    if (h >= 1.0) {  // exactly (a, ga): a primitive that cannot matter may be skipped
        g = ga;
        return a;
    }
    if (h <= 0.0) {
        g = gb;
        return b;
    }
    g = add(gb, mul(sub(ga, gb), h));
    return b + (a - b) * h - k * h * (1.0 - h);
}

}  // namespace

double SkullBasePrim::eval(const Vec3& q, Vec3& g) const {
    switch (kind) {
        case Kind::Ellipsoid: {
            const Vec3 d = sub(q, c);
            double u[3], w[3], k0 = 0, k1 = 0;
            for (int a = 0; a < 3; ++a) {
                u[a] = dot(axes[a], d) / r[a];
                w[a] = u[a] / r[a];
                k0 += u[a] * u[a];
                k1 += w[a] * w[a];
            }
            k0 = std::sqrt(k0);
            k1 = std::sqrt(k1);
            if (k1 < 1e-12 || k0 < 1e-12) {
                g = {0, 0, 0};
                return -std::min({r[0], r[1], r[2]});
            }
            g = {0, 0, 0};
            if (k0 < 1.0) {
                // Inside: rmin (k0 - 1), whose gradient has |.| <= 1 (k0 (k0 - 1) / k1 is
                // steep near the centre of a flat ellipsoid); the same f / |grad f|.
                const double rmin = std::min({r[0], r[1], r[2]});
                for (int a = 0; a < 3; ++a) g = add(g, mul(axes[a], rmin * w[a] / k0));
                return rmin * (k0 - 1.0);
            }
            const double f = k0 * (k0 - 1.0) / k1;
            for (int a = 0; a < 3; ++a) {
                const double gl =
                    ((2.0 * k0 - 1.0) * (w[a] / k0) - f * (w[a] / (r[a] * r[a])) / k1) / k1;
                g = add(g, mul(axes[a], gl));
            }
            return f;
        }
        case Kind::Capsule: {
            const Vec3 ab = sub(b, c);
            const double t = std::clamp(dot(sub(q, c), ab) / dot(ab, ab), 0.0, 1.0);
            const Vec3 v = sub(q, add(c, mul(ab, t)));
            const double l = norm(v);
            g = l > 1e-12 ? mul(v, 1.0 / l) : Vec3{0, 0, 1};
            return l - radius;
        }
        case Kind::Box: {  // exact distance to the box of half sizes r rounded by `radius`
            double a[3], out2 = 0, inner = -kInf;
            int arg = 0;
            for (int i = 0; i < 3; ++i) {
                a[i] = std::fabs(q[i] - c[i]) - (r[i] - radius);
                if (a[i] > 0) out2 += a[i] * a[i];
                if (a[i] > inner) {
                    inner = a[i];
                    arg = i;
                }
            }
            g = {0, 0, 0};
            if (out2 > 0) {
                const double l = std::sqrt(out2);
                for (int i = 0; i < 3; ++i)
                    g[i] = a[i] > 0 ? std::copysign(a[i] / l, q[i] - c[i]) : 0.0;
                return l - radius;
            }
            g[arg] = std::copysign(1.0, q[arg] - c[arg]);
            return inner - radius;
        }
        case Kind::HalfSpace:
            g = axes[0];
            return dot(axes[0], sub(q, c));
    }
    g = {0, 0, 0};
    return kInf;
}

double SkullBasePrim::lower_bound(const Vec3& q) const {
    switch (kind) {
        case Kind::Ellipsoid: {
            // k0 / k1 >= rmin, so k0 (k0 - 1) / k1 >= rmin (k0 - 1) outside; inside the value is
            // rmin (k0 - 1).
            const Vec3 d = sub(q, c);
            double k0 = 0;
            for (int a = 0; a < 3; ++a) {
                const double u = dot(axes[a], d) / r[a];
                k0 += u * u;
            }
            return std::min({r[0], r[1], r[2]}) * (std::sqrt(k0) - 1.0);
        }
        case Kind::Capsule: {  // distance to the segment >= distance to its midpoint - half length
            const Vec3 mid = mul(add(c, b), 0.5);
            return norm(sub(q, mid)) - 0.5 * norm(sub(b, c)) - radius;
        }
        case Kind::Box:
        case Kind::HalfSpace: {
            Vec3 g;
            return eval(q, g);
        }
    }
    return -kInf;
}

bool SkullBasePrim::at_least(const Vec3& q, double threshold) const {
    if (kind == Kind::Ellipsoid) {  // k0 >= |d| / rmax first: no rotation
        const double rmax = std::max({r[0], r[1], r[2]}), rmin = std::min({r[0], r[1], r[2]});
        if (rmin * (norm(sub(q, c)) / rmax - 1.0) >= threshold) return true;
    }
    return lower_bound(q) >= threshold;
}

double SkullBaseModel::eval(const Vec3& q, Vec3& g) const {
    double f = kInf;
    Vec3 gp;
    const Vec3 mirrored{-q[0], q[1], q[2]};
    for (const Term& t : terms) {
        // Skip a term that leaves (f, g) exactly as it is: its lower bound says v >= f + k
        // (union) or v >= k - f (subtraction); a mirrored pair's value is >= min - k/4.
        const double skip = t.op == Op::Union ? f + t.k : t.k - f;
        if (t.op != Op::First &&
            (t.mirror_x ? t.prim.at_least(q, skip + 0.25 * t.k) && t.prim.at_least(mirrored, skip + 0.25 * t.k)
                        : t.prim.at_least(q, skip)))
            continue;
        double v = t.prim.eval(q, gp);
        if (t.mirror_x) {  // smooth_min is symmetric in its operands: so is f
            Vec3 gm;
            const double vm = t.prim.eval(mirrored, gm);
            gm[0] = -gm[0];
            v = smooth_min(v, gp, vm, gm, t.k, gp);
        }
        switch (t.op) {
            case Op::First:
                f = v;
                g = gp;
                break;
            case Op::Union:
                f = smooth_min(f, g, v, gp, t.k, g);
                break;
            case Op::Subtract:  // max(f, -v) = -min(-f, v)
                f = -smooth_min(-f, mul(g, -1.0), v, gp, t.k, g);
                g = mul(g, -1.0);
                break;
            }
    }
    return f;
}

double SkullBaseModel::lower_bound(const Vec3& q, double radius) const {
    // With F <= f and v >= lb >= F + k, smooth_min(f, v) = f - (k - (v - f))^2 / (4k) >= F when
    // v - f < k (the deficit is at most (f - F)^2 / (4k) <= f - F), else f: F stays a bound. The
    // primitives' bounds are 1-Lipschitz: less the radius, they hold over the ball.
    double F = kInf;
    const Vec3 mirrored{-q[0], q[1], q[2]};
    for (const Term& t : terms) {
        if (t.op == Op::Subtract) continue;
        double lb = t.prim.lower_bound(q) - radius;
        if (t.mirror_x) lb = std::min(lb, t.prim.lower_bound(mirrored) - radius) - 0.25 * t.k;
        if (t.op == Op::First) F = lb;
        else if (lb < F + t.k) F = std::min(F, lb) - 0.25 * t.k;
    }
    return F;
}

Vec3 SkullBaseModel::to_phantom(const Vec3& world) const {
    const Vec3 w = sub(world, centre);
    return {w[0], cs * w[1] + sn * w[2], -sn * w[1] + cs * w[2]};
}
Vec3 SkullBaseModel::dir_to_world(const Vec3& v) const {
    return {v[0], cs * v[1] - sn * v[2], sn * v[1] + cs * v[2]};
}
Vec3 SkullBaseModel::to_world(const Vec3& q) const { return add(centre, dir_to_world(q)); }

namespace {

/// g without its component along the unit normal `plane` (none: g itself).
Vec3 in_plane(const Vec3& g, const Vec3* plane) {
    return plane ? sub(g, mul(*plane, dot(g, *plane))) : g;
}

/// Newton projection of x onto {f = 0} (within the plane through x with normal `plane` when
/// given; steps capped at 4 mm); false when it does not converge.
bool project_to_surface(const SkullBaseModel& m, const Vec3* plane, Vec3& x, Vec3& g) {
    for (int it = 0; it < 40; ++it) {
        const double f = m.eval(x, g);
        const Vec3 gp = in_plane(g, plane);
        const double g2 = dot(gp, gp);
        if (g2 < 1e-12) return false;
        if (std::fabs(f) < 1e-11) return true;
        Vec3 step = mul(gp, f / g2);
        const double l = norm(step);
        if (l > 4.0) step = mul(step, 4.0 / l);
        x = sub(x, step);
    }
    return std::fabs(m.eval(x, g)) < 1e-7;
}

/// Distance from q to its foot point on {f = 0} (optionally restricted to the plane through q
/// with normal `plane`, for the rim of a crop), from `start` (default q): Newton projection, then
/// tangential steps along the surface (or the curve), halved until |q - x| decreases, until the
/// tangential offset is below 1e-7 mm. Returns +inf when no surface point is found.
double foot_point(const SkullBaseModel& m, const Vec3& q, const Vec3* plane, Vec3& foot,
                  const Vec3* start = nullptr) {
    auto tangent = [&](const Vec3& g) { return in_plane(g, plane); };
    auto project = [&](Vec3& x, Vec3& g) { return project_to_surface(m, plane, x, g); };
    Vec3 x = start ? *start : q, g;
    if (!project(x, g)) return kInf;
    double best = norm(sub(q, x));
    for (int it = 0; it < 60; ++it) {
        const Vec3 n = normalized(tangent(g));
        const Vec3 r = sub(q, x);
        Vec3 t = sub(r, mul(n, dot(r, n)));
        if (plane) t = sub(t, mul(*plane, dot(t, *plane)));
        if (norm(t) < 1e-7) break;
        bool moved = false;
        for (double a = 1.0; a > 1e-4 && !moved; a *= 0.5) {
            Vec3 y = add(x, mul(t, a)), gy;
            if (!project(y, gy)) continue;
            const double d = norm(sub(q, y));
            if (d < best) {
                best = d;
                x = y;
                g = gy;
                moved = true;
            }
        }
        if (!moved) break;
    }
    foot = x;
    return best;
}

}  // namespace

double SkullBaseModel::signed_distance(const Vec3& q) const {
    Vec3 g, foot;
    const double f = eval(q, g);
    const double first_order = f / std::max(norm(g), 1.0);
    // Far from the surface (|f| / lipschitz > 6 mm) only the sign is promised: an estimate.
    if (std::fabs(f) > lipschitz * kExactBandMm &&
        (!cropped || (f < 0 ? dot(plane_n, q) - plane_h > kExactBandMm : true)))
        return first_order;
    double df = foot_point(*this, q, nullptr, foot);
    if (!std::isfinite(df)) df = std::fabs(first_order);
    if (df > kMultiStartMm) {
        // Another part of the surface may be nearer than this local foot point. Probe the 14
        // points at 1.5 df around q (face and corner directions of a cube): one across the
        // surface (f of the other sign) more than 60 degrees away from the foot's direction
        // hints at another sheet; descend from it.
        const Vec3 to_foot = mul(sub(foot, q), 1.0 / df);
        for (int e = 0; e < 14; ++e) {
            Vec3 dir{0, 0, 0};
            if (e < 6) dir[e / 2] = e % 2 ? -1.0 : 1.0;
            else dir = mul(Vec3{e & 1 ? 1.0 : -1.0, e & 2 ? 1.0 : -1.0, e & 4 ? 1.0 : -1.0}, 1 / std::sqrt(3.0));
            if (dot(dir, to_foot) > 0.5) continue;
            const Vec3 st = add(q, mul(dir, 1.5 * df));
            Vec3 gs, other;
            if ((eval(st, gs) < 0) == (f < 0)) continue;
            const double d = foot_point(*this, q, nullptr, other, &st);
            if (d < df) {
                df = d;
                foot = other;
            }
        }
    }
    if (!cropped) return f < 0 ? -df : df;
    const double dp = dot(plane_n, q) - plane_h;  // > 0 on the kept side
    if (f < 0 && dp >= 0) return -std::min(df, dp);
    double best = kInf;
    if (dot(plane_n, foot) >= plane_h) best = df;  // the surface part above the plane
    const Vec3 qp = sub(q, mul(plane_n, dp));
    Vec3 gq;
    if (dp < 0 && eval(qp, gq) < 0) best = std::min(best, -dp);  // the flat cap
    Vec3 rim;
    const double dr = foot_point(*this, qp, &plane_n, rim);  // the rim curve
    if (std::isfinite(dr)) best = std::min(best, std::hypot(dr, dp));
    if (!std::isfinite(best)) best = std::max(std::fabs(first_order), -dp);
    return best;
}

namespace phantom_detail {

SkullBasePrim ellipsoid(const Vec3& c, const Vec3& r, double yaw_deg) {
    SkullBasePrim p;
    p.kind = SkullBasePrim::Kind::Ellipsoid;
    p.c = c;
    p.r = r;
    const double a = yaw_deg * kPi / 180.0;
    p.axes = {{{std::cos(a), std::sin(a), 0}, {-std::sin(a), std::cos(a), 0}, {0, 0, 1}}};
    return p;
}

SkullBasePrim capsule(const Vec3& a, const Vec3& b, double r) {
    SkullBasePrim p;
    p.kind = SkullBasePrim::Kind::Capsule;
    p.c = a;
    p.b = b;
    p.radius = r;
    return p;
}

SkullBasePrim half_space(const Vec3& c, const Vec3& n) {
    SkullBasePrim p;
    p.kind = SkullBasePrim::Kind::HalfSpace;
    p.c = c;
    p.axes[0] = normalized(n);
    return p;
}

double Canal::sd(const Vec3& q) const {
    const Vec3 d = sub(q, start);
    const double s = dot(d, u);
    const double x = dot(d, v) / a, y = dot(d, w) / b;
    const double k0 = std::hypot(x, y), k1 = std::hypot(x / a, y / b);
    const double radial = k1 < 1e-12 ? -std::min(a, b) : k0 * (k0 - 1.0) / k1;
    return std::max({radial, -inset - s, s - length});
}

Vec3 inner_table_point(const SkullBaseModel& m, const Vec3& p, const Vec3& u, double step) {
    Vec3 g;
    if (!(m.eval(p, g) < 0)) throw std::logic_error("implicit phantom: a canal starts outside");
    double lo = 0, hi = step;
    while (m.eval(add(p, mul(u, hi)), g) < 0) {
        lo = hi;
        hi += step;
    }
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (m.eval(add(p, mul(u, mid)), g) < 0 ? lo : hi) = mid;
    }
    return add(p, mul(u, hi));
}

}  // namespace phantom_detail

namespace {

// ---- anatomy (human sizes in mm, phantom frame; every length scales by Anatomy::s) -----------

/// The orbit: a cone from the apex to the base disk (radius at the base), as in phantom.cpp.
struct Cone {
    Vec3 apex{0, 0, 0}, u{0, 1, 0};
    double length = 1, radius = 1;
    double sd(const Vec3& q) const {
        const Vec3 d = sub(q, apex);
        const double a = dot(d, u);
        const double rho = std::sqrt(std::max(0.0, dot(d, d) - a * a));
        const double side = (rho * length - a * radius) / std::hypot(length, radius);
        return std::max({side, -a, a - length});
    }
};

struct Anatomy {
    double s = 1;           ///< geometric scale (macaque 0.4)
    double plate = 1;       ///< scale of the thin plates (macaque 0.5: the same in voxels)
    std::shared_ptr<SkullBaseModel> model;
    std::vector<SkullBasePrim> base_solids;  ///< solid bone of the skull base and the face
    Cone orbit[2];
    Vec3 roof_centre[2];    ///< thinnest point of each orbital roof (x, y), mm
    Vec3 nasal_c, nasal_half;
    std::vector<Canal> canals;
    Vec3 squama_c[2];       ///< thin lateral bone (squamous temporal, middle fossa floor)
    double squama_r = 32;
    // spine (phantom frame): canal axis x = 0, y = spine_y
    double spine_y = 0, canal_r = 8, ring_top = 0, wall = 5, ring_h = 15, ring_gap = 4;
    double body_y = 0, body_r = 9, pillar_x = 14, pillar_r = 4, fm_z = 0;
    Vec3 box_lo, box_hi;    ///< phantom-frame box of the head (bone + soft tissue + margin)

    double vault_thickness(const Vec3& q) const {
        double w = 0;
        for (const Vec3& c : squama_c) {
            const double t = norm(sub(q, c)) / squama_r;
            w = std::max(w, std::clamp(1.0 - t * t, 0.0, 1.0));
        }
        return s * (6.0 - 3.5 * w);
    }
    double roof_thickness(const Vec3& q) const {
        double rho = kInf;
        for (const Vec3& c : roof_centre) rho = std::min(rho, std::hypot(q[0] - c[0], q[1] - c[1]));
        const double t = std::min(1.0, rho / (12.0 * s));
        return plate * (0.5 + 0.5 * t * t);
    }
};

/// The cavity function's terms (human numbers; P() scales them).
void build_cavity(Anatomy& an) {
    const double s = an.s;
    auto P = [s](double x, double y, double z) { return Vec3{x * s, y * s, z * s}; };
    using Op = SkullBaseModel::Op;
    auto& t = an.model->terms;
    auto push = [&](Op op, const SkullBasePrim& p, double k) { t.push_back({op, p, k * s}); };
    SkullBasePrim floor;  // under the anterior fossa (y > 5): the cerebrum keeps z >= -20
    floor.kind = SkullBasePrim::Kind::Box;
    floor.c = P(0, 62.5, -75);
    floor.r = P(90, 57.5, 55);
    floor.radius = 6 * s;
    push(Op::First, ellipsoid(P(0, 0, 12), P(68, 84, 54)), 1);       // cerebrum
    push(Op::Subtract, floor, 6);
    for (double x : {-1.0, 1.0})                                      // middle fossae
        push(Op::Union, ellipsoid(P(40 * x, 2, -26), P(22, 32, 20), 12.0 * x), 5);
    push(Op::Union, ellipsoid(P(0, 14, -27), P(7, 6, 8)), 2);        // sella turcica
    push(Op::Union, ellipsoid(P(0, 42, -21), P(7, 20, 6)), 3);       // olfactory groove
    for (double x : {-1.0, 1.0})                                      // cerebellar lobes
        push(Op::Union, ellipsoid(P(26 * x, -50, -38), P(30, 30, 22)), 6);
    push(Op::Union, capsule(P(0, -4, -24), P(0, -30, -44), 12 * s), 5);  // brainstem on the clivus
    push(Op::Union, ellipsoid(P(0, -40, -46), P(18, 20, 12)), 5);    // basin over the magnum
    for (double x : {-1.0, 1.0})                                      // sphenoid wings
        push(Op::Subtract, ellipsoid(P(32 * x, 32, -19), P(24, 12, 3.5)), 2);
    for (double x : {-1.0, 1.0})                                      // petrous ridges
        push(Op::Subtract, capsule(P(14 * x, -12, -40), P(60 * x, -34, -38), 9 * s), 3);
    push(Op::Subtract, ellipsoid(P(0, 6, -24), P(9, 2.2, 8)), 1.5);  // dorsum sellae
    an.model->box_lo = P(-70, -86, -64);
    an.model->box_hi = P(70, 86, 68);
}

/// The openings, both sides (human numbers: name, a point inside the cavity, outward axis,
/// semi-axes a (along the hint direction) and b, length through the bone).
void build_canals(Anatomy& an) {
    const double s = an.s;
    struct Spec { const char* name; Vec3 p, u, hint; double a, b, len; };
    const Spec specs[] = {
        {"optic_canal", {9, 18, -19}, {4, 16, -3}, {1, 0, 0}, 2.5, 2.5, 26},
        {"superior_orbital_fissure", {30, 24, -28}, {-0.25, 1, 0}, {1, 0, 0.3}, 10, 2, 24},
        {"foramen_rotundum", {30, 18, -36}, {0, 1, -1}, {1, 0, 0}, 1.5, 1.5, 42},
        {"foramen_ovale", {26, 6, -36}, {0.15, -0.1, -1}, {0, 1, 0}, 3.5, 2, 30},
        {"foramen_spinosum", {33, -3, -36}, {0.1, -0.1, -1}, {1, 0, 0}, 1, 1, 30},
        {"foramen_lacerum", {22, -4, -30}, {-0.25, 0, -1}, {1, 0, 0}, 3, 3, 40},
        {"jugular_foramen", {30, -36, -45}, {0.3, 0.2, -1}, {0.5, 1, 0}, 7.5, 5, 30},
        {"internal_acoustic_meatus", {24, -30, -40}, {1, 0.2, -0.6}, {0, 0, 1}, 2.25, 2.25, 32},
        {"hypoglossal_canal", {20, -30, -44}, {0.6, 0.5, -0.6}, {0, 0, 1}, 1.5, 1.5, 25},
    };
    auto add_canal = [&](const std::string& name, const Vec3& p, Vec3 u, Vec3 hint, double a,
                         double b, double len) {
        Canal c;
        c.name = name;
        c.u = normalized(u);
        c.v = normalized(sub(hint, mul(c.u, dot(hint, c.u))));
        c.w = cross(c.u, c.v);
        c.a = a * s;
        c.b = b * s;
        c.length = len * s;
        c.start = inner_table_point(*an.model, mul(p, s), c.u, 0.25 * s);
        Vec3 g;
        an.model->eval(c.start, g);
        const double cosine = std::fabs(dot(normalized(g), c.u));
        c.covering_radius = std::max(c.a, c.b) / std::max(cosine, 0.3);
        an.canals.push_back(c);
    };
    add_canal("foramen_magnum", {0, -40, -45}, {0, 0, -1}, {0, 1, 0}, 17.5, 15, 12);  // first
    for (const Spec& sp : specs)
        for (double x : {-1.0, 1.0}) {
            const Vec3 m{x, 1, 1};  // mirror
            auto mir = [&](const Vec3& v) { return Vec3{v[0] * m[0], v[1], v[2]}; };
            add_canal(std::string(sp.name) + (x < 0 ? "_left" : "_right"), mir(sp.p), mir(sp.u),
                      mir(sp.hint), sp.a, sp.b, sp.len);
        }
    for (double x : {-1.0, 1.0})  // cribriform plate: 1 mm holes into the nasal cavity
        for (int i = 0; i < 5; ++i)
            add_canal("cribriform_hole_" + std::string(x < 0 ? "left_" : "right_") +
                          std::to_string(i + 1),
                      {3.5 * x, 32.0 + 6.0 * i, -24.0}, {0, 0, -1}, {1, 0, 0}, 0.5 * an.plate / s,
                      0.5 * an.plate / s, 5);
}

/// The whole anatomy at scale s; spine placement follows the foramen magnum.
Anatomy build_anatomy(PhantomPreset preset) {
    Anatomy an;
    an.s = preset == PhantomPreset::Macaque ? 0.4 : 1.0;
    an.plate = preset == PhantomPreset::Macaque ? 0.5 : 1.0;
    const double s = an.s;
    auto P = [s](double x, double y, double z) { return Vec3{x * s, y * s, z * s}; };
    an.model = std::make_shared<SkullBaseModel>();
    build_cavity(an);
    an.base_solids.push_back(ellipsoid(P(0, 5, -48), P(30, 45, 22)));  // sphenoid body, clivus
    for (double x : {-1.0, 1.0})                                        // petrous bones
        an.base_solids.push_back(capsule(P(16 * x, -14, -48), P(62 * x, -36, -45), 12 * s));
    an.base_solids.push_back(ellipsoid(P(0, 62, -45), P(52, 42, 28)));  // face
    for (int i = 0; i < 2; ++i) {
        const double x = i == 0 ? -1.0 : 1.0;
        const Vec3 apex = P(13 * x, 30, -24), base = P(38 * x, 110, -18);
        an.orbit[i].apex = apex;
        an.orbit[i].u = normalized(sub(base, apex));
        an.orbit[i].length = norm(sub(base, apex));
        an.orbit[i].radius = 24 * s;
        an.roof_centre[i] = P(22 * x, 60, 0);
        an.squama_c[i] = P(54 * x, 0, -26);
    }
    an.squama_r = 32 * s;
    an.nasal_c = P(0, 69, -52);
    an.nasal_half = P(9, 41, 26);
    build_canals(an);
    const Canal& fm = an.canals.front();
    an.fm_z = fm.start[2];
    an.spine_y = fm.start[1];
    an.canal_r = 8 * s;
    an.wall = 5 * s;
    an.ring_h = 15 * s;
    an.ring_gap = 4 * s;
    an.ring_top = an.fm_z - 8 * s;
    an.body_r = 9 * s;
    an.body_y = an.spine_y + an.canal_r + an.wall + an.body_r - 2 * s;
    an.pillar_x = an.canal_r + 6 * s;
    an.pillar_r = 4 * s;
    an.box_lo = P(-89, -105, -90);
    an.box_hi = P(89, 120, 87);
    return an;
}

}  // namespace
namespace {

// ---- truth volume: adaptive octree ---------------------------------------------------------

/// Fraction of the cube [-H/2, H/2]^3 where the linear function d + n.x (|n| = 1) is negative:
/// the distribution function at -d of a sum of three uniform variables of widths H |n_i|
/// (the closed form of the convolution of three boxes; widths floored at 1e-4 H).
double cube_fraction(double d, const Vec3& n, double H) {
    double wd[3], W = 0;
    for (int a = 0; a < 3; ++a) {
        wd[a] = std::max(H * std::fabs(n[a]), 1e-4 * H);
        W += wd[a];
    }
    const double t = -d + 0.5 * W;
    if (t <= 0) return 0.0;
    if (t >= W) return 1.0;
    double sum = 0;
    for (int e = 0; e < 8; ++e) {
        double c = t;
        int bits = 0;
        for (int a = 0; a < 3; ++a)
            if (e & (1 << a)) {
                c -= wd[a];
                ++bits;
            }
        if (c > 0) sum += (bits % 2 ? -1.0 : 1.0) * c * c * c;
    }
    return std::clamp(sum / (6.0 * wd[0] * wd[1] * wd[2]), 0.0, 1.0);
}

struct Tally {
    double volume = 0;     ///< mm^3
    double lowest = kInf;  ///< lowest world z (relative to the centre) of the surface, mm
};

/// Integrates the cavity (∩ the crop half-space when the model is cropped) over the cube of side
/// H centred at c, subdividing down to leaves of side hmin.
void integrate_cell(const SkullBaseModel& m, const Vec3& c, double H, double hmin, Tally& t) {
    Vec3 g;
    const double f = m.eval(c, g);
    const double r = 0.5 * H * std::sqrt(3.0);
    const double p = m.cropped ? m.plane_h - dot(m.plane_n, c) : -kInf;  // <= 0 kept
    if (f > m.lipschitz * r || p > r) return;
    const bool leaf = H <= hmin * 1.000001;
    if (f < -m.lipschitz * r && p < -r) {
        t.volume += H * H * H;
        return;
    }
    if (leaf) {
        const double gl = std::max(norm(g), 1e-9);
        const double df = f / gl;
        const bool plane_rules = p > df;
        const Vec3 n = plane_rules ? mul(m.plane_n, -1.0) : mul(g, 1.0 / gl);
        t.volume += H * H * H * cube_fraction(plane_rules ? p : df, n, H);
        if (std::fabs(df) < H) {
            const Vec3 x = sub(c, mul(n, plane_rules ? 0.0 : df));
            if (!m.cropped || dot(m.plane_n, x) >= m.plane_h)
                t.lowest = std::min(t.lowest, m.sn * x[1] + m.cs * x[2]);
        }
        return;
    }
    const double h = 0.25 * H;
    for (int k = 0; k < 8; ++k)
        integrate_cell(m, add(c, Vec3{k & 1 ? h : -h, k & 2 ? h : -h, k & 4 ? h : -h}), 0.5 * H,
                       hmin, t);
}

/// The cavity's volume (mm^3) with leaves of hmin mm, and the lowest surface point; top cells of
/// 16 leaves, summed in a fixed order (the same bytes for any thread count).
Tally integrate_cavity(const SkullBaseModel& m, double hmin) {
    const double H = 16.0 * hmin;
    int64_t n[3];
    for (int a = 0; a < 3; ++a)
        n[a] = static_cast<int64_t>(std::ceil((m.box_hi[a] - m.box_lo[a]) / H));
    const int64_t cells = n[0] * n[1] * n[2];
    std::vector<Tally> part(static_cast<size_t>(cells));
#pragma omp parallel for schedule(dynamic, 4)
    for (int64_t i = 0; i < cells; ++i) {
        const int64_t x = i % n[0], y = (i / n[0]) % n[1], z = i / (n[0] * n[1]);
        const Vec3 c{m.box_lo[0] + (static_cast<double>(x) + 0.5) * H,
                     m.box_lo[1] + (static_cast<double>(y) + 0.5) * H,
                     m.box_lo[2] + (static_cast<double>(z) + 0.5) * H};
        integrate_cell(m, c, H, hmin, part[static_cast<size_t>(i)]);
    }
    Tally t;
    for (const Tally& p : part) {
        t.volume += p.volume;
        t.lowest = std::min(t.lowest, p.lowest);
    }
    return t;
}

}  // namespace
namespace {

// ---- rendering -------------------------------------------------------------------------------

struct Renderer : EdgeBlur {
    explicit Renderer(const Anatomy& a) : an(a) {}
    const Anatomy& an;
    double content = kBrain;  ///< HU in the cavity
    double fill = kBrain;     ///< HU in the canals and the spinal canal
    double orbit_fill = kFat;
    bool has_soft = true;     ///< scalp and neck soft tissue
    bool spine = false;

    /// What lies outside the skull: air, soft tissue (scalp, neck), the cervical spine.
    double outside_value(const Vec3& q, double d_bone) const {
        const double s = an.s;
        double v = kAir;
        if (has_soft) {
            const double neck = std::max(std::hypot(q[0], q[1] + 20.0 * s) - 50.0 * s, q[2] + 30.0 * s);
            v = mix(v, kSoftTissue, step(std::min(d_bone - 5.0 * s, neck)));
        }
        if (!spine || q[2] > an.fm_z + band) return v;
        const double sy = q[1] - an.spine_y, rho = std::hypot(q[0], sy);
        if (std::fabs(q[0]) > an.pillar_x + an.pillar_r + band ||
            sy < -(an.canal_r + an.wall + band) || q[1] > an.body_y + an.body_r + band)
            return v;
        const double period = an.ring_h + an.ring_gap, zl = an.ring_top - q[2];
        double ring_dz = -zl;
        if (zl >= 0) {
            const double m = std::fmod(zl, period);
            ring_dz = m <= an.ring_h ? -std::min(m, an.ring_h - m) : std::min(m - an.ring_h, period - m);
        }
        const double d_ring = std::max({rho - an.canal_r - an.wall, an.canal_r - rho, ring_dz});
        const double d_body = std::max(std::hypot(q[0], q[1] - an.body_y) - an.body_r, ring_dz);
        const double d_pillar =
            std::max(std::hypot(std::fabs(q[0]) - an.pillar_x, sy) - an.pillar_r, q[2] - an.fm_z);
        v = mix(v, kSpineBoneHu, step(std::min({d_ring, d_body, d_pillar})));
        return mix(v, fill, step(std::max(rho - an.canal_r, q[2] - (an.fm_z - 2.0 * an.s))));
    }

    static double mix(double a, double b, double t) { return a + (b - a) * t; }

    /// HU at the phantom-frame point q (before noise).
    double hu(const Vec3& q) const {
        Vec3 g;
        const double d_c = cavity_distance(an.model->eval(q, g), g);
        if (sigma > 0 ? d_c <= -band : d_c < 0) return content;
        double d_bone = d_c - an.vault_thickness(q);
        for (const SkullBasePrim& b : an.base_solids) d_bone = std::min(d_bone, b.eval(q, g));
        if (d_bone >= band && d_c >= band) return outside_value(q, d_bone);
        SoftBlend soft{*this};
        soft.add(-d_bone, outside_value(q, d_bone));
        for (const Cone& o : an.orbit) soft.add(std::max(o.sd(q), an.roof_thickness(q) - d_c), orbit_fill);
        double box = -kInf;
        for (int a = 0; a < 3; ++a) box = std::max(box, std::fabs(q[a] - an.nasal_c[a]) - an.nasal_half[a]);
        soft.add(std::max(box, an.plate - d_c), kAir);
        for (const Canal& c : an.canals) {
            if (norm(sub(q, c.start)) > c.length + 2.0 * std::max(c.a, c.b) + band + 2.0) continue;
            soft.add(std::max(c.sd(q), -d_c), fill);
        }
        const double s_c = step(d_c);
        const double s_soft = std::min(soft.fraction(), 1.0 - s_c);
        return content * s_c + soft.value() * s_soft + kBoneHu * (1.0 - s_c - s_soft);
    }
};

}  // namespace

namespace phantom_detail {

double truth_volume(const SkullBaseModel& m, double h, double& error_ml, double* lowest) {
    const Tally fine = integrate_cavity(m, h), coarse = integrate_cavity(m, 2.0 * h);
    error_ml = (std::fabs(fine.volume - coarse.volume) + 1e-9 * fine.volume) / 1000.0;
    if (lowest) *lowest = fine.lowest;
    return fine.volume / 1000.0;
}

Vec3 validated_spacing(const PhantomParams& p, double default_spacing, const std::string& kind) {
    Vec3 spacing = p.spacing;
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(spacing[a]) || spacing[a] < 0)
            throw InvalidParameter("phantom spacing[" + std::to_string(a) + "] is " +
                                   fmt(spacing[a]) + " mm, expected > 0 (or 0 for the default)");
        if (spacing[a] == 0) spacing[a] = default_spacing;
        if (p.size[a] < 0)
            throw InvalidParameter("phantom size[" + std::to_string(a) + "] is " +
                                   std::to_string(p.size[a]) + ", expected >= 0 (0 = automatic)");
        if (!std::isfinite(p.origin[a]))
            throw InvalidParameter("phantom origin[" + std::to_string(a) + "] is not finite");
        if (!std::isfinite(p.grid_centre_mm[a]))
            throw InvalidParameter("phantom grid centre[" + std::to_string(a) + "] is not finite");
    }
    if (!std::isfinite(p.tilt_deg) || p.tilt_deg < -90.0 || p.tilt_deg > 90.0)
        throw InvalidParameter("phantom tilt is " + fmt(p.tilt_deg) +
                               " degrees, expected within [-90, 90]");
    if (p.frontal_sinus || p.orbits || p.body || p.optic_canal_radius_mm != 0.0)
        throw InvalidParameter(
            "the " + kind + " phantom has its own orbits and nasal cavity: frontal sinus, orbits, "
            "optic canal radius and body are not available with it");
    if (!std::isfinite(p.crop_base_mm) || p.crop_base_mm < 0)
        throw InvalidParameter("phantom crop of the base is " + fmt(p.crop_base_mm) +
                               " mm, expected >= 0 (0 = off)");
    return spacing;
}

Geometry layout_grid(const PhantomParams& p, const SkullBaseModel& m, const Vec3& plo, const Vec3& phi,
                     const Vec3& spacing, double crop_z, bool slabs, Vec3& centre) {
    Vec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
    for (int c = 0; c < 8; ++c) {
        const Vec3 w = m.dir_to_world({c & 1 ? phi[0] : plo[0], c & 2 ? phi[1] : plo[1],
                                       c & 4 ? phi[2] : plo[2]});
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], w[a]);
            hi[a] = std::max(hi[a], w[a]);
        }
    }
    const bool crop = crop_z > -kInf;
    if (crop) lo[2] = crop_z + 0.5 * spacing[2];
    // An explicit size centres the grid on p.grid_centre_mm: the phantom origin lies -R g from it.
    const Vec3 shift = m.dir_to_world(p.grid_centre_mm);
    Geometry geom;
    Vec3 ci{};
    for (int a = 0; a < 3; ++a) {
        if (p.size[a] > 0) {
            geom.dims[a] = p.size[a];
            ci[a] = 0.5 * static_cast<double>(p.size[a] - 1) - shift[a] / spacing[a];
        } else {
            geom.dims[a] = static_cast<int64_t>(std::ceil((hi[a] - lo[a]) / spacing[a])) + 1;
            ci[a] = -lo[a] / spacing[a];
        }
        if (a == 2 && crop) ci[a] = -lo[a] / spacing[a];
    }
    check_phantom_voxels(geom.dims, slabs);
    geom.spacing = spacing;
    geom.origin = p.origin;
    centre = geom.index_to_world(ci[0], ci[1], ci[2]);
    return geom;
}

PhantomResult generate_skull_base_phantom(const PhantomParams& p, int64_t slab_voxels, const PhantomSlabSink& sink) {
    const bool macaque = p.preset == PhantomPreset::Macaque;
    const Vec3 spacing = validated_spacing(p, macaque ? 0.5 : 1.0, "skull-base");
    Anatomy an = build_anatomy(p.preset);
    SkullBaseModel& m = *an.model;
    const double tilt = p.tilt_deg * kPi / 180.0;
    m.cs = std::cos(tilt);
    m.sn = std::sin(tilt);
    const double h = 0.25 * an.s;  // leaves of the truth integration, mm
    PhantomResult res;
    const bool crop = p.crop_base_mm > 0;
    double lowest = 0;  // of the cavity, world z relative to the centre (leaves of 2h when cropped)
    if (crop) lowest = integrate_cavity(m, 2.0 * h).lowest;
    else res.true_ecv_ml = truth_volume(m, h, res.true_ecv_error_ml, &lowest);
    res.true_ecv_slice_centres_ml = res.true_ecv_ml;
    const double height = m.box_hi[2] - m.box_lo[2];
    if (crop && p.crop_base_mm >= 0.5 * height)
        throw InvalidParameter("phantom crop of the base is " + fmt(p.crop_base_mm) +
                               " mm, expected below " + fmt(0.5 * height) + " mm");
    const double crop_z = lowest + p.crop_base_mm;  // world, relative to the centre
    Vec3 centre, plo = an.box_lo;
    if (p.spine)  // 7 vertebrae down
        plo[2] = std::min(plo[2], an.ring_top - 7.0 * (an.ring_h + an.ring_gap) + an.ring_gap);
    const Geometry geom = layout_grid(p, m, plo, an.box_hi, spacing, crop ? crop_z : -kInf, bool(sink), centre);
    m.centre = centre;
    res.crop_plane_z_mm = -kInf;
    if (crop) {
        m.cropped = true;
        m.plane_n = {0, m.sn, m.cs};  // R^T e_z
        m.plane_h = crop_z + 0.5 * spacing[2];
        res.true_ecv_slice_centres_ml = integrate_cavity(m, h).volume / 1000.0;
        m.plane_h = crop_z;
        res.true_ecv_ml = truth_volume(m, h, res.true_ecv_error_ml);
        res.cropped = true;
        res.crop_plane_z_mm = centre[2] + crop_z;
    }
    Renderer rd(an);
    const bool dry = p.preset == PhantomPreset::Dry;
    rd.content = rd.fill = dry ? kAir : kBrain;
    rd.orbit_fill = dry ? kAir : kFat;
    rd.has_soft = !dry && p.scalp;
    rd.spine = p.spine;
    if (p.blur) rd.set_sigma(kBlurVoxels * std::cbrt(spacing[0] * spacing[1] * spacing[2]));
    render_phantom_ct(geom, slab_voxels, sink, res, [&](int64_t k0, int64_t k1, int16_t* dst) {
        render_implicit(rd, m, p.noise, p.seed, geom, k0, k1, dst);
    });

    res.suggested_iso = 0.5 * (rd.content + kBoneHu);
    res.cavity_centre_world = centre;
    res.cavity_semi_axes_mm = mul(sub(m.box_hi, m.box_lo), 0.5);
    res.cavity_rotation = {1, 0, 0, 0, m.cs, -m.sn, 0, m.sn, m.cs};
    for (const Canal& c : an.canals)
        res.openings.push_back({c.name, m.to_world(c.start), m.dir_to_world(c.u), c.covering_radius});
    const Canal& fm = an.canals.front();
    res.foramen_magnum_world = m.to_world(fm.start);
    res.foramen_magnum_axis = m.dir_to_world(fm.u);
    res.foramen_magnum_radius_mm = fm.a;
    res.spinal_canal_radius_mm = p.spine ? an.canal_r : 0.0;
    res.optic_canal_radius_mm = an.canals[1].a;  // after the foramen magnum
    res.shell_thickness_mm = 6.0 * an.s;
    res.sigma_mm = rd.sigma;
    std::ostringstream d;
    d << to_string(p.preset) << " skull-base phantom " << geom.dims[0] << "x" << geom.dims[1]
      << "x" << geom.dims[2] << " voxels at " << fmt(spacing[0]) << "x" << fmt(spacing[1]) << "x"
      << fmt(spacing[2]) << " mm, tilt " << fmt(p.tilt_deg) << " deg, ECV " << fmt(res.true_ecv_ml)
      << " +- " << fmt(res.true_ecv_error_ml) << " mL, iso " << fmt(res.suggested_iso)
      << " HU, seed " << p.seed << "; features:" << (p.noise ? " noise" : "")
      << (p.blur ? " blur" : "") << " openings(" << res.openings.size() << ")"
      << (rd.has_soft ? " scalp+neck" : "") << (p.spine ? " spine" : "");
    if (crop) d << " cropped-base(" << fmt(p.crop_base_mm) << " mm)";
    res.description = d.str();
    res.skull_base = an.model;
    return res;
}

}  // namespace phantom_detail
}  // namespace endocast
