// The mouse phantom (PhantomPreset::Mouse): the cranium of an adult C57BL/6 mouse built as the
// skull-base phantom is (phantom/skull_base.cpp): the inner table is the zero set of one implicit
// function f (phantom frame, mm; cavity = {f < 0}) made of smooth unions of ellipsoids and capsules
// - two cerebral hemispheres over a flat floor with the hypophyseal fossa, the cerebellum with
// its paraflocculi, the brainstem, the olfactory bulbs cut flat by the cribriform plate, and the
// medulla's stub through the foramen magnum - and the truth is {f < 0} cut by the foramen magnum's
// plane.
//
// Bone: a shell of varying thickness outside the cavity, on the braincase side of that plane,
// joined to solid blocks (basisphenoid, basioccipital, snout, zygomatic arches, the bullae's outer
// ellipsoids); carved into it: the nasal cavity (air) with its septum and turbinates, the bullae
// (air), the foramina (canals of content), and the pores of the cribriform plate. Outside: scalp,
// eyes, orbits, jaws and neck (soft tissue), the spinal canal (content) inside the atlas and the
// vertebrae.
//
// Rendering: every region is blended by the erfc of its signed distance (a Gaussian blur of a
// planar edge), as in the skull-base phantom. Thin structures that lie inside one region - the
// pores of the plate, the turbinates and the septum in the nasal air - are added by linearity of
// the blur instead: the blurred pores are the plate's blurred slab times the exact 2-D blur of
// their disks (the Gaussian mass of a disk, tabulated per pore), the blurred turbinates the blurred
// indicator of a thin sheet of their thickness. So the plate is a sieve at 0.14 mm voxels (its
// bone averaged with ~25 % of pores, under the isovalue) and a plate with holes at 0.035 mm.
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

// ---- Hounsfield units (microCT: bright bone) -------------------------------------------------
constexpr double kMouseContent = 40.0;     ///< brain, CSF, cord, nerves, soft tissue, eyes
constexpr double kMouseBone = 1500.0;
constexpr double kVertebra = 1400.0;

// ---- sizes (mm) ------------------------------------------------------------------------------
constexpr double kDefaultSpacing = 0.07;
constexpr double kMargin = 1.0;       ///< automatic grid: air around the head
constexpr double kScalp = 0.6;        ///< soft tissue over the bone
constexpr double kMaxThickness = 0.4; ///< the braincase wall's largest thickness (Mouse::thickness)
constexpr double kPlate = 0.12;       ///< cribriform plate thickness
constexpr double kPoreMin = 0.02, kPoreMax = 0.075;  ///< pore radii
constexpr double kPoreBridge = 0.03;  ///< least bone between two pores, or a pore and the edge
constexpr double kPoreCover = 0.25;   ///< pore area / perforated plate area
constexpr double kTurbinate = 0.07;   ///< turbinate wall thickness
constexpr double kSeptum = 0.1;
constexpr double kBullaWall = 0.1;
constexpr double kTruthLeaf = 0.02;   ///< octree leaves of the truth integration
constexpr double kFmCut = 2.2;        ///< radius of the cut around the foramen magnum's axis
constexpr double kFmTilt = 45.0;      ///< the foramen magnum's plane from the horizontal, degrees
constexpr double kPlateTilt = 15.0;   ///< the cribriform plate from the vertical (top forward)

double bump(double t) { return std::clamp(1.0 - t * t, 0.0, 1.0); }

double smoothstep(double e0, double e1, double x) {
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

/// Distance estimate v / |grad v| of a primitive (ellipsoids: first order on both sides).
double prim_distance(const SkullBasePrim& p, const Vec3& q) {
    Vec3 g;
    const double v = p.eval(q, g);
    return v / std::max(norm(g), 1e-9);
}

/// A pore of the cribriform plate: a cylinder along the plate normal through the plate, centre
/// (a, b) in the plate's coordinates, radius r, and its blurred disk D(rho) tabulated.
struct Pore {
    double a = 0, b = 0, r = 0;
    double reach = 0;            ///< D = 0 beyond this distance from the axis
    std::vector<double> table;   ///< D at rho = i * reach / (size - 1)
    double blurred(double rho, double sigma) const {
        if (rho >= reach) return 0.0;
        if (sigma <= 0) return rho < r ? 1.0 : (rho > r ? 0.0 : 0.5);
        const double x = rho / reach * static_cast<double>(table.size() - 1);
        const size_t i = std::min(static_cast<size_t>(x), table.size() - 2);
        const double t = x - static_cast<double>(i);
        return table[i] + (table[i + 1] - table[i]) * t;
    }
};

/// The Gaussian (sigma) mass of a disk of radius r whose centre lies rho from the point:
/// int_0^pi phi(rho + r cos t) erf(r sin t / (sqrt 2 sigma)) r sin t dt (midpoint rule).
double disk_mass(double rho, double r, double sigma) {
    constexpr int kSteps = 160;
    const double inv = 1.0 / (std::sqrt(2.0) * sigma), norm_c = 1.0 / (sigma * std::sqrt(2.0 * kPi));
    double sum = 0;
    for (int i = 0; i < kSteps; ++i) {
        const double t = (i + 0.5) * kPi / kSteps;
        const double x = rho + r * std::cos(t), h = r * std::sin(t);
        sum += norm_c * std::exp(-0.5 * x * x / (sigma * sigma)) * std::erf(h * inv) * h;
    }
    return std::clamp(sum * kPi / kSteps, 0.0, 1.0);
}

/// A turbinate: a scroll (a cylindrical wall of radius R about an axis parallel to y through
/// (x, z), from y0 to y1, open over the half-angle `gap` about the direction `gap_dir` in the
/// x-z plane) or, with R = 0, a flat sheet: the rectangle from x to x1 at height z, y0 to y1.
struct Turbinate {
    double x = 0, z = 0, y0 = 0, y1 = 0, R = 0, gap = 0, gap_dir = 0, x1 = 0;
    /// Distance (mm) from q (with |q.x|: both sides) to the wall's mid-surface.
    double mid_distance(const Vec3& q) const {
        const double qx = std::fabs(q[0]);
        const double ay = std::max({y0 - q[1], q[1] - y1, 0.0});
        if (R <= 0) {
            const double ax = std::max({x - qx, qx - x1, 0.0});
            return std::sqrt(ax * ax + ay * ay + (q[2] - z) * (q[2] - z));
        }
        const double dx = qx - x, dz = q[2] - z, rho = std::hypot(dx, dz);
        // Angle from the gap's middle; within the gap the wall ends at its two edges.
        double phi = std::atan2(dz, dx) - gap_dir;
        while (phi > kPi) phi -= 2 * kPi;
        while (phi < -kPi) phi += 2 * kPi;
        double radial = rho - R, along = 0;
        if (std::fabs(phi) < gap) {  // the nearer edge of the opening
            const double e = std::copysign(gap, phi) + gap_dir;
            const double ex = x + R * std::cos(e), ez = z + R * std::sin(e);
            radial = 0;
            along = std::hypot(qx - ex, q[2] - ez);
        }
        return std::sqrt(radial * radial + along * along + ay * ay);
    }
};

struct Mouse {
    std::shared_ptr<SkullBaseModel> model;
    // foramen magnum (phantom frame): centre C on its plane, outward axis u, in-plane v (basion ->
    // opisthion) and x
    Vec3 fm_c, fm_u, fm_v;
    Vec3 basion, opisthion;
    double fm_half_width = 0;
    // cribriform plate: inner plane through P0 with outward normal n; in-plane e1 (= x), e2 (up)
    Vec3 plate_p0, plate_n, plate_e1{1, 0, 0}, plate_e2;
    std::vector<Pore> pores;
    double pore_lo[2] = {0, 0}, pore_cell = 0.1;  ///< pore lookup grid over (a, b)
    int pore_n[2] = {0, 0};
    std::vector<std::vector<int>> pore_cells;
    double pore_reach = 0;       ///< largest Pore::reach
    double plate_area = 0, pore_area = 0, pore_field_radius = 0;
    // bone
    std::vector<SkullBasePrim> solids;       ///< bone blocks (cut at the foramen magnum: fm_cut)
    SkullBasePrim bulla_inner[2];
    SkullBasePrim nasal;                     ///< the nasal cavity's ellipsoid
    std::vector<Turbinate> turbinates;
    std::vector<SkullBasePrim> soft;  ///< soft tissue beyond the scalp: eyes, orbits, jaws
    std::vector<Canal> canals;
    // spine (phantom frame): axis from fm_c along w; n_up in the midsagittal plane
    Vec3 spine_w, spine_up;
    double canal_r = 1.0, ring_wall = 0.3, atlas_start = 1.1, atlas_len = 1.0, vert_len = 1.6,
           vert_gap = 0.35, body_r = 0.55;
    Vec3 head_lo, head_hi;  ///< phantom-frame box of the head (and neck to 2 vertebrae) + margin

    /// Wall thickness of the braincase at q: vault 0.2 mm, 0.1 mm at the orbits, floor 0.3,
    /// basioccipital 0.4.
    double thickness(const Vec3& q) const {
        double t = 0.2;
        for (double s : {-1.0, 1.0}) t -= 0.1 * bump(norm(sub(q, {4.6 * s, 3.2, 0.0})) / 2.6);
        t += 0.1 * smoothstep(-1.6, -2.6, q[2]);
        t += 0.1 * bump(norm(sub(q, {0.0, -4.8, -2.7})) / 1.8);
        return t;
    }
    /// Signed distance-like value of the foramen magnum's cut (> 0 inside): the part beyond its
    /// plane within kFmCut of its axis, where no bone of the skull lies.
    double fm_cut(const Vec3& q) const {
        const Vec3 d = sub(q, fm_c);
        const double along = dot(d, fm_u);
        return std::min(along, kFmCut - norm(sub(d, mul(fm_u, along))));
    }
    /// Plate coordinates of q: (a, b) in the plate, c along the normal (0 = inner surface).
    Vec3 plate_coords(const Vec3& q) const {
        const Vec3 d = sub(q, plate_p0);
        return {dot(d, plate_e1), dot(d, plate_e2), dot(d, plate_n)};
    }
    /// Signed distance-like value of the nasal cavity's air (before turbinates and septum):
    /// the nasal ellipsoid in front of the plate's outer surface.
    double nasal_sd(const Vec3& q) const {
        return std::max(prim_distance(nasal, q), kPlate - plate_coords(q)[2]);
    }
    /// The summed blurred pore disks at plate coordinates (a, b).
    double pore_fraction(double a, double b, double sigma) const {
        const int i0 = std::max(0, static_cast<int>(std::floor((a - pore_reach - pore_lo[0]) / pore_cell)));
        const int i1 = std::min(pore_n[0] - 1, static_cast<int>(std::floor((a + pore_reach - pore_lo[0]) / pore_cell)));
        const int j0 = std::max(0, static_cast<int>(std::floor((b - pore_reach - pore_lo[1]) / pore_cell)));
        const int j1 = std::min(pore_n[1] - 1, static_cast<int>(std::floor((b + pore_reach - pore_lo[1]) / pore_cell)));
        double sum = 0;
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i)
                for (int k : pore_cells[static_cast<size_t>(j * pore_n[0] + i)]) {
                    const Pore& p = pores[static_cast<size_t>(k)];
                    sum += p.blurred(std::hypot(a - p.a, b - p.b), sigma);
                }
        return std::min(sum, 1.0);
    }
};

// ---- the cavity --------------------------------------------------------------------------------

void build_cavity(Mouse& mo) {
    using Op = SkullBaseModel::Op;
    auto& t = mo.model->terms;
    for (double s : {1.0, -1.0}) {  // cerebral hemispheres, 10.4 x 8.6 x 6.2 mm over the floor
        const SkullBasePrim h = ellipsoid({2.1 * s, 0.6, 0.2}, {3.1, 4.3, 3.25});
        t.push_back({s > 0 ? Op::First : Op::Union, h, 1.6});
    }
    t.push_back({Op::Subtract, half_space({0, 0, -2.75}, {0, 0, 1}), 0.8});  // flat floor
    t.push_back({Op::Union, ellipsoid({0, 0.6, -2.85}, {0.9, 0.7, 0.45}), 0.25});  // hypophyseal fossa
    // Mirrored pairs (a primitive and its mirror image smoothly united: exactly symmetric):
    // the olfactory bulbs on their peduncles, the paraflocculi.
    t.push_back({Op::Union, ellipsoid({0.72, 6.8, -0.35}, {0.85, 1.9, 1.25}), 0.6, true});
    t.push_back({Op::Union, capsule({0.65, 3.6, -0.6}, {0.72, 6.2, -0.4}, 0.85), 0.5, true});
    // The cribriform plate's inner surface: everything in front of it is cut off.
    t.push_back({Op::Subtract, half_space(mo.plate_p0, mul(mo.plate_n, -1.0)), 0.08});
    t.push_back({Op::Union, ellipsoid({0, -4.2, 0.3}, {3.55, 2.5, 2.5}), 1.4});  // cerebellum
    t.push_back({Op::Union, ellipsoid({3.45, -4.7, -0.5}, {0.55, 0.5, 0.5}), 0.25, true});  // paraflocculi
    t.push_back({Op::Union, capsule({0, -1.2, -1.6}, {0, -4.2, -1.9}, 1.25), 0.5});  // brainstem
    // The medulla through the foramen magnum: an ellipsoid 2.8 mm wide, 1.8 mm high (in the plane),
    // centred 0.15 mm inside the plane; the plane cuts it for the truth.
    SkullBasePrim med = ellipsoid(sub(mo.fm_c, mul(mo.fm_u, 0.15)), {1.4, 0.9, 1.0});
    med.axes = {{{1, 0, 0}, mo.fm_v, mo.fm_u}};
    t.push_back({Op::Union, med, 0.5});
    mo.model->box_lo = {-5.6, -8.3, -3.8};
    mo.model->box_hi = {5.6, 8.3, 3.8};
}

/// The midline point of {f = 0} in the foramen magnum's plane from its centre along dir.
Vec3 rim_point(const SkullBaseModel& m, const Vec3& c, const Vec3& dir) {
    return inner_table_point(m, c, dir, 0.02);
}

// ---- the cribriform plate's pores --------------------------------------------------------------

/// True when the disk of radius r at plate coordinates (a, b) lies on the flat inner surface of
/// the plate (the cavity is the plane there) with the nasal air right in front of it.
bool disk_on_plate(const Mouse& mo, double a, double b, double r) {
    Vec3 g;
    for (int k = 0; k <= 12; ++k) {
        const double ang = 2.0 * kPi * k / 12.0, rr = k == 12 ? 0.0 : r;
        const Vec3 p = add(mo.plate_p0, add(mul(mo.plate_e1, a + rr * std::cos(ang)),
                                            mul(mo.plate_e2, b + rr * std::sin(ang))));
        const Vec3 behind = sub(p, mul(mo.plate_n, 0.005));
        if (std::fabs(mo.model->eval(behind, g) + 0.005) > 1e-9) return false;
        if (mo.nasal_sd(add(p, mul(mo.plate_n, kPlate + 0.02))) > -0.02) return false;
    }
    return true;
}

/// Dart throwing (a fixed stream: the anatomy does not depend on the seed) until the pores cover
/// kPoreCover of the perforated plate: radii uniform in [kPoreMin, kPoreMax], kPoreBridge of bone
/// between pores and around them, none within 0.1 mm of the midline (crista galli, septum).
void build_pores(Mouse& mo, double sigma) {
    const double lo[2] = {-1.7, -1.4}, hi[2] = {1.7, 1.4};
    // The perforable area: the flat plate with air in front, off the midline.
    const double h = 0.02;
    int count = 0;
    for (double a = lo[0] + 0.5 * h; a < hi[0]; a += h)
        for (double b = lo[1] + 0.5 * h; b < hi[1]; b += h)
            if (std::fabs(a) > 0.1 && disk_on_plate(mo, a, b, 0.0)) ++count;
    mo.plate_area = count * h * h;
    uint64_t state = 0x5EEDC0DEULL;
    auto uniform = [&state]() {
        return static_cast<double>(splitmix64_mix(state += 0x9E3779B97F4A7C15ULL) >> 11) * 0x1.0p-53;
    };
    for (int attempt = 0; attempt < 60000 && mo.pore_area < kPoreCover * mo.plate_area; ++attempt) {
        Pore p;
        p.a = lo[0] + (hi[0] - lo[0]) * uniform();
        p.b = lo[1] + (hi[1] - lo[1]) * uniform();
        p.r = kPoreMin + (kPoreMax - kPoreMin) * uniform();
        if (std::fabs(p.a) < p.r + 0.1) continue;
        bool clear = true;
        for (const Pore& o : mo.pores)
            if (std::hypot(p.a - o.a, p.b - o.b) < p.r + o.r + kPoreBridge) {
                clear = false;
                break;
            }
        if (!clear || !disk_on_plate(mo, p.a, p.b, p.r + kPoreBridge)) continue;
        mo.pore_area += kPi * p.r * p.r;
        mo.pore_field_radius = std::max(mo.pore_field_radius, std::hypot(p.a, p.b) + p.r);
        mo.pores.push_back(p);
    }
    // Tables of the blurred disks, and the lookup grid.
    constexpr int kTable = 97;
    for (Pore& p : mo.pores) {
        p.reach = p.r + (sigma > 0 ? 6.0 * sigma : 1e-9);
        if (sigma > 0) {
            p.table.resize(kTable);
            for (int i = 0; i < kTable; ++i)
                p.table[static_cast<size_t>(i)] = disk_mass(p.reach * i / (kTable - 1), p.r, sigma);
            p.table.back() = 0.0;
        }
        mo.pore_reach = std::max(mo.pore_reach, p.reach);
    }
    for (int a = 0; a < 2; ++a) {
        mo.pore_lo[a] = lo[a];
        mo.pore_n[a] = static_cast<int>(std::ceil((hi[a] - lo[a]) / mo.pore_cell));
    }
    mo.pore_cells.assign(static_cast<size_t>(mo.pore_n[0] * mo.pore_n[1]), {});
    for (size_t k = 0; k < mo.pores.size(); ++k) {
        const int i = std::clamp(static_cast<int>((mo.pores[k].a - lo[0]) / mo.pore_cell), 0, mo.pore_n[0] - 1);
        const int j = std::clamp(static_cast<int>((mo.pores[k].b - lo[1]) / mo.pore_cell), 0, mo.pore_n[1] - 1);
        mo.pore_cells[static_cast<size_t>(j * mo.pore_n[0] + i)].push_back(static_cast<int>(k));
    }
}

// ---- canals (foramina) -------------------------------------------------------------------------

void build_canals(Mouse& mo) {
    struct Spec { const char* name; Vec3 p, u, hint; double a, b, len; };
    const Spec specs[] = {
        {"optic_canal", {1.2, 3.0, -1.8}, {0.5, 0.8, -0.35}, {0, 0, 1}, 0.125, 0.125, 1.5},
        {"foramen_ovale", {2.0, -1.2, -2.0}, {0.2, -0.1, -1}, {0, 1, 0}, 0.3, 0.2, 1.5},
        {"jugular_foramen", {1.3, -4.3, -1.6}, {0.15, -0.3, -1}, {1, 0, 0}, 0.18, 0.18, 1.6},
        {"hypoglossal_canal", {0.7, -4.9, -1.7}, {0.3, -0.6, -0.75}, {1, 0, 0}, 0.1, 0.1, 1.5},
    };
    const SkullBaseModel& m = *mo.model;
    for (const Spec& sp : specs)
        for (double s : {-1.0, 1.0}) {
            auto mir = [s](const Vec3& v) { return Vec3{v[0] * s, v[1], v[2]}; };
            Canal c;
            c.name = std::string(sp.name) + (s < 0 ? "_left" : "_right");
            c.u = normalized(mir(sp.u));
            const Vec3 hint = mir(sp.hint);
            c.v = normalized(sub(hint, mul(c.u, dot(hint, c.u))));
            c.w = cross(c.u, c.v);
            c.a = sp.a;
            c.b = sp.b;
            c.length = sp.len;
            c.inset = 0.2;
            c.start = inner_table_point(m, mir(sp.p), c.u, 0.02);
            Vec3 g;
            m.eval(c.start, g);
            const double cosine = std::fabs(dot(normalized(g), c.u));
            c.covering_radius = std::max(c.a, c.b) / std::max(cosine, 0.3);
            mo.canals.push_back(c);
        }
}

// ---- the whole anatomy -------------------------------------------------------------------------

Mouse build_mouse(double sigma) {
    Mouse mo;
    mo.model = std::make_shared<SkullBaseModel>();
    const double fm = kFmTilt * kPi / 180.0, pl = kPlateTilt * kPi / 180.0;
    mo.fm_c = {0, -6.0, -1.9};
    mo.fm_u = {0, -std::cos(fm), -std::sin(fm)};  // posterior-inferior
    mo.fm_v = {0, -std::sin(fm), std::cos(fm)};   // posterior-superior
    mo.plate_n = {0, std::cos(pl), -std::sin(pl)};
    mo.plate_e2 = {0, std::sin(pl), std::cos(pl)};
    mo.plate_p0 = {0, 7.7, -0.35};
    build_cavity(mo);
    SkullBaseModel& m = *mo.model;
    m.lipschitz = 1.5;  // |grad f| <= 1.02 (sampled by the tests)
    m.cropped = true;   // the truth: the braincase side of the foramen magnum's plane
    m.plane_n = mul(mo.fm_u, -1.0);
    m.plane_h = -dot(mo.fm_u, mo.fm_c);
    mo.basion = rim_point(m, mo.fm_c, mul(mo.fm_v, -1.0));
    mo.opisthion = rim_point(m, mo.fm_c, mo.fm_v);
    mo.fm_half_width = rim_point(m, mo.fm_c, {1, 0, 0})[0];

    // Bone blocks.
    mo.solids.push_back(ellipsoid({0, 1.2, -3.05}, {2.0, 3.2, 0.45}));    // basisphenoid
    mo.solids.push_back(ellipsoid({0, -4.0, -3.05}, {2.0, 2.0, 0.45}));   // basioccipital
    mo.solids.push_back(ellipsoid({0, 10.2, -0.6}, {2.2, 5.5, 2.1}));  // snout
    mo.solids.push_back(ellipsoid({0, 6.0, -0.5}, {2.1, 2.2, 1.6}));  // interorbital (frontal) bone
    for (double s : {-1.0, 1.0}) {  // zygomatic arches
        mo.solids.push_back(capsule({3.2 * s, 8.0, -1.3}, {5.6 * s, 4.0, -1.3}, 0.22));
        mo.solids.push_back(capsule({5.6 * s, 4.0, -1.3}, {5.2 * s, -1.2, -1.0}, 0.22));
        mo.solids.push_back(capsule({5.2 * s, -1.2, -1.0}, {4.5 * s, -1.7, -0.9}, 0.22));
    }
    for (double s : {-1.0, 1.0})  // the bullae's joints to the basioccipital
        mo.solids.push_back(capsule({1.5 * s, -4.0, -3.1}, {2.8 * s, -3.8, -3.3}, 0.3));
    for (int i = 0; i < 2; ++i) {  // tympanic bullae, 3 x 4 x 3 mm, long axes turned 20 deg
        const double s = i == 0 ? -1.0 : 1.0;
        mo.solids.push_back(ellipsoid({3.9 * s, -3.6, -3.4}, {1.5, 2.0, 1.5}, 20.0 * s));
        mo.bulla_inner[i] = ellipsoid({3.9 * s, -3.6, -3.4},
                                      {1.5 - kBullaWall, 2.0 - kBullaWall, 1.5 - kBullaWall}, 20.0 * s);
        mo.soft.push_back(ellipsoid({4.9 * s, 4.0, 0.6}, {1.9, 2.3, 1.8}));       // eye
        mo.soft.push_back(capsule({2.6 * s, 3.4, -2.0}, {4.6 * s, 4.2, 0.2}, 1.0));  // orbit's apex
    }
    mo.soft.push_back(ellipsoid({0, 3.5, -3.6}, {4.8, 9.0, 2.6}));  // jaws and their muscles
    mo.nasal = ellipsoid({0, 10.4, -0.5}, {1.7, 5.6, 1.6});
    // Turbinates (right side; mirrored): the nasoturbinate (a shelf from the lateral wall), the
    // maxilloturbinate (a scroll low in front, with its shelf to the lateral wall), three
    // ethmoturbinate scrolls behind, from 0.15 mm in front of the plate (at their top: the plate
    // leans forward).
    auto clear_of_plate = [&](double z_top) {
        return mo.plate_p0[1] + (z_top - mo.plate_p0[2]) * std::tan(pl) + kPlate / std::cos(pl) + 0.15;
    };
    mo.turbinates = {
        {0.55, 0.1, clear_of_plate(0.1), 14.0, 0, 0, 0, 1.6},           // nasoturbinate shelf
        {0.85, -1.3, 10.5, 14.5, 0.38, 0.6, 2.3, 0},                    // maxilloturbinate scroll
        {1.23, -1.3, 10.5, 14.5, 0, 0, 0, 1.6},                         // its shelf
        {0.75, 0.0, clear_of_plate(0.33), 10.5, 0.33, 0.5, kPi, 0},     // ethmoturbinates
        {0.8, -0.8, clear_of_plate(-0.47), 10.0, 0.33, 0.5, kPi, 0},
        {0.62, -1.55, clear_of_plate(-1.3), 9.5, 0.25, 0.6, 0.5 * kPi, 0},
    };
    build_canals(mo);
    build_pores(mo, sigma);

    // The spine: the canal leaves the foramen magnum 23 deg below the horizontal.
    mo.spine_w = normalized({0, -1.0, -0.42});
    mo.spine_up = {0, mo.spine_w[2], -mo.spine_w[1]};
    // The head's box: the eyes, the jaws and the scalp over the vault and the snout, and the
    // margin, reaching back over the atlas and 2 vertebrae.
    const double pad = kScalp + kMargin;
    const double spine_end = mo.atlas_start + mo.atlas_len + 2.0 * (mo.vert_gap + mo.vert_len) + mo.vert_gap;
    const Vec3 tail = add(mo.fm_c, mul(mo.spine_w, spine_end));
    mo.head_lo = {-6.8 - kMargin, tail[1], -6.2 - kMargin};
    mo.head_hi = {6.8 + kMargin, 15.7 + pad, 3.6 + pad};
    return mo;
}

// ---- rendering ---------------------------------------------------------------------------------

/// Cells (phantom frame, 0.25 mm) that say, by lower bounds over the cell's bounding ball, which
/// bone blocks come within `far` mm of it (1-Lipschitz bounds less the ball's radius), and
/// whether the cavity's wall and the blocks all lie beyond `far` (f's bound over its Lipschitz
/// bound, less the thickest wall): then only the outside is there.
struct FarMap {
    static constexpr uint32_t kFar = 1u << 31;  ///< flag bit; the others: solids that matter
    Vec3 lo{0, 0, 0};
    double cell = 0.25;
    int n[3] = {0, 0, 0};
    uint32_t all = 0;  ///< every solid
    std::vector<uint32_t> cells;
    void build(const Mouse& mo, double far) {
        if (mo.solids.size() >= 31) throw std::logic_error("mouse phantom: too many bone blocks for the far map");
        const SkullBaseModel& m = *mo.model;
        all = (1u << mo.solids.size()) - 1;
        lo = mo.head_lo;
        for (int a = 0; a < 3; ++a) n[a] = static_cast<int>(std::ceil((mo.head_hi[a] - lo[a]) / cell));
        cells.assign(static_cast<size_t>(n[0]) * n[1] * n[2], 0);
        const double radius = 0.5 * std::sqrt(3.0) * cell;
#pragma omp parallel for schedule(dynamic, 1)
        for (int k = 0; k < n[2]; ++k)
            for (int j = 0; j < n[1]; ++j)
                for (int i = 0; i < n[0]; ++i) {
                    const Vec3 c{lo[0] + (i + 0.5) * cell, lo[1] + (j + 0.5) * cell, lo[2] + (k + 0.5) * cell};
                    uint32_t bits = 0;
                    for (size_t b = 0; b < mo.solids.size(); ++b)
                        if (mo.solids[b].lower_bound(c) - radius < far) bits |= 1u << b;
                    if (bits == 0 && m.lower_bound(c, radius) / m.lipschitz - kMaxThickness >= far) bits = kFar;
                    cells[(static_cast<size_t>(k) * n[1] + j) * n[0] + i] = bits;
                }
    }
    /// The cell's bits at q; outside the map: every solid matters.
    uint32_t at(const Vec3& q) const {
        int idx[3];
        for (int a = 0; a < 3; ++a) {
            const double x = (q[a] - lo[a]) / cell;
            if (!(x >= 0) || x >= n[a]) return all;
            idx[a] = static_cast<int>(x);
        }
        return cells[(static_cast<size_t>(idx[2]) * n[1] + idx[1]) * n[0] + idx[0]];
    }
};

struct MouseRenderer : EdgeBlur {
    explicit MouseRenderer(const Mouse& m) : mo(m) {}
    const Mouse& mo;
    bool has_soft = true;
    FarMap far_map;

    static double mix(double a, double b, double t) { return a + (b - a) * t; }
    /// Blurred indicator of a sheet of thickness w at (unsigned or signed) distance m from its
    /// mid-surface: step(m - w/2) - step(m + w/2).
    double sheet(double m, double w) const { return step(m - 0.5 * w) - step(m + 0.5 * w); }

    /// Signed distance along the spine's axis to the nearest vertebra (negative inside one);
    /// `first` = 0: any, 1: the vertebrae after the atlas.
    double vertebra_dz(double s, int first) const {
        const double a0 = mo.atlas_start, a1 = a0 + mo.atlas_len;
        const double atlas = first == 0 ? std::max(a0 - s, s - a1) : kInf;
        const double z = s - (a1 + mo.vert_gap), period = mo.vert_len + mo.vert_gap;
        double rest = -z;  // before the first: the distance to it
        if (z >= 0) {
            const double r = std::fmod(z, period);
            rest = r <= mo.vert_len ? -std::min(r, mo.vert_len - r) : std::min(r - mo.vert_len, period - r);
        }
        return std::min(atlas, rest);
    }

    /// What lies outside the skull: air, soft tissue (scalp, eyes, orbits, jaws, neck), the
    /// cervical spine.
    double outside_value(const Vec3& q, double d_bone) const {
        const Vec3 d = sub(q, mo.fm_c);
        const double s = dot(d, mo.spine_w);
        const Vec3 e = sub(d, mul(mo.spine_w, s));
        const double rho = norm(e), up = dot(e, mo.spine_up);
        double v = kAir;
        if (has_soft) {
            const double neck = std::max((std::hypot(q[0] / 4.0, up / 3.0) - 1.0) * 3.0, -2.5 - s);
            double soft = std::min(d_bone - kScalp, neck);
            for (const SkullBasePrim& e2 : mo.soft)
                if (!e2.at_least(q, band)) soft = std::min(soft, prim_distance(e2, q));
            v = mix(v, kMouseContent, step(soft));
            if (q[1] > 13.0) v = mix(v, kAir, step(prim_distance(mo.nasal, q)));  // nostrils
        }
        if (s < mo.atlas_start - band || rho > mo.canal_r + mo.ring_wall + 2.0 * mo.body_r + band) {
            // Only the canal (or nothing of the spine) here.
            if (s > -0.3 - band) v = mix(v, kMouseContent, step(std::max(rho - mo.canal_r, -0.3 - s)));
            return v;
        }
        const double dz = vertebra_dz(s, 0);
        const double d_ring = std::max({rho - mo.canal_r - mo.ring_wall, mo.canal_r - rho, dz});
        const Vec3 body_c = mul(mo.spine_up, -(mo.canal_r + mo.ring_wall + mo.body_r - 0.15));
        const double d_body = std::max(norm(sub(e, body_c)) - mo.body_r, vertebra_dz(s, 1));
        v = mix(v, kVertebra, step(std::min(d_ring, d_body)));
        return mix(v, kMouseContent, step(std::max(rho - mo.canal_r, -0.3 - s)));
    }

    /// HU at the phantom-frame point q (before noise).
    double hu(const Vec3& q) const {
        // Far from the cavity and the bone (by lower bounds): only the outside, which does not
        // depend on the bone's distance beyond the scalp and its blur (the same value).
        // Bone blocks beyond `far` of q's cell leave the result as it is: skipped.
        const double far = kScalp + band;
        const uint32_t cell = far_map.at(q);
        if (cell == FarMap::kFar) return outside_value(q, far);
        auto near_solids = [&](auto&& visit) {
            for (uint32_t bits = cell; bits; bits &= bits - 1) visit(mo.solids[static_cast<size_t>(__builtin_ctz(bits))]);
        };
        Vec3 g;
        const double d_c = cavity_distance(mo.model->eval(q, g), g);
        if (sigma > 0 ? d_c <= -band : d_c < 0) return kMouseContent;
        const double dp = mo.fm_cut(q);
        double d_bone = std::max(d_c - mo.thickness(q), dp);
        near_solids([&](const SkullBasePrim& b) {
            if (!b.at_least(q, d_bone)) d_bone = std::min(d_bone, std::max(b.eval(q, g), dp));
        });
        if (d_bone >= band && d_c >= band) return outside_value(q, d_bone);

        // Soft regions: the outside, canals and nasal air blend as one union; the bullae's air
        // (inside bone, apart from them) adds to it.
        SoftBlend soft{*this};
        soft.add(-d_bone, outside_value(q, d_bone));
        for (const Canal& c : mo.canals) {
            if (norm(sub(q, c.start)) > c.length + 2.0 * std::max(c.a, c.b) + band + 0.3) continue;
            soft.add(std::max(c.sd(q), -d_c), kMouseContent);
        }
        const bool in_snout = q[1] > mo.plate_p0[1] - 1.5 && std::fabs(q[0]) < 2.5;
        const double w_nasal = in_snout ? soft.add(mo.nasal_sd(q), kAir) : 0.0;
        double s_bulla = 0;
        for (const SkullBasePrim& b : mo.bulla_inner) s_bulla += step(prim_distance(b, q));
        const double s_c = step(d_c);
        const double s_a = soft.fraction();
        const double total = s_a + s_bulla;
        const double scale = total > 1.0 - s_c ? (1.0 - s_c) / total : 1.0;
        const double s_soft = total * scale;
        double v = kMouseContent * s_c + (soft.value() * s_a + kAir * s_bulla) * scale +
                   kMouseBone * (1.0 - s_c - s_soft);

        if (w_nasal > 0) {
            // Turbinates and septum in the nasal air: (bone - air) times their blurred sheets,
            // at most the air's share here.
            double sheets = sheet(std::fabs(q[0]), kSeptum);
            for (const Turbinate& t : mo.turbinates) {
                const double md = t.mid_distance(q);
                if (md < 0.5 * kTurbinate + band) sheets += sheet(md, kTurbinate);
            }
            const double air_share = s_a * scale * w_nasal / soft.wsum;
            v += (kMouseBone - kAir) * std::min(sheets, air_share);
        }
        if (!mo.pores.empty()) {
            // Pores of the cribriform plate: (content - bone) times the plate's blurred slab
            // times the blurred pore disks (exact by linearity: the pores lie in its bone).
            const Vec3 pc = mo.plate_coords(q);
            if (pc[2] > -band && pc[2] < kPlate + band && std::hypot(pc[0], pc[1]) < mo.pore_field_radius + mo.pore_reach) {
                const double slab = sheet(pc[2] - 0.5 * kPlate, kPlate);
                if (slab > 0) v += (kMouseContent - kMouseBone) * slab * mo.pore_fraction(pc[0], pc[1], sigma);
            }
        }
        return v;
    }
};

}  // namespace

namespace phantom_detail {

PhantomResult generate_rodent_phantom(const PhantomParams& p, int64_t slab_voxels, const PhantomSlabSink& sink) {
    const Vec3 spacing = validated_spacing(p, kDefaultSpacing, "mouse");
    if (p.crop_base_mm > 0)
        throw InvalidParameter("the mouse phantom cannot be cropped at the base (its cavity ends at the "
                               "foramen magnum's plane)");
    const double sigma = p.blur ? kBlurVoxels * std::cbrt(spacing[0] * spacing[1] * spacing[2]) : 0.0;
    const Mouse mo = build_mouse(sigma);
    SkullBaseModel& m = *mo.model;
    const double tilt = p.tilt_deg * kPi / 180.0;
    m.cs = std::cos(tilt);
    m.sn = std::sin(tilt);
    PhantomResult res;
    res.true_ecv_ml = truth_volume(m, kTruthLeaf, res.true_ecv_error_ml);
    res.true_ecv_slice_centres_ml = res.true_ecv_ml;
    res.crop_plane_z_mm = -kInf;
    Vec3 centre;
    const Geometry geom = layout_grid(p, m, mo.head_lo, mo.head_hi, spacing, -kInf, bool(sink), centre);
    m.centre = centre;
    MouseRenderer rd(mo);
    rd.has_soft = p.scalp;
    rd.set_sigma(sigma);
    rd.far_map.build(mo, kScalp + rd.band);
    render_phantom_ct(geom, slab_voxels, sink, res, [&](int64_t k0, int64_t k1, int16_t* dst) {
        render_implicit(rd, m, p.noise, p.seed, geom, k0, k1, dst);
    });

    res.suggested_iso = 0.5 * (kMouseContent + kMouseBone);
    res.cavity_centre_world = centre;
    res.cavity_semi_axes_mm = mul(sub(m.box_hi, m.box_lo), 0.5);
    res.cavity_rotation = {1, 0, 0, 0, m.cs, -m.sn, 0, m.sn, m.cs};
    const Vec3 fm_mid = mul(add(mo.basion, mo.opisthion), 0.5);
    const double fm_radius = std::max(mo.fm_half_width, 0.5 * norm(sub(mo.opisthion, mo.basion)));
    res.openings.push_back({"foramen_magnum", m.to_world(fm_mid), m.dir_to_world(mo.fm_u), fm_radius});
    for (const Canal& c : mo.canals)
        res.openings.push_back({c.name, m.to_world(c.start), m.dir_to_world(c.u), c.covering_radius});
    res.openings.push_back({"cribriform_plate", m.to_world(mo.plate_p0), m.dir_to_world(mo.plate_n),
                            mo.pore_field_radius});
    res.foramen_magnum_world = m.to_world(fm_mid);
    res.foramen_magnum_axis = m.dir_to_world(mo.fm_u);
    res.foramen_magnum_radius_mm = fm_radius;
    res.spinal_canal_radius_mm = mo.canal_r;
    res.optic_canal_radius_mm = mo.canals.front().a;
    res.shell_thickness_mm = 0.2;
    res.sigma_mm = sigma;
    PhantomLandmarks lm;
    lm.basion = m.to_world(mo.basion);
    lm.opisthion = m.to_world(mo.opisthion);
    lm.foramen_magnum_plane_point = m.to_world(fm_mid);
    lm.foramen_magnum_plane_normal = m.dir_to_world(mo.fm_u);
    lm.cribriform_plate_centre = m.to_world(mo.plate_p0);
    lm.symmetry_plane_point = centre;
    lm.symmetry_plane_normal = m.dir_to_world({1, 0, 0});
    res.landmarks = lm;
    std::ostringstream d;
    d << "mouse phantom " << geom.dims[0] << "x" << geom.dims[1] << "x" << geom.dims[2] << " voxels at "
      << fmt(spacing[0]) << "x" << fmt(spacing[1]) << "x" << fmt(spacing[2]) << " mm, tilt "
      << fmt(p.tilt_deg) << " deg, ECV " << fmt(res.true_ecv_ml) << " +- " << fmt(res.true_ecv_error_ml)
      << " mL, iso " << fmt(res.suggested_iso) << " HU, seed " << p.seed << "; features:"
      << (p.noise ? " noise" : "") << (p.blur ? " blur" : "") << " openings(" << res.openings.size()
      << ") cribriform-pores(" << mo.pores.size() << ", " << fmt(std::round(100.0 * mo.pore_area / mo.plate_area))
      << " % of " << fmt(std::round(100.0 * mo.plate_area) / 100.0) << " mm^2) turbinates bullae spine"
      << (rd.has_soft ? " scalp+neck" : "");
    res.description = d.str();
    res.skull_base = mo.model;
    return res;
}

}  // namespace phantom_detail
}  // namespace endocast
