// Tests of the mouse phantom (PhantomPreset::Mouse): its truth (size and stated error, the volume
// against an independent stratified Monte Carlo, symmetry, the signed distance's sign against f
// and its magnitude against brute force, the landmarks on the inner table and the foramen
// magnum's plane, the cribriform plate closing the olfactory chamber), its CT (the plate a sieve
// at 0.14 mm, its pores resolved at 0.035 mm, the contents), tilt, the grid window, refusals,
// determinism and the preset's names.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "test_helpers.h"
#include "phantom/phantom_internal.h"  // SkullBaseModel: f and its Lipschitz bound
#include "phantom_test_helpers.h"

using namespace endocast;
using endocast::testing::along;
using endocast::testing::to_world;
using endocast::testing::trilinear;

namespace {

PhantomParams mouse(double spacing = 0.14) {
    PhantomParams p;
    p.preset = PhantomPreset::Mouse;
    p.spacing = {spacing, spacing, spacing};
    return p;
}

/// The mouse at 0.14 mm without noise, generated once for the tests that only read it.
const PhantomResult& coarse() {
    static const PhantomResult r = [] {
        PhantomParams p = mouse(0.14);
        p.noise = false;
        return generate_phantom(p);
    }();
    return r;
}

/// The truth only (a tiny grid: the truth does not depend on it).
const PhantomResult& truth() {
    static const PhantomResult r = [] {
        PhantomParams p = mouse(0.14);
        p.size = {8, 8, 8};
        return generate_phantom(p);
    }();
    return r;
}

Vec3 diff(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dotp(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double len(const Vec3& a) { return std::sqrt(dotp(a, a)); }
Vec3 crossp(const Vec3& a, const Vec3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

double sdf(const PhantomResult& r, const Vec3& w) { return phantom_cavity_signed_distance(r, w); }

/// f of the truth, cut by the foramen magnum's plane (its sign is the truth's).
double cut_f(const PhantomResult& r, const Vec3& w) {
    const SkullBaseModel& m = *r.skull_base;
    const Vec3 q = m.to_phantom(w);
    Vec3 g;
    return std::max(m.eval(q, g), m.plane_h - dotp(m.plane_n, q));
}

/// The cavity's extent (mm) along the phantom-frame line through o along d: the outermost sign
/// changes of the truth found by marching 0.02 mm, refined by bisection.
double extent(const PhantomResult& r, const Vec3& o, const Vec3& d) {
    auto inside = [&](double t) { return cut_f(r, to_world(r, along(o, d, t))) < 0; };
    double first = 1e9, last = -1e9;
    for (double t = -12; t < 12; t += 0.02)
        if (inside(t) != inside(t + 0.02)) {
            double lo = t, hi = t + 0.02;
            const bool a = inside(lo);
            for (int i = 0; i < 40; ++i) {
                const double m = 0.5 * (lo + hi);
                (inside(m) == a ? lo : hi) = m;
            }
            first = std::min(first, lo);
            last = std::max(last, lo);
        }
    return last - first;
}

/// True where the truth's surface is the cribriform plate's flat inner face (its perforable part),
/// at the plate point x with the plate's normal n.
bool flat_plate(const PhantomResult& r, const Vec3& x, const Vec3& n) {
    return std::fabs(cut_f(r, along(x, n, -0.02)) + 0.02) < 1e-9 && cut_f(r, along(x, n, 0.06)) > 0;
}

/// In-plane unit vectors of the cribriform plate (world): e1 = left->right, e2 = its up.
void plate_frame(const PhantomResult& r, Vec3& n, Vec3& e1, Vec3& e2) {
    n = r.openings.back().axis_world;
    e1 = {1, 0, 0};
    e2 = crossp(n, e1);
    if (e2[2] < 0) e2 = {-e2[0], -e2[1], -e2[2]};
}

}  // namespace

TEST(PhantomMouse, TruthSizeAndStatedError) {
    const PhantomResult& r = truth();
    EXPECT_GT(r.true_ecv_ml, 0.42);
    EXPECT_LT(r.true_ecv_ml, 0.52);
    EXPECT_GT(r.true_ecv_error_ml, 0.0);
    EXPECT_LT(r.true_ecv_error_ml, 0.001 * r.true_ecv_ml);  // < 0.1 %
    EXPECT_NEAR(r.suggested_iso, 770.0, 1e-9);
    ASSERT_TRUE(r.skull_base != nullptr);
    ASSERT_TRUE(r.landmarks.has_value());
    EXPECT_EQ(r.openings.front().name, "foramen_magnum");
    EXPECT_EQ(r.openings.back().name, "cribriform_plate");
    // Whole length through a bulb, cerebral width and height, the bulbs' chamber.
    EXPECT_NEAR(extent(r, {0.72, 0, -0.35}, {0, 1, 0}), 14.5, 0.6);
    EXPECT_NEAR(extent(r, {0, 0.6, 0.2}, {1, 0, 0}), 10.2, 0.5);
    EXPECT_NEAR(extent(r, {2.1, 0.6, 0}, {0, 0, 1}), 6.3, 0.4);
    EXPECT_NEAR(extent(r, {0, -4.5, 0.3}, {1, 0, 0}), 7.1, 0.4);  // cerebellum
    EXPECT_NEAR(extent(r, {0, 6.8, -0.35}, {1, 0, 0}), 3.1, 0.3);  // bulbs
    EXPECT_NEAR(extent(r, {0.72, 6.8, 0}, {0, 0, 1}), 2.5, 0.2);
}

TEST(PhantomMouse, TruthVolumeMatchesStratifiedMonteCarlo) {
    // One uniform point in each 0.12 mm cube of the cavity's box (0.3 mm margin), classified by
    // f and the foramen magnum's plane: ~22k boundary cells of 1.7e-3 mm^3, standard error
    // ~1.3e-4 mL; 4 sigma plus the stated bound.
    const PhantomResult& r = truth();
    const Vec3 half = r.cavity_semi_axes_mm;
    const Vec3 hi{half[0] + 0.3, half[1] + 0.3, half[2] + 0.3};
    const double mc = endocast::testing::stratified_volume_ml(
        {-hi[0], -hi[1], -hi[2]}, hi, 0.12, 17, [&](const Vec3& q) { return cut_f(r, to_world(r, q)) < 0; });
    EXPECT_NEAR(mc, r.true_ecv_ml, 5.2e-4 + r.true_ecv_error_ml) << "MC " << mc;
}

TEST(PhantomMouse, TruthIsSymmetric) {
    const PhantomResult& r = truth();
    const PhantomLandmarks& l = *r.landmarks;
    const Vec3 n = l.symmetry_plane_normal, c = l.symmetry_plane_point;
    EXPECT_NEAR(len(n), 1.0, 1e-12);
    for (const Vec3& p : {l.basion, l.opisthion, l.cribriform_plate_centre, l.foramen_magnum_plane_point})
        EXPECT_NEAR(dotp(diff(p, c), n), 0.0, 1e-9);
    std::mt19937_64 rng(4);
    std::uniform_real_distribution<double> ux(0.0, 6.0), uy(-8.5, 8.5), uz(-4.0, 4.0);
    int near = 0;
    for (int i = 0; i < 400; ++i) {
        const Vec3 w = to_world(r, {ux(rng), uy(rng), uz(rng)});
        const Vec3 m = along(w, n, -2.0 * dotp(diff(w, c), n));  // the mirror image
        EXPECT_NEAR(cut_f(r, w), cut_f(r, m), 1e-9);
        if (std::fabs(cut_f(r, w)) < 0.5 && ++near <= 60) EXPECT_NEAR(sdf(r, w), sdf(r, m), 1e-5);
    }
    EXPECT_GT(near, 20);
    // The openings come in mirrored pairs (after the foramen magnum, before the plate).
    for (size_t i = 1; i + 2 < r.openings.size(); i += 2) {
        const Vec3 a = r.openings[i].centre_world, b = r.openings[i + 1].centre_world;
        EXPECT_NEAR(dotp(diff(a, c), n), -dotp(diff(b, c), n), 1e-9) << r.openings[i].name;
    }
}

TEST(PhantomMouse, SignedDistanceSignAgreesWithF) {
    const PhantomResult& r = truth();
    const SkullBaseModel& m = *r.skull_base;
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> ux(-6.0, 6.0), uy(-9.0, 9.0), uz(-4.5, 4.5);
    double gmax = 0;
    int inside = 0;
    for (int i = 0; i < 3000; ++i) {
        const Vec3 q{ux(rng), uy(rng), uz(rng)};
        const Vec3 w = to_world(r, q);
        Vec3 g;
        m.eval(q, g);
        gmax = std::max(gmax, len(g));
        const double f = cut_f(r, w);
        if (std::fabs(f) < 1e-9) continue;
        const double s = sdf(r, w);
        EXPECT_EQ(s < 0, f < 0) << q[0] << " " << q[1] << " " << q[2];
        inside += f < 0;
    }
    EXPECT_GT(inside, 300);
    EXPECT_LE(gmax, m.lipschitz);  // the octree's and the renderer's bound
}

TEST(PhantomMouse, SignedDistanceMatchesBruteForce) {
    // Surface points by bisection of the sign along the edges of a 0.0125 mm grid around the
    // query (within 0.3 mm of the surface): the nearest of them is within ~0.001 mm of the distance.
    const PhantomResult& r = truth();
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<double> ux(-5.5, 5.5), uy(-8.0, 8.0), uz(-3.6, 3.6), u(-1.0, 1.0);
    int checked = 0;
    for (int i = 0; i < 2000 && checked < 10; ++i) {
        const Vec3 q = to_world(r, {ux(rng), uy(rng), uz(rng)});
        const double got = sdf(r, q);
        if (std::fabs(got) > 0.3 || std::fabs(got) < 0.02) continue;
        ++checked;
        const double best = endocast::testing::brute_force_distance(
            q, std::fabs(got) + 0.05, 0.0125, [&](const Vec3& w) { return cut_f(r, w) < 0; });
        EXPECT_LE(std::fabs(got), best + 1e-6) << i;
        EXPECT_GE(std::fabs(got), best - 0.003) << i;
    }
    EXPECT_EQ(checked, 10);
}

TEST(PhantomMouse, ForamenMagnumLandmarksAndPlane) {
    const PhantomResult& r = truth();
    const PhantomLandmarks& l = *r.landmarks;
    const Vec3 n = l.foramen_magnum_plane_normal, p = l.foramen_magnum_plane_point;
    EXPECT_NEAR(len(n), 1.0, 1e-12);
    EXPECT_NEAR(dotp(n, l.symmetry_plane_normal), 0.0, 1e-12);
    // Basion and opisthion: on the inner table and in the plane, the opisthion higher and more
    // posterior; the plane 40-50 degrees from the horizontal, facing posterior-inferior.
    for (const Vec3& x : {l.basion, l.opisthion}) {
        EXPECT_NEAR(sdf(r, x), 0.0, 1e-6);
        EXPECT_NEAR(dotp(diff(x, p), n), 0.0, 1e-9);
    }
    EXPECT_GT(l.opisthion[2], l.basion[2] + 0.5);
    EXPECT_LT(l.opisthion[1], l.basion[1] - 0.5);
    const double tilt = std::acos(std::fabs(n[2])) * 180.0 / 3.14159265358979323846;
    EXPECT_GE(tilt, 40.0);
    EXPECT_LE(tilt, 50.0);
    EXPECT_LT(n[1], 0.0);
    EXPECT_LT(n[2], 0.0);
    const double height = len(diff(l.opisthion, l.basion));
    EXPECT_GT(height, 1.8);
    EXPECT_LT(height, 2.4);
    // Width: the cavity just inside the plane, along left-right.
    const Vec3 in = along(p, n, -0.01);
    double lo = 0, hi = 3;
    for (int i = 0; i < 40; ++i) {
        const double m = 0.5 * (lo + hi);
        (sdf(r, along(in, l.symmetry_plane_normal, m)) < 0 ? lo : hi) = m;
    }
    EXPECT_GT(2 * lo, 2.5);
    EXPECT_LT(2 * lo, 3.0);
    // Closed by the plane: just beyond it is not cavity, just inside it is.
    EXPECT_GT(sdf(r, along(p, n, 0.03)), 0.0);
    EXPECT_LT(sdf(r, along(p, n, -0.03)), 0.0);
    EXPECT_NEAR(sdf(r, along(p, n, 0.03)), 0.03, 1e-6);
    EXPECT_EQ(r.openings.front().centre_world, p);
}

TEST(PhantomMouse, CribriformPlateClosesTheOlfactoryChamber) {
    const PhantomResult& r = truth();
    const Vec3 c = r.landmarks->cribriform_plate_centre;
    Vec3 n, e1, e2;
    plate_frame(r, n, e1, e2);
    EXPECT_NEAR(sdf(r, c), 0.0, 1e-6);
    EXPECT_EQ(r.openings.back().centre_world, c);
    // Over the plate: just behind it the bulbs (cavity), just in front of it and in the nasal
    // cavity beyond it not; the distance in front is the distance to the plate's inner surface.
    for (double a : {-0.7, -0.4, 0.4, 0.7})
        for (double b : {-0.4, 0.0, 0.3}) {
            const Vec3 x = along(along(c, e1, a), e2, b);
            EXPECT_LT(sdf(r, along(x, n, -0.03)), 0.0) << a << " " << b;
            EXPECT_NEAR(sdf(r, along(x, n, 0.05)), 0.05, 1e-6) << a << " " << b;
            EXPECT_GT(sdf(r, along(x, n, 0.5)), 0.0) << a << " " << b;
        }
}

TEST(PhantomMouse, CribriformPlateIsASieveAtCoarseVoxels) {
    // At 0.14 mm (blur sigma 0.084 mm) the 0.12 mm plate with ~25 % pores peaks below the
    // isovalue almost everywhere over its flat part (off the midline crest, where the septum
    // meets it), though there is bone (above the content) all over it.
    const PhantomResult& r = coarse();
    const Vec3 c = r.landmarks->cribriform_plate_centre;
    Vec3 n, e1, e2;
    plate_frame(r, n, e1, e2);
    int used = 0, below = 0, boned = 0;
    for (double a = -1.2; a <= 1.2; a += 0.05)
        for (double b = -1.0; b <= 1.0; b += 0.05) {
            const Vec3 x = along(along(c, e1, a), e2, b);
            if (!flat_plate(r, x, n) || std::fabs(a) < 0.25) continue;
            double peak = -1e9;  // through the plate, short of the turbinates in front
            for (double t = -0.1; t <= 0.22; t += 0.01) peak = std::max(peak, trilinear(r, along(x, n, t)));
            ++used;
            below += peak < r.suggested_iso;
            boned += peak > 200;
        }
    EXPECT_GT(used, 300);
    EXPECT_GE(below, used * 90 / 100) << below << " of " << used;
    EXPECT_GE(boned, used * 90 / 100) << boned << " of " << used;
}

TEST(PhantomMouse, CribriformPoresResolvedAtFineVoxels) {
    // A 0.035 mm window around the plate: along lines in its mid-surface the CT alternates
    // between bone above the isovalue and pores below it.
    PhantomParams p = mouse(0.035);
    p.noise = false;
    const PhantomResult& t = truth();
    const Vec3 cq = t.skull_base->to_phantom(t.landmarks->cribriform_plate_centre);
    p.grid_centre_mm = cq;
    p.size = {100, 40, 90};
    const PhantomResult r = generate_phantom(p);
    EXPECT_EQ(r.true_ecv_ml, t.true_ecv_ml);
    const Vec3 c = r.landmarks->cribriform_plate_centre;
    Vec3 n, e1, e2;
    plate_frame(r, n, e1, e2);
    int pores = 0, samples = 0, low = 0;
    for (double b = -0.8; b <= 0.6; b += 0.1) {
        int state = 0;  // 0: not yet on bone, 1: bone, 2: in a pore after bone
        for (double a = -1.5; a <= 1.5; a += 0.0175) {
            const Vec3 x = along(along(c, e1, a), e2, b);
            if (!flat_plate(r, x, n) || std::fabs(a) < 0.12) {
                state = 0;
                continue;
            }
            const double v = trilinear(r, along(x, n, 0.06));
            ++samples;
            low += v < r.suggested_iso;
            if (v > r.suggested_iso + 300) {
                if (state == 2) ++pores;  // a pore closed by bone on both sides
                state = 1;
            } else if (v < r.suggested_iso - 300 && state == 1) {
                state = 2;
            }
        }
    }
    EXPECT_GE(pores, 15);
    EXPECT_GT(samples, 500);
    EXPECT_GT(low, samples / 10);      // the pores: ~25 % of the plate
    EXPECT_LT(low, samples * 45 / 100);
}

TEST(PhantomMouse, ContentsOfTheCt) {
    const PhantomResult& r = coarse();
    const PhantomLandmarks& l = *r.landmarks;
    EXPECT_NEAR(trilinear(r, r.cavity_centre_world), 40.0, 1.0);  // brain
    EXPECT_NEAR(trilinear(r, to_world(r, {3.9, -3.6, -3.4})), -1000.0, 1.0);  // bulla air
    EXPECT_NEAR(trilinear(r, to_world(r, {-3.9, -3.6, -3.4})), -1000.0, 1.0);
    double vault = -1e9;
    for (double z = 3.2; z <= 3.9; z += 0.02) vault = std::max(vault, trilinear(r, to_world(r, {2.1, 0.6, z})));
    EXPECT_GT(vault, 1000.0);
    // The nasal cavity: air between the turbinates, 1 mm in front of the plate's centre.
    Vec3 n, e1, e2;
    plate_frame(r, n, e1, e2);
    int air = 0;
    for (double a : {-1.0, -0.6, -0.3, 0.3, 0.6, 1.0})
        air += trilinear(r, along(along(l.cribriform_plate_centre, n, 1.5), e1, a)) < -300;
    EXPECT_GE(air, 3);
    // The spinal canal: content from the foramen magnum to the grid's border, in bone rings.
    const Vec3 fm = l.foramen_magnum_plane_point;
    const Vec3 w = diff(to_world(r, {0, -1.0, -0.42}), r.cavity_centre_world);
    const Vec3 wu = {w[0] / len(w), w[1] / len(w), w[2] / len(w)};
    for (double t = 0.5; t < 5.5; t += 0.25) EXPECT_NEAR(trilinear(r, along(fm, wu, t)), 40.0, 60.0) << t;
    double ring = -1e9;
    for (double t = 1.0; t < 5.5; t += 0.05) ring = std::max(ring, trilinear(r, along(along(fm, wu, t), {1, 0, 0}, 1.15)));
    EXPECT_GT(ring, 1000.0);
    EXPECT_NEAR(r.spinal_canal_radius_mm, 1.0, 1e-12);
}

TEST(PhantomMouse, TiltKeepsTheTruthAndTurnsTheLandmarks) {
    PhantomParams p = mouse(0.14);
    p.size = {8, 8, 8};
    p.tilt_deg = 25;
    const PhantomResult b = generate_phantom(p);
    const PhantomResult& a = truth();
    EXPECT_EQ(a.true_ecv_ml, b.true_ecv_ml);
    EXPECT_EQ(a.true_ecv_error_ml, b.true_ecv_error_ml);
    for (const Vec3& q : {Vec3{0, 0, 3.4}, Vec3{2.5, -4.6, -1}, Vec3{0.7, 7.7, -0.3}, Vec3{0, -6.5, -1.5}})
        EXPECT_NEAR(sdf(a, to_world(a, q)), sdf(b, to_world(b, q)), 1e-6);
    const Vec3 qa = a.skull_base->to_phantom(a.landmarks->basion), qb = b.skull_base->to_phantom(b.landmarks->basion);
    EXPECT_NEAR(len(diff(qa, qb)), 0.0, 1e-9);
    const double t = 25 * 3.14159265358979323846 / 180;
    const Vec3 na = a.landmarks->foramen_magnum_plane_normal, nb = b.landmarks->foramen_magnum_plane_normal;
    EXPECT_NEAR(nb[1], std::cos(t) * na[1] - std::sin(t) * na[2], 1e-12);
    EXPECT_NEAR(nb[2], std::sin(t) * na[1] + std::cos(t) * na[2], 1e-12);
}

TEST(PhantomMouse, GridCentreWindowAndRefusals) {
    PhantomParams p = mouse(0.05);
    p.noise = false;
    p.size = {21, 21, 21};
    p.grid_centre_mm = {0, -4.2, 0.3};  // the cerebellum's centre
    const PhantomResult r = generate_phantom(p);
    EXPECT_NEAR(len(diff(r.ct.geometry().index_to_world(10, 10, 10), to_world(r, p.grid_centre_mm))), 0.0, 1e-9);
    EXPECT_EQ(r.ct(10, 10, 10), 40);
    PhantomParams bad = mouse();
    bad.size = {8, 8, 8};
    bad.crop_base_mm = 1.0;
    EXPECT_THROW(generate_phantom(bad), InvalidParameter);
    for (int i = 0; i < 3; ++i) {
        PhantomParams q = mouse();
        q.size = {8, 8, 8};
        (i == 0 ? q.orbits : i == 1 ? q.frontal_sinus : q.body) = true;
        EXPECT_THROW(generate_phantom(q), InvalidParameter);
    }
    PhantomParams ellipsoid;  // the ellipsoid phantoms take no window
    ellipsoid.size = {8, 8, 8};
    ellipsoid.grid_centre_mm = {1, 0, 0};
    EXPECT_THROW(generate_phantom(ellipsoid), InvalidParameter);
}

TEST(PhantomMouse, DeterministicForThreadCounts) {
    PhantomParams p = mouse(0.2);
    p.seed = 5;
    endocast::testing::expect_same_for_thread_counts(p);
}

TEST(PhantomMouse, PresetNames) {
    EXPECT_EQ(parse_phantom_preset("mouse"), PhantomPreset::Mouse);
    EXPECT_EQ(parse_phantom_preset("rodent"), parse_phantom_preset("mouse"));
    EXPECT_EQ(parse_phantom_preset("Rodent"), PhantomPreset::Mouse);
    EXPECT_EQ(to_string(PhantomPreset::Mouse), "mouse");
    EXPECT_EQ(parse_phantom_preset(to_string(PhantomPreset::Mouse)), PhantomPreset::Mouse);
    try {
        parse_phantom_preset("rat");
        FAIL() << "expected InvalidParameter";
    } catch (const InvalidParameter& e) {
        EXPECT_NE(std::string(e.what()).find("mouse"), std::string::npos);
    }
    EXPECT_EQ(truth().description.rfind("mouse phantom", 0), 0u);
}

TEST(PhantomMouse, ExtractionStaysInTheBraincase) {
    // The method on the mouse phantom at 0.14 mm (the shared scans' voxel): no leak into the nasal
    // cavity or down the spinal canal (no vertex more than two voxels outside the true cavity away
    // from its openings), the olfactory bulbs' chamber kept (it holds 4 % of the volume), a clean
    // genus-0 surface, no warning.
    PhantomParams pp;
    pp.preset = PhantomPreset::Mouse;
    pp.spacing = {0.14, 0.14, 0.14};
    const PhantomResult ph = generate_phantom(pp);
    ExtractParams p;
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    endocast::testing::expect_clean_genus0(r.mesh);
    double outside = 0;
    for (const auto& v : r.mesh.vertices) {
        const Vec3 w{v[0], v[1], v[2]};
        if (phantom_near_opening(ph, w, 0.3)) continue;
        outside = std::max(outside, phantom_cavity_signed_distance(ph, w));
    }
    const double err = r.ecv_ml / ph.true_ecv_ml - 1;
    std::printf("mouse phantom 0.14 mm: ECV %+.2f %%, farthest vertex outside %.3f mm, contact %.3f, leak %.3f\n",
                100 * err, outside, r.bone_contact, r.leak_share);
    EXPECT_LT(outside, 2 * 0.14);
    EXPECT_GT(err, -0.05);
    EXPECT_LT(err, 0.02);
    // The bulbs' chamber: 0.5 mm behind the plate's centre (toward the cavity's centre) is
    // endocast, 0.3 mm in front of it (the nasal cavity) is not.
    const Vec3 plate = ph.landmarks->cribriform_plate_centre, centre = ph.cavity_centre_world;
    Vec3 in{centre[0] - plate[0], centre[1] - plate[1], centre[2] - plate[2]};
    const double len = std::sqrt(in[0] * in[0] + in[1] * in[1] + in[2] * in[2]);
    auto mask_at = [&](double t) {
        const Vec3 q = r.mask.geometry().world_to_index(
            {plate[0] + t * in[0] / len, plate[1] + t * in[1] / len, plate[2] + t * in[2] / len});
        return r.mask(std::llround(q[0]), std::llround(q[1]), std::llround(q[2]));
    };
    EXPECT_EQ(mask_at(0.5), 1);
    EXPECT_EQ(mask_at(-0.3), 0);
    EXPECT_GE(r.bone_contact, 0.85);
    EXPECT_TRUE(r.warnings.empty());
}
