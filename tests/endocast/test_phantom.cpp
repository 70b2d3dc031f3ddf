#include <gtest/gtest.h>
#include <omp.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "endocast/phantom.h"

using namespace endocast;

namespace {

constexpr double kPi = 3.14159265358979323846;

PhantomParams clean(PhantomPreset preset = PhantomPreset::Human) {
    PhantomParams p;
    p.preset = preset;
    p.noise = false;
    p.blur = false;
    return p;
}

/// Voxel value at the world position nearest to phantom-frame point q (tilt about x, degrees).
int16_t at_phantom(const PhantomResult& r, const Vec3& q, double tilt_deg = 0.0) {
    const double t = tilt_deg * kPi / 180.0;
    const double c = std::cos(t), s = std::sin(t);
    const Vec3 w{r.cavity_centre_world[0] + q[0], r.cavity_centre_world[1] + c * q[1] - s * q[2],
                 r.cavity_centre_world[2] + s * q[1] + c * q[2]};
    const Vec3 idx = r.ct.geometry().world_to_index(w);
    const int64_t i = std::llround(idx[0]), j = std::llround(idx[1]), k = std::llround(idx[2]);
    EXPECT_TRUE(r.ct.contains(i, j, k)) << q[0] << "," << q[1] << "," << q[2];
    if (!r.ct.contains(i, j, k)) return 0;
    return r.ct(i, j, k);
}

/// Counts voxels below the iso whose centre lies inside the inner ellipsoid grown by `grow` mm.
double cavity_ml(const PhantomResult& r, double grow) {
    const auto& g = r.ct.geometry();
    const Vec3 a = r.cavity_semi_axes_mm;
    size_t n = 0;
    for (int64_t k = 0; k < r.ct.nz(); ++k)
        for (int64_t j = 0; j < r.ct.ny(); ++j)
            for (int64_t i = 0; i < r.ct.nx(); ++i) {
                const Vec3 w = g.index_to_world(double(i), double(j), double(k));
                const double x = (w[0] - r.cavity_centre_world[0]) / (a[0] + grow);
                const double y = (w[1] - r.cavity_centre_world[1]) / (a[1] + grow);
                const double z = (w[2] - r.cavity_centre_world[2]) / (a[2] + grow);
                if (x * x + y * y + z * z < 1.0 && r.ct(i, j, k) < r.suggested_iso) ++n;
            }
    return double(n) * g.voxel_volume_mm3() / 1000.0;
}

}  // namespace

TEST(PhantomPreset, ParseAndToString) {
    EXPECT_EQ(parse_phantom_preset("human"), PhantomPreset::Human);
    EXPECT_EQ(parse_phantom_preset("dry"), PhantomPreset::Dry);
    EXPECT_EQ(parse_phantom_preset("macaque"), PhantomPreset::Macaque);
    EXPECT_EQ(to_string(PhantomPreset::Macaque), "macaque");
    EXPECT_EQ(parse_phantom_preset(to_string(PhantomPreset::Dry)), PhantomPreset::Dry);
    try {
        parse_phantom_preset("gorilla");
        FAIL() << "expected InvalidParameter";
    } catch (const InvalidParameter& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("gorilla"), std::string::npos);
        EXPECT_NE(m.find("macaque"), std::string::npos);
    }
}

TEST(Phantom, DeterministicAndSeedDependent) {
    PhantomParams p;
    const auto a = generate_phantom(p);
    const auto b = generate_phantom(p);
    EXPECT_EQ(a.ct.buffer(), b.ct.buffer());
    p.seed = 2;
    const auto c = generate_phantom(p);
    ASSERT_EQ(a.ct.size(), c.ct.size());
    EXPECT_NE(a.ct.buffer(), c.ct.buffer());
    EXPECT_FALSE(a.description.empty());
    EXPECT_EQ(a.description.find('\n'), std::string::npos);
}

TEST(Phantom, IdenticalForAnyThreadCount) {
    PhantomParams p;
    p.tilt_deg = 17;
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const auto a = generate_phantom(p);
    omp_set_num_threads(2);
    const auto b = generate_phantom(p);
    omp_set_num_threads(saved);
    EXPECT_EQ(a.ct.buffer(), b.ct.buffer());
}

TEST(Phantom, NoiseHasExpectedSigma) {
    PhantomParams p;
    p.blur = false;
    const auto r = generate_phantom(p);
    // The voxels near the cavity centre are brain (35 HU) plus noise.
    double s1 = 0, s2 = 0;
    int n = 0;
    for (int dz = -10; dz <= 10; ++dz)
        for (int dy = -10; dy <= 10; ++dy)
            for (int dx = -10; dx <= 10; ++dx) {
                const double v = at_phantom(r, {double(dx), double(dy), double(dz)});
                s1 += v;
                s2 += v * v;
                ++n;
            }
    const double mean = s1 / n, sd = std::sqrt(s2 / n - mean * mean);
    EXPECT_NEAR(mean, 35.0, 1.5);
    EXPECT_NEAR(sd, 20.0, 1.0);
}

TEST(Phantom, TrueVolumeIsTheEllipsoid) {
    for (auto preset : {PhantomPreset::Human, PhantomPreset::Dry, PhantomPreset::Macaque}) {
        PhantomParams p;
        p.preset = preset;
        p.size = {0, 0, 0};
        const auto r = generate_phantom(p);
        const Vec3 a = r.cavity_semi_axes_mm;
        EXPECT_DOUBLE_EQ(r.true_ecv_ml, 4.0 / 3.0 * kPi * a[0] * a[1] * a[2] / 1000.0);
    }
}

TEST(Phantom, HumanGeometryMatchesTruth) {
    const auto r = generate_phantom(clean());
    EXPECT_GT(r.true_ecv_ml, 1300.0);
    EXPECT_LT(r.true_ecv_ml, 1400.0);
    EXPECT_NEAR(r.suggested_iso, 717.5, 1e-9);
    EXPECT_NEAR(cavity_ml(r, 2.0), r.true_ecv_ml, 0.01 * r.true_ecv_ml);

    const Vec3 a = r.cavity_semi_axes_mm;
    const double t = r.shell_thickness_mm;
    EXPECT_EQ(at_phantom(r, {0, 0, 0}), 35);                        // brain
    EXPECT_EQ(at_phantom(r, {0, 0, a[2] + 0.5 * t}), 1400);         // vault bone
    EXPECT_EQ(at_phantom(r, {-a[0] - 0.5 * t, 0, 0}), 1400);        // left side (no foramen at z=0)
    EXPECT_EQ(at_phantom(r, {0, a[1] + 0.5 * t, 0}), 1400);         // frontal bone
    EXPECT_EQ(at_phantom(r, {0, 0, a[2] + t + 2.5}), 30);           // scalp
    EXPECT_EQ(at_phantom(r, {0, 0, a[2] + t + 5 + 4}), -1000);      // air above the scalp
    EXPECT_EQ(r.ct(0, 0, r.ct.nz() - 1), -1000);                    // air corner

    // Foramen magnum: its axis at the shell's mid-depth is below the iso.
    const Vec3 fm = r.foramen_magnum_world;
    const Vec3 idx = r.ct.geometry().world_to_index({fm[0], fm[1], fm[2] - 0.5 * t});
    EXPECT_LT(r.ct(std::llround(idx[0]), std::llround(idx[1]), std::llround(idx[2])),
              r.suggested_iso);
    EXPECT_NEAR(r.foramen_magnum_radius_mm, 14.0, 1e-9);
    // Neck: soft tissue at the lower border under the foramen magnum.
    const Vec3 low = r.ct.geometry().world_to_index({fm[0], fm[1], r.ct.geometry().origin[2]});
    EXPECT_EQ(r.ct(std::llround(low[0]), std::llround(low[1]), 0), 30);
}

TEST(Phantom, BlurredSurfaceCrossesIsoOnTheEllipsoid) {
    PhantomParams p;
    p.noise = false;
    p.small_foramina = false;
    p.crack = false;
    p.foramen_magnum = false;
    const auto r = generate_phantom(p);
    EXPECT_NEAR(cavity_ml(r, 2.0), r.true_ecv_ml, 0.002 * r.true_ecv_ml);
    // Along +x from the centre, the iso crossing of the inner surface is at x = a (linear interp.).
    const Vec3 c = r.ct.geometry().world_to_index(r.cavity_centre_world);
    const int64_t j = std::llround(c[1]), k = std::llround(c[2]);
    const double a = r.cavity_semi_axes_mm[0];
    const double iso = r.suggested_iso;
    double crossing = -1;
    for (int64_t i = std::llround(c[0]); i + 1 < r.ct.nx(); ++i) {
        const double v0 = r.ct(i, j, k), v1 = r.ct(i + 1, j, k);
        if (v0 < iso && v1 >= iso) {
            crossing = double(i) + (iso - v0) / (v1 - v0);
            break;
        }
    }
    const double x = r.ct.geometry().index_to_world(crossing, 0, 0)[0] - r.cavity_centre_world[0];
    EXPECT_NEAR(x, a, 0.05);
}

TEST(Phantom, DryHasAirAndNoScalp) {
    const auto r = generate_phantom(clean(PhantomPreset::Dry));
    EXPECT_NEAR(r.suggested_iso, 200.0, 1e-9);
    const Vec3 a = r.cavity_semi_axes_mm;
    const double t = r.shell_thickness_mm;
    EXPECT_EQ(at_phantom(r, {0, 0, 0}), -1000);
    EXPECT_EQ(at_phantom(r, {0, 0, a[2] + 0.5 * t}), 1400);
    EXPECT_EQ(at_phantom(r, {0, 0, a[2] + t + 2.5}), -1000);  // no scalp
    EXPECT_EQ(at_phantom(r, {0, -15, -a[2] - t - 3}), -1000); // no neck
    EXPECT_NEAR(cavity_ml(r, 2.0), r.true_ecv_ml, 0.01 * r.true_ecv_ml);
}

TEST(Phantom, DiploicVoidsAreInsideTheShell) {
    // Voids lower the bone but never cross the inner or outer surface: without voids and with them,
    // the voxels outside the shell are identical.
    PhantomParams p = clean();
    p.diploic_voids = false;
    const auto plain = generate_phantom(p);
    p.diploic_voids = true;
    const auto holey = generate_phantom(p);
    ASSERT_EQ(plain.ct.size(), holey.ct.size());
    size_t changed = 0, outside = 0;
    for (size_t i = 0; i < plain.ct.size(); ++i) {
        if (plain.ct[i] == holey.ct[i]) continue;
        ++changed;
        if (plain.ct[i] != 1400) ++outside;
    }
    EXPECT_GT(changed, 100u);
    EXPECT_EQ(outside, 0u);
    EXPECT_NE(holey.description.find("voids(40)"), std::string::npos) << holey.description;
}

TEST(Phantom, TiltRotatesTheSkull) {
    PhantomParams p = clean();
    p.tilt_deg = 30;
    const auto r = generate_phantom(p);
    const double c = r.cavity_semi_axes_mm[2], b = r.cavity_semi_axes_mm[1];
    EXPECT_EQ(at_phantom(r, {0, 0, c - 3}, 30), 35);
    EXPECT_EQ(at_phantom(r, {0, 0, c + 3}, 30), 1400);
    EXPECT_EQ(at_phantom(r, {0, b - 3, 0}, 30), 35);
    EXPECT_EQ(at_phantom(r, {0, b + 3, 0}, 30), 1400);
    // Without rotation, the world point straight above at c+3 is not bone in the tilted skull
    // (it lies inside the cavity since the top moved forward).
    EXPECT_EQ(at_phantom(r, {0, 0, c + 3}, 0), 35);
}

TEST(Phantom, OriginAndSpacingHonoured) {
    PhantomParams p = clean();
    p.origin = {-100, 50, 20};
    p.spacing = {1, 1, 1.5};
    const auto r = generate_phantom(p);
    const auto& g = r.ct.geometry();
    EXPECT_EQ(g.origin, p.origin);
    EXPECT_EQ(g.spacing, p.spacing);
    const Vec3 c = g.world_to_index(r.cavity_centre_world);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(c[a], 0.5 * double(g.dims[a] - 1), 1e-9);
    const Vec3 w = g.index_to_world(c[0], c[1], c[2]);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(w[a], r.cavity_centre_world[a], 1e-9);
    const double zc = r.cavity_semi_axes_mm[2];
    EXPECT_EQ(at_phantom(r, {0, 0, 0}), 35);
    EXPECT_EQ(at_phantom(r, {0, 0, zc - 2}), 35);
    EXPECT_EQ(at_phantom(r, {0, 0, zc + 3}), 1400);
    EXPECT_NEAR(cavity_ml(r, 2.0), r.true_ecv_ml, 0.01 * r.true_ecv_ml);
}

TEST(Phantom, ExplicitSizeIsUsed) {
    PhantomParams p = clean(PhantomPreset::Dry);
    p.size = {160, 190, 150};
    const auto r = generate_phantom(p);
    EXPECT_EQ(r.ct.dims(), (Dims{160, 190, 150}));
    EXPECT_EQ(at_phantom(r, {0, 0, 0}), -1000);
}

TEST(Phantom, Macaque) {
    PhantomParams p;
    p.preset = PhantomPreset::Macaque;
    const auto r = generate_phantom(p);
    EXPECT_NEAR(r.true_ecv_ml, 89.0, 2.0);
    EXPECT_EQ(r.ct.geometry().spacing, (Vec3{0.5, 0.5, 0.5}));
    EXPECT_GT(r.foramen_magnum_radius_mm * 2.0 / 0.5, 12.0);
    const auto q = generate_phantom(clean(PhantomPreset::Macaque));
    EXPECT_NEAR(cavity_ml(q, 1.0), q.true_ecv_ml, 0.01 * q.true_ecv_ml);
    const double t = q.shell_thickness_mm;
    EXPECT_EQ(at_phantom(q, {0, 0, 0}), 35);
    EXPECT_EQ(at_phantom(q, {0, 0, q.cavity_semi_axes_mm[2] + 0.5 * t}), 1400);
    EXPECT_EQ(at_phantom(q, {0, 0, q.cavity_semi_axes_mm[2] + t + 1}), 30);
}

TEST(Phantom, RejectsBadParameters) {
    EXPECT_THROW(parse_phantom_preset("chimp"), InvalidParameter);
    PhantomParams p;
    p.spacing = {-1, 1, 1};
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = {};
    p.spacing = {1, std::nan(""), 1};
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = {};
    p.size = {50, 50, 50};
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = {};
    p.size = {-1, 0, 0};
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = {};
    p.tilt_deg = 120;
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = {};
    p.size = {2000, 2000, 1000};
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
}

TEST(Phantom, DefaultHumanIsFast) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = generate_phantom();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("default human phantom: %s in %.2f s\n", r.description.c_str(), s);
    EXPECT_LT(s, 20.0);  // generous: sanitizer and debug builds
}

TEST(Phantom, OpeningsCarveTheShellOnly) {
    PhantomParams p = clean();
    p.diploic_voids = false;
    p.small_foramina = p.crack = p.foramen_magnum = false;
    const auto closed = generate_phantom(p);
    p.small_foramina = true;
    const auto foramina = generate_phantom(p);
    p.small_foramina = false;
    p.crack = true;
    const auto cracked = generate_phantom(p);
    size_t opened_f = 0, opened_c = 0;
    for (size_t i = 0; i < closed.ct.size(); ++i) {
        if (closed.ct[i] == 1400 && foramina.ct[i] < closed.suggested_iso) ++opened_f;
        if (closed.ct[i] == 1400 && cracked.ct[i] < closed.suggested_iso) ++opened_c;
        // Nothing but bone changes.
        if (closed.ct[i] != 1400) {
            EXPECT_EQ(closed.ct[i], foramina.ct[i]);
            EXPECT_EQ(closed.ct[i], cracked.ct[i]);
        }
    }
    EXPECT_GT(opened_f, 5u * 20u);  // five holes through ~6 mm of bone
    EXPECT_GT(opened_c, 60u);       // ~30 mm x 1 mm x 6 mm slit
    EXPECT_LT(opened_c, 400u);
}
