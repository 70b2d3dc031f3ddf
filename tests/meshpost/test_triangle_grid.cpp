#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "meshpost/triangle_grid.h"
#include "test_meshes.h"

using namespace meshpost;

namespace {

double brute_force_sq_dist(const TriangleMesh& m, const Point& p) {
    double best = HUGE_VAL;
    for (const Face& f : m.faces)
        best = std::min(best, sq_dist_point_triangle(p.data(), m.vertices[f[0]].data(), m.vertices[f[1]].data(),
                                                     m.vertices[f[2]].data()));
    return best;
}

}  // namespace

TEST(TriangleGrid, PointTriangleDistanceInEveryRegion) {
    const Point a{0, 0, 0}, b{2, 0, 0}, c{0, 2, 0};
    auto d2 = [&](Point p) { return sq_dist_point_triangle(p.data(), a.data(), b.data(), c.data()); };
    EXPECT_DOUBLE_EQ(d2({0.5, 0.5, 3}), 9.0);     // above the face
    EXPECT_DOUBLE_EQ(d2({-1, -1, 0}), 2.0);       // corner a
    EXPECT_DOUBLE_EQ(d2({3, -1, 0}), 2.0);        // corner b
    EXPECT_DOUBLE_EQ(d2({1, -2, 1}), 5.0);        // edge ab
    EXPECT_DOUBLE_EQ(d2({2, 2, 0}), 2.0);         // edge bc
    EXPECT_DOUBLE_EQ(d2({-3, 1, 4}), 25.0);       // edge ca
}

TEST(TriangleGrid, NearestIsExactAgainstBruteForceNearAndFar) {
    const TriangleMesh m = test::merged(test::icosphere(10.0, 3), test::torus(30.0, 5.0, 32, 16, {5, 0, 0}));
    const TriangleGrid grid(m, 2.0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-60.0, 60.0);
    int settled = 0, open = 0;
    uint32_t hint = UINT32_MAX;
    for (int i = 0; i < 2000; ++i) {
        const Point p{u(rng), u(rng), 0.3 * u(rng)};
        double d2 = 0;
        uint32_t tri = (i % 2) ? hint : UINT32_MAX;  // with and without a hint
        if (grid.nearest(p.data(), 1000, d2, tri)) {
            ++settled;
            EXPECT_EQ(d2, brute_force_sq_dist(m, p)) << "point " << i;
            ASSERT_LT(tri, m.faces.size());
            hint = tri;
        }
        double d2_few = 0;
        uint32_t t2 = UINT32_MAX;
        if (!grid.nearest(p.data(), 1, d2_few, t2)) {
            ++open;
            EXPECT_GE(d2_few, d2);  // the best found so far is an upper bound
        }
    }
    EXPECT_EQ(settled, 2000);
    EXPECT_GT(open, 100);  // far points are left open by one ring
}
