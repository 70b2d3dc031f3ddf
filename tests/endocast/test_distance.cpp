#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <omp.h>

#include "endocast/stages/distance.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;
using endocast::testing::random_mask;

namespace {

// Brute force: min over all feature voxels of the squared world distance.
double brute_sq(const Volume<uint8_t>& m, int64_t x, int64_t y, int64_t z) {
    const auto& s = m.geometry().spacing;
    double best = std::numeric_limits<double>::infinity();
    for (int64_t c = 0; c < m.nz(); ++c)
        for (int64_t b = 0; b < m.ny(); ++b)
            for (int64_t a = 0; a < m.nx(); ++a) {
                if (!m(a, b, c)) continue;
                const double dx = (a - x) * s[0], dy = (b - y) * s[1], dz = (c - z) * s[2];
                best = std::min(best, dx * dx + dy * dy + dz * dz);
            }
    return best;
}

}  // namespace

TEST(Distance, MatchesBruteForceOnRandomAnisotropicVolumes) {
    const Vec3 spacings[] = {{1, 1, 1}, {1, 1, 2}, {0.5, 0.7, 1.3}, {2.0, 0.3, 0.9}};
    const double densities[] = {0.01, 0.1, 0.5};
    uint32_t seed = 1;
    for (const auto& sp : spacings)
        for (double dens : densities) {
            const auto g = grid(13, 9, 11, sp);
            const auto m = random_mask(g, dens, seed++);
            const auto d2 = squared_distance_transform(m);
            for (int64_t z = 0; z < m.nz(); ++z)
                for (int64_t y = 0; y < m.ny(); ++y)
                    for (int64_t x = 0; x < m.nx(); ++x) {
                        const double ref = brute_sq(m, x, y, z);
                        ASSERT_NEAR(d2(x, y, z), ref, 1e-5 * std::max(1.0, ref))
                            << "at " << x << "," << y << "," << z << " spacing " << sp[0];
                    }
        }
}

TEST(Distance, SingleFeatureGivesEuclideanDistanceInMm) {
    auto g = grid(20, 20, 20, {0.5, 1.0, 2.0});
    Volume<uint8_t> m(g);
    m(3, 4, 5) = 1;
    const auto d = distance_transform(m);
    EXPECT_FLOAT_EQ(d(3, 4, 5), 0.0f);
    EXPECT_NEAR(d(13, 4, 5), 5.0, 1e-5);               // 10 voxels x 0.5 mm
    EXPECT_NEAR(d(3, 4, 9), 8.0, 1e-5);                // 4 voxels x 2 mm
    EXPECT_NEAR(d(7, 7, 5), std::sqrt(4.0 + 9.0), 1e-5);  // (2 mm, 3 mm)
}

TEST(Distance, NoFeatureIsInfinite) {
    Volume<uint8_t> m(grid(5, 4, 3));
    const auto d = distance_transform(m);
    for (size_t i = 0; i < d.size(); ++i) EXPECT_TRUE(std::isinf(d[i]));
}

TEST(Distance, GeneralizedTransformIsUnionOfBalls) {
    // f0 = -r^2 at a few centres: f <= 0 exactly inside the union of the balls.
    auto g = grid(24, 20, 16, {1.0, 0.8, 1.5});
    std::vector<float> f(g.voxel_count(), std::numeric_limits<float>::infinity());
    struct Ball { int64_t x, y, z; double r; };
    const Ball balls[] = {{5, 5, 5, 4.0}, {18, 12, 8, 6.5}, {10, 15, 3, 2.2}};
    const int64_t nx = g.dims[0], ny = g.dims[1];
    for (const auto& b : balls) f[size_t(b.x + nx * (b.y + ny * b.z))] = float(-b.r * b.r);
    generalized_squared_distance(f, g);
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                double best = std::numeric_limits<double>::infinity();
                for (const auto& b : balls) {
                    const double dx = (x - b.x) * g.spacing[0], dy = (y - b.y) * g.spacing[1],
                                 dz = (z - b.z) * g.spacing[2];
                    best = std::min(best, dx * dx + dy * dy + dz * dz - b.r * b.r);
                }
                ASSERT_NEAR(f[size_t(x + nx * (y + ny * z))], best, 1e-4 * std::max(1.0, std::fabs(best)));
            }
}

TEST(Distance, SameResultForOneAndTwoThreads) {
    const auto m = random_mask(grid(40, 33, 27, {0.9, 0.9, 1.7}), 0.02, 7);
    omp_set_num_threads(1);
    const auto a = squared_distance_transform(m);
    omp_set_num_threads(2);
    const auto b = squared_distance_transform(m);
    EXPECT_EQ(a.buffer(), b.buffer());
}

// The binary transforms (the x pass as table copies between features, lines of only 0 or +inf
// skipped) give bit for bit the textbook envelope, which the generalized transform runs on the same
// 0 / +inf samples, on masks with solid blocks of features (bone, a dilation's centres) and
// isolated ones.
TEST(Distance, ZeroRunsGiveTheTextbookEnvelopeBitForBit) {
    const Vec3 spacings[] = {{1, 1, 1}, {0.45, 0.45, 0.8}, {0.7, 1.3, 0.5}};
    uint32_t seed = 11;
    for (const auto& sp : spacings) {
        const auto g = grid(37, 29, 23, sp);
        auto m = random_mask(g, 0.003, seed++);
        std::mt19937 rng(seed++);
        for (int b = 0; b < 6; ++b) {  // solid blocks: runs of zeros along every axis
            const int64_t x0 = int64_t(rng() % 30), y0 = int64_t(rng() % 22), z0 = int64_t(rng() % 16);
            const int64_t ex = 1 + int64_t(rng() % 7), ey = 1 + int64_t(rng() % 7), ez = 1 + int64_t(rng() % 7);
            for (int64_t z = z0; z < z0 + ez; ++z)
                for (int64_t y = y0; y < y0 + ey; ++y)
                    for (int64_t x = x0; x < x0 + ex; ++x) m(x, y, z) = 1;
        }
        std::vector<float> f(m.size());
        for (size_t i = 0; i < m.size(); ++i) f[i] = m[i] ? 0.0f : std::numeric_limits<float>::infinity();
        generalized_squared_distance(f, g);
        const auto d2 = squared_distance_transform(m);
        for (size_t i = 0; i < m.size(); ++i) ASSERT_EQ(d2[i], f[i]) << "voxel " << i << " spacing " << sp[0];
    }
}

