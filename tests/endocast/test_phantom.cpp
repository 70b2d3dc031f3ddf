#include <gtest/gtest.h>
#include <omp.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <queue>
#include <random>

#include "endocast/stages/binarize.h"
#include "endocast/stages/distance.h"
#include "endocast/stages/morphology.h"
#include "endocast/phantom.h"
#include "endocast/stages/seeds.h"

#include "phantom_test_helpers.h"
#include "test_helpers.h"
using namespace endocast;
using endocast::testing::to_float;

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
    endocast::testing::expect_same_for_thread_counts(p);
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

// ---- the added structures: spine, sinus, orbits, body, cropped base, truth functions ----------

namespace {

/// Value at a world point (nearest voxel); `inside` tells whether it lies in the volume.
int16_t at_world(const PhantomResult& r, const Vec3& w) {
    const Vec3 idx = r.ct.geometry().world_to_index(w);
    const int64_t i = std::llround(idx[0]), j = std::llround(idx[1]), k = std::llround(idx[2]);
    EXPECT_TRUE(r.ct.contains(i, j, k)) << w[0] << "," << w[1] << "," << w[2];
    if (!r.ct.contains(i, j, k)) return 0;
    return r.ct(i, j, k);
}

Vec3 along(const Vec3& c, const Vec3& axis, double t) {
    return {c[0] + axis[0] * t, c[1] + axis[1] * t, c[2] + axis[2] * t};
}

/// World point of a phantom-frame point q (through the result's rotation).
Vec3 world_of(const PhantomResult& r, const Vec3& q) {
    const auto& R = r.cavity_rotation;
    const Vec3& c = r.cavity_centre_world;
    return {c[0] + R[0] * q[0] + R[1] * q[1] + R[2] * q[2],
            c[1] + R[3] * q[0] + R[4] * q[1] + R[5] * q[2],
            c[2] + R[6] * q[0] + R[7] * q[1] + R[8] * q[2]};
}

const PhantomOpening* find_opening(const PhantomResult& r, const std::string& name) {
    for (const auto& o : r.openings)
        if (o.name == name) return &o;
    return nullptr;
}

/// 6-connected flood over voxels where pass(value) holds, from `seed`; returns the visited mask.
template <class Pass>
std::vector<uint8_t> flood(const Volume<int16_t>& v, const Vec3& seed_world, Pass pass) {
    std::vector<uint8_t> seen(v.size(), 0);
    const Vec3 s = v.geometry().world_to_index(seed_world);
    const int64_t si = std::llround(s[0]), sj = std::llround(s[1]), sk = std::llround(s[2]);
    if (!v.contains(si, sj, sk) || !pass(v(si, sj, sk))) return seen;
    std::queue<size_t> q;
    q.push(v.index(si, sj, sk));
    seen[q.front()] = 1;
    const int64_t nx = v.nx(), ny = v.ny(), nz = v.nz();
    while (!q.empty()) {
        const size_t id = q.front();
        q.pop();
        const int64_t i = int64_t(id % nx), j = int64_t((id / nx) % ny), k = int64_t(id / (nx * ny));
        const int64_t nb[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k},
                                  {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
        for (const auto& n : nb) {
            if (n[0] < 0 || n[1] < 0 || n[2] < 0 || n[0] >= nx || n[1] >= ny || n[2] >= nz) continue;
            const size_t m = v.index(n[0], n[1], n[2]);
            if (seen[m] || !pass(v[m])) continue;
            seen[m] = 1;
            q.push(m);
        }
    }
    return seen;
}

bool touches_border(const Volume<int16_t>& v, const std::vector<uint8_t>& seen) {
    for (int64_t k = 0; k < v.nz(); ++k)
        for (int64_t j = 0; j < v.ny(); ++j)
            for (int64_t i = 0; i < v.nx(); ++i)
                if (seen[v.index(i, j, k)] && (i == 0 || j == 0 || k == 0 || i == v.nx() - 1 ||
                                               j == v.ny() - 1 || k == v.nz() - 1))
                    return true;
    return false;
}

bool seen_at(const PhantomResult& r, const std::vector<uint8_t>& seen, const Vec3& w) {
    const Vec3 idx = r.ct.geometry().world_to_index(w);
    return seen[r.ct.index(std::llround(idx[0]), std::llround(idx[1]), std::llround(idx[2]))] != 0;
}

// Human geometry that the tests mirror from phantom.cpp (phantom frame, mm).
constexpr double kFmY = -15.0;
const double kRingTop = -66.0 * std::sqrt(1.0 - (15.0 / 88.0) * (15.0 / 88.0)) - 2.0;

}  // namespace

TEST(PhantomEllipsoid, SignedDistanceOnAxesAndAgainstBruteForce) {
    const Vec3 a{65, 82, 60};
    EXPECT_NEAR(ellipsoid_signed_distance({0, 0, 0}, a), -60.0, 1e-12);
    EXPECT_NEAR(ellipsoid_signed_distance({70, 0, 0}, a), 5.0, 1e-12);
    EXPECT_NEAR(ellipsoid_signed_distance({0, -90, 0}, a), 8.0, 1e-12);
    EXPECT_NEAR(ellipsoid_signed_distance({0, 0, 59}, a), -1.0, 1e-12);
    EXPECT_NEAR(ellipsoid_signed_distance({0, 81, 0}, a), -1.0, 1e-12);
    EXPECT_NEAR(ellipsoid_signed_distance({-64.5, 0, 0}, a), -0.5, 1e-12);
    // Near the centre on the y axis, the nearest point leaves the axis (towards the short z axis);
    // deeper along y (y = 40) the vertex (0, 82, 0) is nearest.
    Vec3 x;
    const double d = ellipsoid_signed_distance({0, 10, 0}, a, &x);
    EXPECT_GT(d, -60.0);
    EXPECT_LT(d, -58.0);
    EXPECT_GT(std::fabs(x[2]), 1.0);
    EXPECT_NEAR(ellipsoid_signed_distance({0, 40, 0}, a, &x), -42.0, 1e-9);
    EXPECT_NEAR(x[1], 82.0, 1e-9);
    // Random points: the closest point lies on the surface, p - x is along the normal there, and
    // no surface sample is nearer.
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-110, 110);
    for (int n = 0; n < 60; ++n) {
        const Vec3 p{u(rng), u(rng), u(rng) * 0.8};
        Vec3 c;
        const double sd = ellipsoid_signed_distance(p, a, &c);
        const double g = c[0] * c[0] / (a[0] * a[0]) + c[1] * c[1] / (a[1] * a[1]) +
                         c[2] * c[2] / (a[2] * a[2]);
        EXPECT_NEAR(g, 1.0, 1e-9);
        const Vec3 v{p[0] - c[0], p[1] - c[1], p[2] - c[2]};
        EXPECT_NEAR(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), std::fabs(sd), 1e-9);
        const Vec3 nrm{c[0] / (a[0] * a[0]), c[1] / (a[1] * a[1]), c[2] / (a[2] * a[2])};
        const Vec3 cr{v[1] * nrm[2] - v[2] * nrm[1], v[2] * nrm[0] - v[0] * nrm[2],
                      v[0] * nrm[1] - v[1] * nrm[0]};
        const double nn = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        EXPECT_NEAR(std::sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]) / nn, 0.0, 1e-7);
        double brute = 1e300;
        for (int it = 0; it <= 180; ++it)
            for (int ip = 0; ip < 360; ++ip) {
                const double th = it * kPi / 180, ph = ip * kPi / 180;
                const Vec3 s{a[0] * std::sin(th) * std::cos(ph), a[1] * std::sin(th) * std::sin(ph),
                             a[2] * std::cos(th)};
                brute = std::min(brute, std::hypot(p[0] - s[0], p[1] - s[1], p[2] - s[2]));
            }
        EXPECT_LE(std::fabs(sd), brute + 1e-9);
        EXPECT_NEAR(std::fabs(sd), brute, 0.6);  // the 1-degree grid is ~0.7 mm coarse
        EXPECT_EQ(sd < 0, g > 0 && (p[0] * p[0] / (a[0] * a[0]) + p[1] * p[1] / (a[1] * a[1]) +
                                    p[2] * p[2] / (a[2] * a[2])) < 1.0);
    }
    EXPECT_THROW(ellipsoid_signed_distance({1, 1, 1}, {1, 0, 1}), InvalidParameter);
}

TEST(PhantomTruth, CavitySignedDistanceFollowsTheTilt) {
    PhantomParams p = clean();
    p.tilt_deg = 30;
    const auto r = generate_phantom(p);
    const Vec3 a = r.cavity_semi_axes_mm;
    EXPECT_NEAR(phantom_cavity_signed_distance(r, r.cavity_centre_world), -a[2], 1e-9);
    EXPECT_NEAR(phantom_cavity_signed_distance(r, world_of(r, {0, 0, a[2] + 3})), 3.0, 1e-9);
    EXPECT_NEAR(phantom_cavity_signed_distance(r, world_of(r, {0, a[1] - 2, 0})), -2.0, 1e-9);
    EXPECT_NEAR(phantom_cavity_signed_distance(r, world_of(r, {-a[0] - 1.5, 0, 0})), 1.5, 1e-9);
    // The rotation maps the phantom's +z to (0, -sin, cos) in world.
    const auto& R = r.cavity_rotation;
    EXPECT_NEAR(R[5], -0.5, 1e-12);
    EXPECT_NEAR(R[8], std::cos(30 * kPi / 180), 1e-12);
    // Foramen magnum: on the inner surface, axis = rotated -z.
    EXPECT_NEAR(phantom_cavity_signed_distance(r, r.foramen_magnum_world), 0.0, 1e-9);
    EXPECT_NEAR(r.foramen_magnum_axis[1], 0.5, 1e-12);
    EXPECT_NEAR(r.foramen_magnum_axis[2], -std::cos(30 * kPi / 180), 1e-12);
    EXPECT_FALSE(r.cropped);
    EXPECT_DOUBLE_EQ(r.true_ecv_slice_centres_ml, r.true_ecv_ml);
}

TEST(PhantomTruth, OpeningsAreListedAndNearOpeningWorks) {
    PhantomParams p = human_full_phantom_params();
    p.noise = false;
    p.tilt_deg = 12;
    const auto r = generate_phantom(p);
    ASSERT_EQ(r.openings.size(), 9u);  // foramen magnum, 5 foramina, crack, 2 optic canals
    for (const auto& o : r.openings) {
        EXPECT_NEAR(phantom_cavity_signed_distance(r, o.centre_world), 0.0, 1e-6) << o.name;
        EXPECT_NEAR(std::hypot(o.axis_world[0], o.axis_world[1], o.axis_world[2]), 1.0, 1e-12);
        // The axis points out of the braincase.
        EXPECT_GT(phantom_cavity_signed_distance(r, along(o.centre_world, o.axis_world, 1.0)), 0.0)
            << o.name;
        EXPECT_TRUE(phantom_near_opening(r, o.centre_world, 0.0));
        // Through the opening the CT is below the iso (open), at mid-depth of the shell.
        if (o.name.rfind("foramen_", 0) == 0 || o.name == "optic_canal_left")
            EXPECT_LT(at_world(r, along(o.centre_world, o.axis_world, 3.0)), r.suggested_iso) << o.name;
    }
    const PhantomOpening* fm = find_opening(r, "foramen_magnum");
    ASSERT_NE(fm, nullptr);
    EXPECT_EQ(fm->centre_world, r.foramen_magnum_world);
    EXPECT_EQ(fm->axis_world, r.foramen_magnum_axis);
    EXPECT_DOUBLE_EQ(fm->radius_mm, 14.0);
    const PhantomOpening* oc = find_opening(r, "optic_canal_right");
    ASSERT_NE(oc, nullptr);
    EXPECT_DOUBLE_EQ(oc->radius_mm, 7.0);
    EXPECT_DOUBLE_EQ(r.optic_canal_radius_mm, 7.0);
    // Near: within the disk's radius, 1 mm off the plane; far: 5 mm beyond the rim.
    Vec3 side{fm->axis_world[1] * 0 + 1, 0, 0};  // x is across every axis here (tilt about x)
    EXPECT_TRUE(phantom_near_opening(r, along(along(fm->centre_world, side, 10.0), fm->axis_world, 1.0), 1.0 + 1e-9));
    EXPECT_FALSE(phantom_near_opening(r, along(along(fm->centre_world, side, 10.0), fm->axis_world, 3.0), 2.0));
    EXPECT_FALSE(phantom_near_opening(r, along(fm->centre_world, side, 14.0 + 5.0), 4.0));
    EXPECT_TRUE(phantom_near_opening(r, along(fm->centre_world, side, 14.0 + 5.0), 5.0 + 1e-9));
    EXPECT_FALSE(phantom_near_opening(r, world_of(r, {r.cavity_semi_axes_mm[0], 0, 0}), 5.0));
}

TEST(PhantomTruth, AddedStructuresKeepTheInnerSurfaceExact) {
    // Every voxel that the spine, sinus or orbits change lies outside the inner surface's blend
    // band (+-4 sigma), unless it is near a listed opening (the optic canals): inside that band the
    // skull is pure bone, so the iso crossing of the inner surface is the ellipsoid.
    // (Diploic voids off: they are placed around the carvings, so they would move.)
    PhantomParams p;
    p.noise = false;
    p.diploic_voids = false;
    const auto plain = generate_phantom(p);
    PhantomParams q = human_full_phantom_params();
    q.noise = false;
    q.diploic_voids = false;
    q.size = plain.ct.dims();  // the same grid around the same centre
    const auto full = generate_phantom(q);
    ASSERT_EQ(full.cavity_centre_world, plain.cavity_centre_world);
    const auto& g = plain.ct.geometry();
    const double band = 4.0 * plain.sigma_mm;
    size_t changed = 0, near_surface = 0;
    double min_clear = 1e300;
    for (int64_t k = 0; k < g.dims[2]; ++k)
        for (int64_t j = 0; j < g.dims[1]; ++j)
            for (int64_t i = 0; i < g.dims[0]; ++i) {
                if (plain.ct(i, j, k) == full.ct(i, j, k)) continue;
                ++changed;
                const Vec3 w = g.index_to_world(double(i), double(j), double(k));
                if (phantom_near_opening(full, w, 2.0 * band + 1.0)) continue;
                const double d = phantom_cavity_signed_distance(full, w);
                min_clear = std::min(min_clear, d);
                if (d < band) ++near_surface;
            }
    EXPECT_GT(changed, 10000u);
    EXPECT_EQ(near_surface, 0u) << "closest changed voxel " << min_clear << " mm";
    std::printf("added structures change voxels >= %.2f mm outside the inner surface\n", min_clear);
    // Hence the same cavity volume below the iso, and the same crossing along +x.
    EXPECT_NEAR(cavity_ml(full, 0.0), cavity_ml(plain, 0.0), 1e-9);
}

TEST(PhantomSpine, CanalRingsAndConnection) {
    PhantomParams p = clean();
    p.spine = true;
    const auto r = generate_phantom(p);
    EXPECT_DOUBLE_EQ(r.spinal_canal_radius_mm, 8.0);
    // Middle of the first ring: canal content inside, bone in the wall, soft tissue beyond.
    const double zr = kRingTop - 7.5;
    EXPECT_EQ(at_phantom(r, {0, kFmY, zr}), 35);
    EXPECT_EQ(at_phantom(r, {0, kFmY - 10.5, zr}), 1300);  // posterior wall (radius 8..13)
    EXPECT_EQ(at_phantom(r, {-10.5, kFmY, zr}), 1300);     // lateral wall
    EXPECT_EQ(at_phantom(r, {0, kFmY - 20, zr}), 30);      // neck
    // The gap between rings 1 and 2: soft tissue in the wall's place, canal still content.
    const double zg = kRingTop - 15 - 2;
    EXPECT_EQ(at_phantom(r, {0, kFmY - 10.5, zg}), 30);
    EXPECT_EQ(at_phantom(r, {0, kFmY, zg}), 35);
    // Seventh ring and the lower border: the canal reaches it.
    EXPECT_EQ(at_phantom(r, {0, kFmY - 10.5, kRingTop - 6 * 19 - 7.5}), 1300);
    const Vec3 low = r.ct.geometry().world_to_index(world_of(r, {0, kFmY, 0}));
    EXPECT_EQ(r.ct(std::llround(low[0]), std::llround(low[1]), 0), 35);
    // The foramen magnum (radius 14) is wider than the canal (8): bone of the first ring lies
    // under the foramen's opening.
    EXPECT_GT(r.foramen_magnum_radius_mm, r.spinal_canal_radius_mm + 5);
    // Connected: the cavity centre, the foramen and the canal down to the lower border are one
    // component of content-valued voxels.
    const auto seen = flood(r.ct, r.cavity_centre_world, [](int16_t v) { return v == 35; });
    EXPECT_TRUE(seen[r.ct.index(std::llround(low[0]), std::llround(low[1]), 0)]);
    // The column is one bone component with the skull (articular pillars): the largest
    // component of the bone mask keeps the lowest ring.
    BinarizeParams bp;
    bp.isovalue = r.suggested_iso;
    bp.thin_bone_prominence = 0;  // the bone as rendered (thin-bone ridges make specks of their own)
    const auto b = binarize(to_float(r.ct), bp);
    const Vec3 ring = r.ct.geometry().world_to_index(world_of(r, {0, kFmY - 10.5, kRingTop - 6 * 19 - 7.5}));
    EXPECT_EQ(b.bone(std::llround(ring[0]), std::llround(ring[1]), std::llround(ring[2])), 1);
    EXPECT_EQ(b.removed_fragment_voxels, 0u);
    EXPECT_NE(r.description.find("spine"), std::string::npos);

    // Dry: air in the canal, no neck; macaque: a 3.5 mm canal.
    PhantomParams d = clean(PhantomPreset::Dry);
    d.spine = true;
    const auto rd = generate_phantom(d);
    EXPECT_EQ(at_phantom(rd, {0, kFmY, zr}), -1000);
    EXPECT_EQ(at_phantom(rd, {0, kFmY - 10.5, zr}), 1300);
    EXPECT_EQ(at_phantom(rd, {0, kFmY - 20, zr}), -1000);
    PhantomParams m = clean(PhantomPreset::Macaque);
    m.spine = true;
    const auto rm = generate_phantom(m);
    EXPECT_DOUBLE_EQ(rm.spinal_canal_radius_mm, 3.5);
    const Vec3 fm = rm.foramen_magnum_world;
    EXPECT_EQ(at_world(rm, along(fm, rm.foramen_magnum_axis, 20.0)), 35);
}

TEST(PhantomSinus, AirSeparatedFromTheCavityAndOpenToTheOutside) {
    PhantomParams p = clean();
    p.frontal_sinus = true;
    p.foramen_magnum = p.small_foramina = p.crack = false;  // only the sinus's passages are open
    const auto r = generate_phantom(p);
    // The sinus centre as phantom.cpp places it without blur: 3.5 mm + 6 mm out along the normal at the inner
    // surface point in direction (0, 1, -0.32).
    const Vec3 a = r.cavity_semi_axes_mm;
    const double dy = 1.0 / std::hypot(1.0, 0.32), dz = -0.32 / std::hypot(1.0, 0.32);
    const double kk = std::sqrt((dy / a[1]) * (dy / a[1]) + (dz / a[2]) * (dz / a[2]));
    const Vec3 ps{0, dy / kk, dz / kk};
    const double ny = ps[1] / (a[1] * a[1]), nz = ps[2] / (a[2] * a[2]), nn = std::hypot(ny, nz);
    const Vec3 n{0, ny / nn, nz / nn};
    EXPECT_EQ(at_phantom(r, along(ps, n, 9.5)), -1000);  // sinus centre
    EXPECT_EQ(at_phantom(r, along(ps, n, 1.75)), 1400);  // bone between sinus and braincase
    EXPECT_EQ(at_phantom(r, along(ps, n, -2.0)), 35);
    // Air all the way from the sinus to the outside (duct, nasal cavity, nostrils) ...
    const Vec3 sinus_w = world_of(r, along(ps, n, 9.5));
    const auto air = flood(r.ct, sinus_w, [](int16_t v) { return v < -500; });
    EXPECT_TRUE(touches_border(r.ct, air));
    EXPECT_TRUE(seen_at(r, air, world_of(r, {0, 78, -68})));  // nasal cavity
    // ... but separated from the braincase: the empty space reached from the sinus never gets
    // into the cavity.
    const auto empty = flood(r.ct, sinus_w, [&](int16_t v) { return v < r.suggested_iso; });
    EXPECT_FALSE(seen_at(r, empty, r.cavity_centre_world));
    // Bone everywhere within 3 mm outside the inner surface in front (the sinus keeps 3.5 mm).
    for (double t = 0.5; t <= 3.0; t += 0.5)
        for (double lat : {-8.0, 0.0, 8.0}) {
            const Vec3 q = along({lat, ps[1], ps[2]}, n, t);
            EXPECT_GE(at_phantom(r, q), r.suggested_iso) << t << " " << lat;
        }
    EXPECT_NE(r.description.find("frontal-sinus"), std::string::npos);
}

TEST(PhantomOrbits, ContentWallsAndOpenCanal) {
    PhantomParams p = clean();
    p.orbits = true;
    const auto r = generate_phantom(p);
    for (double side : {-1.0, 1.0}) {
        // Geometry of phantom.cpp: apex (17, 60, -47), opening (34, 104, -40), eye radius 12 at
        // 13 mm behind the opening.
        const Vec3 apex{17 * side, 60, -47}, base{34 * side, 104, -40};
        const Vec3 d{(base[0] - apex[0]) / 48.0, (base[1] - apex[1]) / 48.0, (base[2] - apex[2]) / 48.0};
        const double L = std::hypot(base[0] - apex[0], base[1] - apex[1], base[2] - apex[2]);
        const Vec3 dn{(base[0] - apex[0]) / L, (base[1] - apex[1]) / L, (base[2] - apex[2]) / L};
        (void)d;
        const Vec3 eye = along(base, dn, -13.0);
        EXPECT_EQ(at_phantom(r, eye), 10);                       // eyeball
        EXPECT_EQ(at_phantom(r, along(apex, dn, 20.0)), -80);    // fat behind the eye
        // Bone around the orbit: 5 mm outside the cone's wall, half-way along.
        const Vec3 mid = along(apex, dn, 0.5 * L);
        const double rad = 0.5 * 20.0 + 5.0;
        EXPECT_EQ(at_phantom(r, {mid[0], mid[1], mid[2] - rad}), 1400);
        // The canal: below the iso from the inner surface to the apex.
        const PhantomOpening* oc = find_opening(r, side < 0 ? "optic_canal_left" : "optic_canal_right");
        ASSERT_NE(oc, nullptr);
        for (double t = 0; t <= 4.0; t += 1.0)
            EXPECT_LT(at_world(r, along(oc->centre_world, oc->axis_world, t)), r.suggested_iso);
    }
    // The default canal stays open after the pipeline's void closing (6 voxels): the empty space
    // of the closed bone still joins the braincase to the orbit along the canal's axis.
    BinarizeParams bp;
    bp.isovalue = r.suggested_iso;
    const auto b = binarize(to_float(r.ct), bp);
    const auto filled = fill_voids(b.bone);
    for (const char* name : {"optic_canal_left", "optic_canal_right"}) {
        const PhantomOpening* oc = find_opening(r, name);
        for (double t = -2.0; t <= 10.0; t += 1.0) {
            const Vec3 idx = r.ct.geometry().world_to_index(along(oc->centre_world, oc->axis_world, t));
            EXPECT_EQ(filled.bone(std::llround(idx[0]), std::llround(idx[1]), std::llround(idx[2])), 0)
                << name << " t=" << t;
        }
    }
    // An anatomical 3 mm canal is sealed by that closing.
    p.optic_canal_radius_mm = 3.0;
    const auto r3 = generate_phantom(p);
    const auto b3 = binarize(to_float(r3.ct), bp);
    const auto f3 = fill_voids(b3.bone);
    const PhantomOpening* oc3 = find_opening(r3, "optic_canal_left");
    ASSERT_NE(oc3, nullptr);
    EXPECT_DOUBLE_EQ(oc3->radius_mm, 3.0);
    const Vec3 idx = r3.ct.geometry().world_to_index(along(oc3->centre_world, oc3->axis_world, 2.0));
    EXPECT_EQ(f3.bone(std::llround(idx[0]), std::llround(idx[1]), std::llround(idx[2])), 1);
    // Dry orbits are air.
    PhantomParams dp = clean(PhantomPreset::Dry);
    dp.orbits = true;
    const auto rd = generate_phantom(dp);
    EXPECT_EQ(at_phantom(rd, {17 + 17 * 20.0 / 48.1, 60 + 44 * 20.0 / 48.1, -47 + 7 * 20.0 / 48.1}), -1000);
}

TEST(PhantomCrop, CavityTouchesTheBorderAndTruthIsTheCap) {
    for (double tilt : {0.0, 20.0}) {
        PhantomParams p = clean();
        p.crop_base_mm = 15.0;
        p.tilt_deg = tilt;
        const auto r = generate_phantom(p);
        ASSERT_TRUE(r.cropped);
        const auto& g = r.ct.geometry();
        // The lower face of the volume: half a voxel below the first slice's centres.
        EXPECT_NEAR(r.crop_plane_z_mm, g.origin[2] - 0.5 * g.spacing[2], 1e-9);
        // The border slice holds cavity voxels (brain content) across the cut.
        size_t content = 0;
        for (int64_t j = 0; j < r.ct.ny(); ++j)
            for (int64_t i = 0; i < r.ct.nx(); ++i) content += r.ct(i, j, 0) == 35;
        EXPECT_GT(content, 1000u) << tilt;
        // Truth by numeric integration over horizontal sections: for each (x, z) the y range
        // inside the rotated ellipsoid is a quadratic's root interval.
        const Vec3 a = r.cavity_semi_axes_mm;
        const double c = std::cos(tilt * kPi / 180), s = std::sin(tilt * kPi / 180);
        const double zlo = r.crop_plane_z_mm - r.cavity_centre_world[2];
        const double zhi = std::sqrt(s * s * a[1] * a[1] + c * c * a[2] * a[2]);
        const int nzs = 3000, nxs = 3000;
        double vol = 0;
        for (int iz = 0; iz < nzs; ++iz) {
            const double z = zlo + (iz + 0.5) * (zhi - zlo) / nzs;
            double area = 0;
            for (int ix = 0; ix < nxs; ++ix) {
                const double x = -a[0] + (ix + 0.5) * 2 * a[0] / nxs;
                // q = (x, c y + s z, -s y + c z); quad(q) <= 1 -> A y^2 + B y + C <= 0.
                const double A = c * c / (a[1] * a[1]) + s * s / (a[2] * a[2]);
                const double B = 2 * z * c * s * (1 / (a[1] * a[1]) - 1 / (a[2] * a[2]));
                const double C = x * x / (a[0] * a[0]) + z * z * (s * s / (a[1] * a[1]) + c * c / (a[2] * a[2])) - 1;
                const double disc = B * B - 4 * A * C;
                if (disc > 0) area += std::sqrt(disc) / A * (2 * a[0] / nxs);
            }
            vol += area * (zhi - zlo) / nzs;
        }
        EXPECT_NEAR(r.true_ecv_ml / (vol / 1000.0), 1.0, 1e-4) << tilt;
        EXPECT_LT(r.true_ecv_ml, 4.0 / 3.0 * kPi * a[0] * a[1] * a[2] / 1000.0 - 10.0);
        EXPECT_LT(r.true_ecv_slice_centres_ml, r.true_ecv_ml);
        // The voxel count below the iso inside the ellipsoid agrees with the cut truth (the
        // half-voxel cells below the centres of the first slice are not in the volume).
        EXPECT_NEAR(cavity_ml(r, 2.0), r.true_ecv_slice_centres_ml, 0.01 * r.true_ecv_ml);
        // Signed distance: the flat cap and the rim.
        const Vec3 on_cap{r.cavity_centre_world[0], r.cavity_centre_world[1], r.crop_plane_z_mm};
        EXPECT_NEAR(phantom_cavity_signed_distance(r, on_cap), 0.0, 1e-9);
        EXPECT_NEAR(phantom_cavity_signed_distance(r, {on_cap[0], on_cap[1], on_cap[2] - 4}), 4.0, 1e-9);
        EXPECT_NEAR(phantom_cavity_signed_distance(r, {on_cap[0], on_cap[1], on_cap[2] + 3}), -3.0, 1e-9);
        // Below the plane and outside the rim: the distance to the rim, against a dense sampling
        // of the rim found by bisection with the ellipsoid's own equation.
        auto inside_e = [&](const Vec3& w) {
            const Vec3 v{w[0] - r.cavity_centre_world[0], w[1] - r.cavity_centre_world[1],
                         w[2] - r.cavity_centre_world[2]};
            const Vec3 q{v[0], c * v[1] + s * v[2], -s * v[1] + c * v[2]};
            return q[0] * q[0] / (a[0] * a[0]) + q[1] * q[1] / (a[1] * a[1]) + q[2] * q[2] / (a[2] * a[2]) < 1.0;
        };
        // Brute force over the boundary of the cut cavity: the ellipsoid above the plane (a
        // 0.25 degree grid), the rim, and the flat cap (when the foot of the query lies in it).
        std::vector<Vec3> boundary;
        for (int it = 0; it <= 720; ++it)
            for (int ip = 0; ip < 1440; ++ip) {
                const double th = it * kPi / 720, ph = ip * kPi / 720;
                const Vec3 q{a[0] * std::sin(th) * std::cos(ph), a[1] * std::sin(th) * std::sin(ph),
                             a[2] * std::cos(th)};
                const Vec3 w{r.cavity_centre_world[0] + q[0],
                             r.cavity_centre_world[1] + c * q[1] - s * q[2],
                             r.cavity_centre_world[2] + s * q[1] + c * q[2]};
                if (w[2] >= r.crop_plane_z_mm) boundary.push_back(w);
            }
        for (int ip = 0; ip < 7200; ++ip) {
            const double ph = ip * 2 * kPi / 7200;
            double lo = 0, hi = 200;
            for (int it = 0; it < 60; ++it) {
                const double m = 0.5 * (lo + hi);
                (inside_e({on_cap[0] + m * std::cos(ph), on_cap[1] + m * std::sin(ph), on_cap[2]}) ? lo : hi) = m;
            }
            boundary.push_back({on_cap[0] + lo * std::cos(ph), on_cap[1] + lo * std::sin(ph), on_cap[2]});
        }
        for (const Vec3& off : {Vec3{200, 0, -5}, Vec3{-30, 120, -2}, Vec3{70, -70, -10},
                                Vec3{10, 20, -7}, Vec3{0, 0, 40}, Vec3{60, 0, 1}}) {
            const Vec3 query{on_cap[0] + off[0], on_cap[1] + off[1], on_cap[2] + off[2]};
            double brute = 1e300;
            for (const Vec3& b : boundary)
                brute = std::min(brute, std::hypot(query[0] - b[0], query[1] - b[1], query[2] - b[2]));
            if (inside_e({query[0], query[1], on_cap[2]}))
                brute = std::min(brute, std::fabs(on_cap[2] - query[2]));
            const double sd = phantom_cavity_signed_distance(r, query);
            const bool in = inside_e(query) && query[2] >= r.crop_plane_z_mm;
            EXPECT_EQ(sd < 0, in) << tilt;
            EXPECT_LE(std::fabs(sd), brute + 1e-9) << tilt;
            EXPECT_NEAR(std::fabs(sd), brute, 0.02) << tilt << " " << off[0] << "," << off[1];
        }
    }
    PhantomParams bad = clean();
    bad.crop_base_mm = 130;
    EXPECT_THROW(generate_phantom(bad), InvalidParameter);
    bad.crop_base_mm = -1;
    EXPECT_THROW(generate_phantom(bad), InvalidParameter);
}

TEST(PhantomBody, CouchTouchesTheHeadAndTheDeepestEmptySpaceIsOutside) {
    PhantomParams p;
    p.body = true;
    p.spine = true;
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = generate_phantom(p);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("body phantom: %s in %.2f s\n", r.description.c_str(), secs);
    const auto& g = r.ct.geometry();
    EXPECT_LE(r.ct.size(), 40000000u);
    EXPECT_GE(double(g.dims[0] - 1) * g.spacing[0], 430.0 - 1e-9);
    EXPECT_GE(double(g.dims[1] - 1) * g.spacing[1], 320.0 - 1);
    // Couch > 300 HU touching the scalp behind the head: walk backwards from the cavity centre
    // through brain and bone, then the scalp (< 300 HU, no air), into the couch (> 300 HU).
    const Vec3 c = g.world_to_index(r.cavity_centre_world);
    const int64_t i = std::llround(c[0]), k = std::llround(c[2]);
    int64_t j = std::llround(c[1]);
    while (j > 0 && r.ct(i, j, k) < 1000) --j;   // brain
    while (j > 0 && r.ct(i, j, k) >= 300) --j;   // bone
    int64_t scalp = 0, air = 0;
    while (j > 0 && r.ct(i, j, k) <= 300) {     // scalp
        ++scalp;
        air += r.ct(i, j, k) < -200;
        --j;
    }
    EXPECT_GT(scalp, 2);
    EXPECT_LE(scalp, 6);
    EXPECT_EQ(air, 0) << "air gap between scalp and couch";
    EXPECT_GT(r.ct(i, j, k), 300);       // the couch's skin, touching the scalp voxel at j + 1
    EXPECT_LT(r.ct(i, j + 1, k), 300);
    // Shoulders: body soft tissue and a clavicle.
    const Vec3 rel_sh{r.cavity_centre_world[0] + 150, r.cavity_centre_world[1] + 0, r.cavity_centre_world[2] - 190};
    EXPECT_NEAR(at_world(r, rel_sh), 40, 80);
    // The failure this phantom reproduces: after the void closing, the deepest empty voxel (the
    // maximum of the distance to bone) is outside the braincase, and so is the paper's automatic
    // endocast seed (deepest voxel outside the border balls).
    Volume<uint8_t> bone(g);
    for (size_t n = 0; n < r.ct.size(); ++n) bone[n] = r.ct[n] >= r.suggested_iso;
    const auto filled = fill_voids(bone);
    const auto dist = distance_transform(filled.bone);
    size_t best = 0;
    for (size_t n = 0; n < dist.size(); ++n)
        if (dist[n] > dist[best]) best = n;
    const int64_t bi = int64_t(best % dist.nx()), bj = int64_t((best / dist.nx()) % dist.ny()),
                  bk = int64_t(best / (dist.nx() * dist.ny()));
    const Vec3 w = g.index_to_world(double(bi), double(bj), double(bk));
    const double braincase_depth = dist(i, std::llround(c[1]), k);
    EXPECT_NEAR(braincase_depth, 60.0, 1.0);
    EXPECT_GT(dist[best], braincase_depth + 20.0);
    EXPECT_GT(phantom_cavity_signed_distance(r, w), 20.0);
    SeedParams largest;
    largest.mode = SeedMode::AutoLargest;  // the paper's rule
    const SeedResult seeds = place_seeds(filled.bone, dist, largest);
    ASSERT_FALSE(seeds.endocast_seeds_world.empty());
    const Vec3 e = seeds.endocast_seeds_world[0];
    std::printf("body phantom: distance maximum %.1f mm at world (%.0f, %.0f, %.0f); braincase depth "
                "%.1f mm; automatic endocast seed (d = %.1f mm) at %.1f mm outside the braincase, "
                "relative to its centre (%.0f, %.0f, %.0f)\n",
                dist[best], w[0], w[1], w[2], braincase_depth, seeds.endocast_seed_distance_mm,
                phantom_cavity_signed_distance(r, e), e[0] - r.cavity_centre_world[0],
                e[1] - r.cavity_centre_world[1], e[2] - r.cavity_centre_world[2]);
    EXPECT_GT(phantom_cavity_signed_distance(r, e), 10.0);
    EXPECT_GT(seeds.endocast_seed_distance_mm, braincase_depth);
    // The default rule (SeedMode::Auto) chooses the braincase by its enclosure.
    const SeedResult chosen = place_seeds(filled.bone, dist);
    ASSERT_FALSE(chosen.endocast_seeds_world.empty());
    EXPECT_LT(phantom_cavity_signed_distance(r, chosen.endocast_seeds_world[0]), -30.0);
}

TEST(PhantomBody, RejectsDryAndScalpless) {
    PhantomParams p = clean(PhantomPreset::Dry);
    p.body = true;
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = clean();
    p.body = true;
    p.scalp = false;
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
    p = clean();
    p.optic_canal_radius_mm = -1;
    EXPECT_THROW(generate_phantom(p), InvalidParameter);
}

TEST(PhantomFull, DeterministicForAnyThreadCountAndQuick) {
    PhantomParams p = human_full_phantom_params();
    p.tilt_deg = 30;
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const auto a = generate_phantom(p);
    omp_set_num_threads(2);
    const auto t0 = std::chrono::steady_clock::now();
    const auto b = generate_phantom(p);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    omp_set_num_threads(saved);
    EXPECT_EQ(a.ct.buffer(), b.ct.buffer());
    std::printf("human-full phantom: %s in %.2f s\n", b.description.c_str(), secs);
    EXPECT_TRUE(p.spine && p.frontal_sinus && p.orbits && !p.body);
    // The truth is unchanged by the features.
    EXPECT_DOUBLE_EQ(b.true_ecv_ml, generate_phantom(clean()).true_ecv_ml);
    // Macaque with everything, for the record.
    PhantomParams m = human_full_phantom_params();
    m.preset = PhantomPreset::Macaque;
    const auto rm = generate_phantom(m);
    EXPECT_EQ(rm.openings.size(), 9u);
    EXPECT_DOUBLE_EQ(rm.optic_canal_radius_mm, 3.5);
}

namespace {

/// generate_phantom_slabs(p, slab_voxels) gathered into one volume, with the slabs' checks.
Volume<int16_t> gathered(const PhantomParams& p, int64_t slab_voxels, PhantomResult* res, int* calls) {
    Volume<int16_t> whole_ct;
    int64_t next = 0;
    *res = generate_phantom_slabs(p, slab_voxels, [&](const Geometry& whole, int64_t z0, const Volume<int16_t>& slab) {
        if (z0 == 0) whole_ct = Volume<int16_t>(whole);
        EXPECT_EQ(z0, next);
        EXPECT_EQ(slab.nx(), whole.dims[0]);
        EXPECT_EQ(slab.ny(), whole.dims[1]);
        EXPECT_LE(int64_t(slab.size()), std::max<int64_t>(slab_voxels, whole.dims[0] * whole.dims[1]));
        // The slab's geometry is the whole grid's, from slice z0.
        const Vec3 a = slab.geometry().index_to_world(0, 0, 0), b = whole.index_to_world(0, 0, double(z0));
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[size_t(c)], b[size_t(c)], 1e-9);
        std::copy(slab.data(), slab.data() + slab.size(), whole_ct.data() + size_t(z0 * whole.dims[0] * whole.dims[1]));
        next = z0 + slab.nz();
        ++*calls;
    });
    EXPECT_EQ(next, res->geometry.dims[2]);
    return whole_ct;
}

}  // namespace

TEST(PhantomSlabs, SameVoxelsAndTruthAsTheWholeVolume) {
    // Ellipsoid phantoms (with and without tilt and spine) and the skull-base phantom, in slabs of
    // one slice, a few slices and more than the whole grid.
    std::vector<PhantomParams> cases;
    PhantomParams mac;
    mac.preset = PhantomPreset::Macaque;
    cases.push_back(mac);
    PhantomParams dry;
    dry.preset = PhantomPreset::Dry;
    dry.tilt_deg = 20;
    dry.spine = true;
    cases.push_back(dry);
    PhantomParams sb;
    sb.preset = PhantomPreset::Macaque;
    sb.skull_base = true;
    cases.push_back(sb);
    for (const PhantomParams& p : cases) {
        const PhantomResult whole = generate_phantom(p);
        const int64_t slice = whole.ct.nx() * whole.ct.ny();
        for (const int64_t slab_voxels : {int64_t{1}, 7 * slice + 3, int64_t(whole.ct.size()) * 2}) {
            PhantomResult r;
            int calls = 0;
            const Volume<int16_t> ct = gathered(p, slab_voxels, &r, &calls);
            SCOPED_TRACE(to_string(p.preset) + (p.skull_base ? " skull base" : "") + ", slabs of " +
                         std::to_string(slab_voxels) + " voxels");
            EXPECT_TRUE(r.ct.empty());
            EXPECT_EQ(r.geometry.dims, whole.ct.dims());
            EXPECT_EQ(ct.buffer(), whole.ct.buffer());
            EXPECT_EQ(r.true_ecv_ml, whole.true_ecv_ml);
            EXPECT_EQ(r.description, whole.description);
            const int64_t per = std::max<int64_t>(1, slab_voxels / slice);
            EXPECT_EQ(calls, int((whole.ct.nz() + per - 1) / per));
        }
    }
}

TEST(PhantomSlabs, RejectsBadArgumentsAndStopsOnTheSinksError) {
    PhantomParams p;
    p.preset = PhantomPreset::Macaque;
    const PhantomSlabSink none;
    EXPECT_THROW(generate_phantom_slabs(p, 1 << 20, none), InvalidParameter);
    EXPECT_THROW(generate_phantom_slabs(p, 0, [](const Geometry&, int64_t, const Volume<int16_t>&) {}),
                 InvalidParameter);
    int calls = 0;
    EXPECT_THROW(generate_phantom_slabs(p, 1, [&](const Geometry&, int64_t, const Volume<int16_t>&) {
                     if (++calls == 3) throw IoError("disk full");
                 }),
                 IoError);
    EXPECT_EQ(calls, 3);
    // Too many voxels for one volume, but fine in slabs (the check runs before any rendering).
    PhantomParams big = p;
    big.size = {4096, 4096, 256};
    EXPECT_THROW(generate_phantom(big), InvalidParameter);
    big.size = {int64_t{1} << 14, int64_t{1} << 14, int64_t{1} << 13};  // 2^41 voxels
    EXPECT_THROW(generate_phantom_slabs(big, 1 << 26, [](const Geometry&, int64_t, const Volume<int16_t>&) {}),
                 InvalidParameter);
}
