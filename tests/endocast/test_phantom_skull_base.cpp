// Tests of the anatomical skull-base phantom (PhantomParams::skull_base): its truth (volume by an
// independent stratified Monte Carlo, signed distance against offsets along the normal), its CT
// (the isovalue crossing on the truth surface, every opening of >= 3 mm open along its axis, thin
// orbital roofs below the isovalue, the vault above it), presets, tilt, spine, crop,
// determinism, and the old phantoms' new error field.
#include <gtest/gtest.h>
#include <omp.h>

#include <chrono>
#include <cmath>
#include <random>

#include "endocast/phantom.h"
#include "phantom_test_helpers.h"

using namespace endocast;
using endocast::testing::along;
using endocast::testing::to_world;
using endocast::testing::trilinear;

namespace {

constexpr double kPi = 3.14159265358979323846;

PhantomParams skull_base(PhantomPreset preset = PhantomPreset::Human) {
    PhantomParams p;
    p.preset = preset;
    p.skull_base = true;
    return p;
}

/// The default human skull-base phantom, generated once for the tests that only read it.
const PhantomResult& human() {
    static const PhantomResult r = generate_phantom(skull_base());
    return r;
}

/// Nearest voxel's HU at a world point (-32768 outside the grid: nothing closes a path there).
int value_at(const PhantomResult& r, const Vec3& w) {
    const Vec3 idx = r.ct.geometry().world_to_index(w);
    const int64_t i = std::llround(idx[0]), j = std::llround(idx[1]), k = std::llround(idx[2]);
    if (!r.ct.contains(i, j, k)) return -32768;
    return r.ct(i, j, k);
}

double sdf(const PhantomResult& r, const Vec3& w) { return phantom_cavity_signed_distance(r, w); }

/// Stratified Monte Carlo volume (mL) of {sdf < 0}: one uniform point in each cube of side `cell`
/// mm of the phantom-frame box (centre +- semi axes, 3 mm margin). Its standard error is about
/// cell^3 sqrt(boundary cells / 4).
double monte_carlo_ml(const PhantomResult& r, double cell, uint64_t seed) {
    const Vec3 half = r.cavity_semi_axes_mm;
    // The cavity box of the phantom is centred at (0, 0, 2 s) in the phantom frame.
    const double zc = 2.0 * half[0] / 70.0;
    const Vec3 lo{-(half[0] + 3.0), -(half[1] + 3.0), zc - (half[2] + 3.0)};
    const Vec3 hi{half[0] + 3.0, half[1] + 3.0, lo[2] + 2.0 * (half[2] + 3.0)};
    return endocast::testing::stratified_volume_ml(lo, hi, cell, seed,
                                                   [&](const Vec3& q) { return sdf(r, to_world(r, q)) < 0; });
}

/// Surface point (world) on the ray from the phantom-frame point o (inside) along the direction
/// d: the last sign change found by marching outwards, refined by bisection.
Vec3 surface_point(const PhantomResult& r, const Vec3& d, const Vec3& o = {0, 0, 0}) {
    const Vec3 c = to_world(r, o);
    const double l = std::hypot(d[0], d[1], d[2]);
    const Vec3 u = to_world(r, {o[0] + d[0] / l, o[1] + d[1] / l, o[2] + d[2] / l});
    const Vec3 dir{u[0] - c[0], u[1] - c[1], u[2] - c[2]};
    double lo = 0, hi = 0;
    for (double t = 0.5; t < 120; t += 0.5)
        if (sdf(r, along(c, dir, t - 0.5)) < 0 && sdf(r, along(c, dir, t)) >= 0) {
            lo = t - 0.5;
            hi = t;
        }
    for (int i = 0; i < 50; ++i) {
        const double m = 0.5 * (lo + hi);
        (sdf(r, along(c, dir, m)) < 0 ? lo : hi) = m;
    }
    return along(c, dir, 0.5 * (lo + hi));
}

}  // namespace

TEST(PhantomSkullBase, HumanSizeAndStatedError) {
    const PhantomResult& r = human();
    EXPECT_GT(r.true_ecv_ml, 1300.0);
    EXPECT_LT(r.true_ecv_ml, 1500.0);
    EXPECT_GT(r.true_ecv_error_ml, 0.0);
    EXPECT_LT(r.true_ecv_error_ml, 0.0005 * r.true_ecv_ml);  // target < 0.05 %
    EXPECT_NEAR(r.suggested_iso, 717.5, 1e-9);
    EXPECT_TRUE(r.skull_base != nullptr);
    // Length and breadth of the cavity (phantom frame): 165-175 and 130-140 mm.
    auto extent = [&](const Vec3& d) {
        const Vec3 o{0, 0, 12};
        const Vec3 a = surface_point(r, d, o), b = surface_point(r, {-d[0], -d[1], -d[2]}, o);
        return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    };
    EXPECT_NEAR(extent({0, 1, 0}), 170.0, 5.0);
    EXPECT_NEAR(extent({1, 0, 0}), 137.0, 3.0);
}

TEST(PhantomSkullBase, TruthVolumeMatchesStratifiedMonteCarlo) {
    // The truth geometry does not depend on the CT grid: a tiny grid keeps the test fast.
    PhantomParams p = skull_base();
    p.size = {16, 16, 16};
    const PhantomResult r = generate_phantom(p);
    const double mc = monte_carlo_ml(r, 2.0, 7);
    // ~20k boundary cells of 8 mm^3: standard error ~0.6 mL; 4 sigma plus the stated bound.
    EXPECT_NEAR(mc, r.true_ecv_ml, 2.4 + r.true_ecv_error_ml) << "MC " << mc;
}

TEST(PhantomSkullBase, SignedDistanceAlongNormals) {
    const PhantomResult& r = human();
    std::mt19937_64 rng(11);
    std::normal_distribution<double> nd;
    int checked = 0, exact = 0;
    double worst_excess = 0;
    for (int i = 0; i < 150; ++i) {
        Vec3 d{nd(rng), nd(rng), nd(rng)};
        if (d[2] > 0.3) d[2] = -d[2];  // weigh the base
        const Vec3 p = surface_point(r, d);
        EXPECT_NEAR(sdf(r, p), 0.0, 1e-6);
        // Normal by central differences of the distance itself.
        const double e = 1e-3;
        Vec3 n;
        for (int a = 0; a < 3; ++a) {
            Vec3 pp = p, pm = p;
            pp[a] += e;
            pm[a] -= e;
            n[a] = (sdf(r, pp) - sdf(r, pm)) / (2 * e);
        }
        const double l = std::hypot(n[0], n[1], n[2]);
        ASSERT_GT(l, 0.5);
        for (double delta : {-3.0, -1.0, -0.3, 0.3, 1.0, 3.0}) {
            const Vec3 q = along(p, n, delta / l);
            const double s = sdf(r, q);
            EXPECT_EQ(s < 0, delta < 0) << "sign at " << delta;
            // The surface point p is |delta| away: the distance can only be smaller...
            worst_excess = std::max(worst_excess, std::fabs(s) - std::fabs(delta));

            ++checked;
            // ... and equals it unless another part of the surface is nearer.
            if (std::fabs(std::fabs(s) - std::fabs(delta)) <= 0.02) ++exact;
        }
    }
    EXPECT_LE(worst_excess, 0.02);
    EXPECT_GE(exact, checked * 85 / 100) << exact << " of " << checked;
}

TEST(PhantomSkullBase, SignedDistanceMatchesBruteForce) {
    // Independent of the foot-point search: surface points by bisection of the sign along the
    // edges of a 0.2 mm grid around the query, and the nearest of them. Those points lie on the
    // surface 0.2 mm apart, so the brute-force distance exceeds the true one by < 0.01 mm.
    PhantomParams p = skull_base();
    p.size = {16, 16, 16};
    const PhantomResult r = generate_phantom(p);
    std::mt19937_64 rng(21);
    std::normal_distribution<double> nd;
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < 24; ++i) {
        Vec3 d{nd(rng), nd(rng), nd(rng)};
        if (d[2] > 0) d[2] = -d[2];  // the base
        const Vec3 s0 = surface_point(r, d);
        const Vec3 q = along(s0, {u(rng), u(rng), u(rng)}, 1.6);  // within 2.8 mm
        const double got = sdf(r, q);
        const double best = endocast::testing::brute_force_distance(
            q, std::fabs(got) + 0.3, 0.2, [&](const Vec3& w) { return sdf(r, w) < 0; });
        EXPECT_LE(std::fabs(got), best + 1e-6) << i;
        EXPECT_GE(std::fabs(got), best - 0.03) << i;  // 0.02 promised + 0.01 of the sampling
    }
}

TEST(PhantomSkullBase, IsoCrossingOfTheCtIsTheTruthSurface) {
    // Where the bone is thick on one side and the cavity on the other (away from openings and
    // thin plates), the blurred CT crosses the suggested isovalue on the truth surface.
    const PhantomResult& r = human();
    std::mt19937_64 rng(5);
    std::normal_distribution<double> nd;
    int used = 0, good = 0;
    for (int i = 0; i < 300; ++i) {
        const Vec3 p = surface_point(r, {nd(rng), nd(rng), nd(rng)});
        if (phantom_near_opening(r, p, 5.0)) continue;
        Vec3 n;
        for (int a = 0; a < 3; ++a) {
            Vec3 pp = p, pm = p;
            pp[a] += 1e-3;
            pm[a] -= 1e-3;
            n[a] = (sdf(r, pp) - sdf(r, pm)) / 2e-3;
        }
        if (value_at(r, along(p, n, 2.5)) < r.suggested_iso + 500 ||
            value_at(r, along(p, n, -2.5)) > r.suggested_iso - 500)
            continue;
        ++used;
        if (std::fabs(trilinear(r, p) - r.suggested_iso) < 100.0) ++good;  // ~0.1 mm of the edge
    }
    EXPECT_GT(used, 150);
    EXPECT_GE(good, used * 95 / 100) << good << " of " << used;
}

TEST(PhantomSkullBase, SignedDistanceAtManyPointsNearTheSurface) {
    const PhantomResult& r = human();
    // 200k points within 1 mm of the vault and the base.
    const int n = 200000;
    std::vector<Vec3> pts(n);
    std::mt19937_64 rng(3);
    std::normal_distribution<double> nd;
    std::vector<Vec3> surf;
    for (int i = 0; i < 200; ++i) surf.push_back(surface_point(r, {nd(rng), nd(rng), nd(rng)}));
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < n; ++i) pts[i] = along(surf[i % surf.size()], {u(rng), u(rng), u(rng)}, 1.0);
    std::vector<double> out(n);
    const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel for schedule(dynamic, 256)
    for (int i = 0; i < n; ++i) out[i] = sdf(r, pts[i]);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("signed distance: %.2f us per point (%d threads)\n", 1e6 * s / n, omp_get_max_threads());
    // Each point lies within sqrt(3) mm of a surface point (offsets in [-1, 1]^3): so does its
    // distance (no timing is asserted; the time per point is printed for the record).
    for (int i = 0; i < n; ++i) ASSERT_LE(std::fabs(out[i]), std::sqrt(3.0) + 1e-6) << i;
}

TEST(PhantomSkullBase, OpeningsAreOpenAlongTheirAxes) {
    const PhantomResult& r = human();
    ASSERT_EQ(r.openings.size(), 29u);
    int checked = 0;
    for (const PhantomOpening& o : r.openings) {
        // >= 3 mm openings; spinosum (2 mm) and the 1 mm cribriform holes vanish in the blur.
        if (o.name.rfind("cribriform", 0) == 0 || o.name.rfind("foramen_spinosum", 0) == 0) continue;
        EXPECT_NEAR(sdf(r, o.centre_world), 0.0, 1e-6) << o.name;
        EXPECT_GT(sdf(r, along(o.centre_world, o.axis_world, 1.0)), 0.0) << o.name << " axis points in";
        // From 2 mm inside to 45 mm out: through the canal and on in the space it leads to.
        for (double t = -2.0; t <= 45.0; t += 0.25)
            if (value_at(r, along(o.centre_world, o.axis_world, t)) >= r.suggested_iso) {
                ADD_FAILURE() << o.name << " closed at " << t << " mm along its axis";
                break;
            }
        ++checked;
    }
    EXPECT_EQ(checked, 17);
}

TEST(PhantomSkullBase, ThinOrbitalRoofFallsBelowIsoAndVaultStaysAbove) {
    const PhantomResult& r = human();
    for (double x : {-22.0, 22.0}) {
        // Vertical profile through the thinnest point of the roof: brain above, fat below.
        int peak = -32768;
        for (double z = -30; z <= -12; z += 0.25) peak = std::max(peak, value_at(r, to_world(r, {x, 60, z})));
        EXPECT_LT(peak, r.suggested_iso) << "roof at x " << x;
        EXPECT_GT(peak, 200) << "there is a roof at x " << x;
    }
    int vault = -32768;
    for (double z = 60; z <= 80; z += 0.25) vault = std::max(vault, value_at(r, to_world(r, {0, 0, z})));
    EXPECT_GT(vault, 1300);
}

TEST(PhantomSkullBase, DryPresetIsAirFilled) {
    PhantomParams p = skull_base(PhantomPreset::Dry);
    p.noise = false;
    const PhantomResult r = generate_phantom(p);
    EXPECT_NEAR(r.suggested_iso, 200.0, 1e-9);
    EXPECT_EQ(value_at(r, r.cavity_centre_world), -1000);
    EXPECT_NEAR(r.true_ecv_ml, human().true_ecv_ml, 1e-9);
    // Outside the skull: air (no scalp).
    EXPECT_EQ(value_at(r, to_world(r, {0, 0, 80})), -1000);
    int peak = -32768;
    for (double z = -30; z <= -12; z += 0.25) peak = std::max(peak, value_at(r, to_world(r, {22, 60, z})));
    EXPECT_LT(peak, r.suggested_iso);
}

TEST(PhantomSkullBase, TiltKeepsTheTruth) {
    PhantomParams p = skull_base();
    p.size = {16, 16, 16};
    const PhantomResult a = generate_phantom(p);
    p.tilt_deg = 25;
    const PhantomResult b = generate_phantom(p);
    EXPECT_NEAR(a.true_ecv_ml, b.true_ecv_ml, a.true_ecv_error_ml + b.true_ecv_error_ml);
    // The same phantom-frame point has the same distance in both.
    for (const Vec3& q : {Vec3{0, 0, 64}, Vec3{40, 2, -44}, Vec3{0, -40, -57}, Vec3{22, 60, -21}})
        EXPECT_NEAR(sdf(a, to_world(a, q)), sdf(b, to_world(b, q)), 1e-6);
    const double t = 25 * kPi / 180;
    EXPECT_NEAR(b.foramen_magnum_axis[1], std::sin(t), 1e-9);
    EXPECT_NEAR(b.foramen_magnum_axis[2], -std::cos(t), 1e-9);
}

TEST(PhantomSkullBase, MacaquePreset) {
    PhantomParams p = skull_base(PhantomPreset::Macaque);
    const PhantomResult r = generate_phantom(p);
    EXPECT_GT(r.true_ecv_ml, 80.0);
    EXPECT_LT(r.true_ecv_ml, 100.0);
    EXPECT_LT(r.true_ecv_error_ml, 0.0005 * r.true_ecv_ml);
    EXPECT_NEAR(r.ct.geometry().spacing[0], 0.5, 1e-12);
    EXPECT_NEAR(r.foramen_magnum_radius_mm, 0.4 * 17.5, 1e-9);
    EXPECT_GT(value_at(r, to_world(r, {0, 0, 0.4 * 70})), r.suggested_iso);  // vault
}

TEST(PhantomSkullBase, SpineHasASpinalCanalBelowTheForamenMagnum) {
    PhantomParams p = skull_base();
    p.spine = true;
    p.noise = false;
    const PhantomResult r = generate_phantom(p);
    EXPECT_NEAR(r.spinal_canal_radius_mm, 8.0, 1e-12);
    const Vec3 fm = r.foramen_magnum_world, ax = r.foramen_magnum_axis;
    for (double t = -2; t <= 80; t += 1) EXPECT_LT(value_at(r, along(fm, ax, t)), r.suggested_iso) << t;
    // Vertebral rings around the canal: bone at 10.5 mm from the axis somewhere below.
    int ring = -32768;
    for (double t = 10; t <= 60; t += 0.5)
        ring = std::max(ring, value_at(r, {fm[0] + 10.5, fm[1] + t * ax[1], fm[2] + t * ax[2]}));
    EXPECT_GT(ring, 1000);
    EXPECT_NEAR(r.true_ecv_ml, human().true_ecv_ml, 1e-9);  // the canal is not cavity
}

TEST(PhantomSkullBase, CropCutsTheTruthByThePlane) {
    PhantomParams p = skull_base();
    p.crop_base_mm = 25;
    p.tilt_deg = 10;
    const PhantomResult r = generate_phantom(p);
    ASSERT_TRUE(r.cropped);
    const double lower_face = r.ct.geometry().origin[2] - 0.5 * r.ct.geometry().spacing[2];
    EXPECT_NEAR(r.crop_plane_z_mm, lower_face, 1e-9);
    EXPECT_LT(r.true_ecv_ml, human().true_ecv_ml - 20);
    EXPECT_LT(r.true_ecv_slice_centres_ml, r.true_ecv_ml);
    // Below the plane nothing is cavity; just above it, inside the uncropped cavity, the distance
    // is the height above the plane. The foramen magnum's centre lies below the plane.
    const Vec3 fm = r.foramen_magnum_world;
    EXPECT_GT(sdf(r, {fm[0], fm[1], r.crop_plane_z_mm - 1.0}), 0.0);
    const Vec3 q{fm[0], fm[1] + 10, r.crop_plane_z_mm + 0.7};
    EXPECT_NEAR(sdf(r, q), -0.7, 0.02);
    EXPECT_NEAR(sdf(r, {q[0], q[1], q[2] - 1.4}), 0.7, 0.02);
}

TEST(PhantomSkullBase, DeterministicForThreadCounts) {
    PhantomParams p = skull_base(PhantomPreset::Macaque);
    p.seed = 5;
    endocast::testing::expect_same_for_thread_counts(p);
}

TEST(PhantomSkullBase, RefusesTheOldPhantomsFaceOptions) {
    for (int i = 0; i < 3; ++i) {
        PhantomParams p = skull_base();
        p.size = {8, 8, 8};
        (i == 0 ? p.orbits : i == 1 ? p.frontal_sinus : p.body) = true;
        EXPECT_THROW(generate_phantom(p), InvalidParameter);
    }
}

TEST(PhantomSkullBase, OldPhantomsStateATinyError) {
    PhantomParams p;
    p.preset = PhantomPreset::Macaque;
    p.noise = false;
    const PhantomResult r = generate_phantom(p);
    EXPECT_GT(r.true_ecv_error_ml, 0.0);
    EXPECT_LT(r.true_ecv_error_ml, 1e-9 * r.true_ecv_ml);
    EXPECT_EQ(r.skull_base, nullptr);
}
