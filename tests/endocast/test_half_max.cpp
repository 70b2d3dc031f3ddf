// The half-maximum-height surface (PolygonizeParams::surface = SurfaceMode::HalfMax).
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>

#include "endocast/errors.h"
#include "endocast/stages/polygonize.h"
#include "meshpost/measure.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;
using endocast::testing::grid;

namespace {

constexpr double kPi = 3.14159265358979323846;

// A braincase of radius 15 voxels (CT 0) in a bone shell out to 22 (1000), soft tissue (0) beyond,
// blurred (edge width ~1.2 voxels), plus Gaussian noise of `noise` HU.
Volume<float> blurred_shell(double noise, uint32_t seed) {
    const auto g = grid(56, 56, 56);
    Volume<float> ct(g);
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, noise);
    auto step = [](double d) { return 0.5 * (1 + std::erf(d / 1.2)); };
    for (int64_t z = 0; z < 56; ++z)
        for (int64_t y = 0; y < 56; ++y)
            for (int64_t x = 0; x < 56; ++x) {
                const double r = std::sqrt((x - 27.5) * (x - 27.5) + (y - 27.5) * (y - 27.5) + (z - 27.5) * (z - 27.5));
                ct(x, y, z) = float(1000 * (step(r - 15) - step(r - 22)) + (noise > 0 ? n(rng) : 0.0));
            }
    return ct;
}

// The segmentation at T: the cavity inside the shell, bone, "other" outside it.
Volume<uint8_t> labels_at(const Volume<float>& ct, double T) {
    Volume<uint8_t> l(ct.geometry());
    for (int64_t z = 0; z < 56; ++z)
        for (int64_t y = 0; y < 56; ++y)
            for (int64_t x = 0; x < 56; ++x) {
                const double r = std::sqrt((x - 27.5) * (x - 27.5) + (y - 27.5) * (y - 27.5) + (z - 27.5) * (z - 27.5));
                l(x, y, z) = ct(x, y, z) >= T ? kBone : r < 18.5 ? kEndocast : kOther;
            }
    return l;
}

PolygonizeResult run(const Volume<float>& ct, double T, SurfaceMode m) {
    PolygonizeParams p;
    p.isovalue = T;
    p.surface = m;
    return polygonize(ct, labels_at(ct, T), p);
}

}  // namespace

TEST(HalfMax, SurfaceModeNames) {
    EXPECT_EQ(PolygonizeParams{}.surface, SurfaceMode::Iso);  // the default is the paper's method
    EXPECT_STREQ(to_string(SurfaceMode::HalfMax), "half-max");
    EXPECT_STREQ(to_string(SurfaceMode::Iso), "iso");
}

TEST(HalfMax, BlurredEdgeGivesTheSameSurfaceForAnyIsovalue) {
    // The isosurface moves across the blurred edge with T; the half-maximum one stays at the edge
    // (CT 500 = half-way between the cavity, 0, and the bone, 1000: radius 15).
    const auto ct = blurred_shell(0, 1);
    const double true_volume = 4.0 / 3.0 * kPi * 15 * 15 * 15;
    const double iso_lo = meshpost::signed_volume_mm3(run(ct, 200, SurfaceMode::Iso).mesh);
    const double iso_hi = meshpost::signed_volume_mm3(run(ct, 800, SurfaceMode::Iso).mesh);
    EXPECT_GT(iso_hi / iso_lo, 1.15);  // what half-max is for
    double volumes[3];
    int k = 0;
    for (const double T : {200.0, 500.0, 800.0}) {
        const PolygonizeResult r = run(ct, T, SurfaceMode::HalfMax);
        SCOPED_TRACE("T " + std::to_string(T));
        expect_clean_genus0(r.mesh);
        volumes[k++] = meshpost::signed_volume_mm3(r.mesh);
        EXPECT_NEAR(volumes[k - 1] / true_volume, 1.0, 0.01);
        EXPECT_NEAR(r.half_max.cavity_level, 0.0, 1.0);
        EXPECT_NEAR(r.half_max.threshold_median, 500.0, 10.0);
        EXPECT_GT(r.half_max.band_voxels, 0u);
        EXPECT_EQ(r.half_max.fallback_voxels, 0u);
        EXPECT_NEAR(r.other_value, 1000.0, 20.0);  // median tau + (median tau - c)
        size_t n = 0;
        for (size_t i = 0; i < r.mask.size(); ++i) n += r.mask[i];
        EXPECT_EQ(n, r.mask_voxels);
        if (T < 500) EXPECT_GT(r.half_max.voxels_added, 0u);
        if (T > 500) EXPECT_GT(r.half_max.voxels_removed, 0u);
    }
    EXPECT_NEAR(volumes[0] / volumes[1], 1.0, 0.002);
    EXPECT_NEAR(volumes[2] / volumes[1], 1.0, 0.002);
}

TEST(HalfMax, NeverEntersOtherAndClosesAgainstIt) {
    // As PolygonizeClosesTheEndocastAgainstOtherLabels: the lower half of the cavity is "other".
    Volume<float> ct;
    Volume<uint8_t> labels;
    endocast::testing::half_other_cavity(ct, labels);
    PolygonizeParams p;
    p.isovalue = 0;
    p.surface = SurfaceMode::HalfMax;
    const auto r = polygonize(ct, labels, p);
    expect_clean_genus0(r.mesh);
    for (size_t i = 0; i < labels.size(); ++i)
        if (r.mask[i]) EXPECT_EQ(labels[i], kEndocast) << i;
    EXPECT_EQ(r.mask_voxels, 20u * 20u * 10u);
    const auto bb = meshpost::bounding_box(r.mesh);
    EXPECT_NEAR(bb.min[2], 14.5, 0.01);  // midway between the last endocast and the first other voxel
    EXPECT_NEAR(bb.max[2], 24.5, 0.01);  // CT 0 = half-way between -1000 and 1000
    EXPECT_NEAR(meshpost::signed_volume_mm3(r.mesh), 20.0 * 20.0 * 10.0, 20.0 * 20 * 10 * 0.03);
}

TEST(HalfMax, IdenticalForOneAndTwoThreads) {
    const auto ct = blurred_shell(40, 7);
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const PolygonizeResult a = run(ct, 300, SurfaceMode::HalfMax);
    omp_set_num_threads(2);
    const PolygonizeResult b = run(ct, 300, SurfaceMode::HalfMax);
    omp_set_num_threads(threads);
    EXPECT_EQ(a.mesh.vertices, b.mesh.vertices);
    EXPECT_EQ(a.mesh.faces, b.mesh.faces);
    EXPECT_EQ(a.mask.buffer(), b.mask.buffer());
    EXPECT_EQ(a.half_max.threshold_median, b.half_max.threshold_median);
    EXPECT_EQ(a.half_max.voxels_added, b.half_max.voxels_added);
    expect_clean_genus0(a.mesh);
}

TEST(HalfMax, RejectsABadBand) {
    const auto ct = blurred_shell(0, 1);
    PolygonizeParams p;
    p.isovalue = 500;
    p.surface = SurfaceMode::HalfMax;
    p.band_voxels = 0;
    EXPECT_THROW(polygonize(ct, labels_at(ct, 500), p), InvalidParameter);
}
