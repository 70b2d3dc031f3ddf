#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "endocast/marching_cubes.h"
#include "endocast/polygonize.h"
#include "meshpost/measure.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;

namespace {

Volume<float> sphere_field(const Geometry& g, const Vec3& c_index) {
    Volume<float> f(g);
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                const double dx = (x - c_index[0]) * g.spacing[0], dy = (y - c_index[1]) * g.spacing[1],
                             dz = (z - c_index[2]) * g.spacing[2];
                f(x, y, z) = float(std::sqrt(dx * dx + dy * dy + dz * dz));
            }
    return f;
}

void expect_clean(const meshpost::TriangleMesh& m) {
    const auto t = meshpost::analyze_topology(m);
    EXPECT_TRUE(t.closed);
    EXPECT_TRUE(t.manifold);
    EXPECT_TRUE(t.oriented);
    EXPECT_EQ(t.degenerate_faces, 0u);
    EXPECT_EQ(meshpost::find_self_intersections(m).intersecting_pairs, 0u);
    meshpost::SelfIntersectionOptions reference;  // CGAL's box intersection agrees
    reference.method = meshpost::SelfIntersectionMethod::CgalReference;
    EXPECT_EQ(meshpost::find_self_intersections(m, reference).intersecting_pairs, 0u);
}

}  // namespace

TEST(MarchingCubes, SphereOfRadius20IsClosedGenus0WithAccurateVolume) {
    const auto f = sphere_field(grid(48, 48, 48), {23.3, 24.1, 23.7});
    const auto m = isosurface(f, 20.0);
    expect_clean(m);
    const auto t = meshpost::analyze_topology(m);
    EXPECT_EQ(t.components, 1u);
    EXPECT_EQ(t.genus, 0);
    const double exact = 4.0 / 3.0 * M_PI * 20 * 20 * 20;
    const double vol = meshpost::signed_volume_mm3(m);
    EXPECT_GT(vol, 0);  // outward
    EXPECT_NEAR(vol / exact, 1.0, 0.005);
}

TEST(MarchingCubes, WorldCoordinatesFollowOriginSpacingAndDirection) {
    auto g = grid(40, 40, 20, {0.5, 0.5, 1.0});
    g.origin = {-100, 50, 20};
    g.direction = {1, 0, 0, 0, -1, 0, 0, 0, 1};  // left-handed: y flipped
    const auto f = sphere_field(g, {20, 20, 10});
    const auto m = isosurface(f, 6.0);
    expect_clean(m);
    EXPECT_GT(meshpost::signed_volume_mm3(m), 0);  // still outward with a flipped axis
    const auto c = meshpost::volume_centroid(m);
    const Vec3 w = g.index_to_world(20, 20, 10);  // (-90, 40, 30)
    EXPECT_NEAR(c[0], w[0], 0.05);
    EXPECT_NEAR(c[1], w[1], 0.05);
    EXPECT_NEAR(c[2], w[2], 0.05);
    EXPECT_NEAR(meshpost::signed_volume_mm3(m) / (4.0 / 3.0 * M_PI * 216), 1.0, 0.02);
}

TEST(MarchingCubes, RandomFieldsAlwaysGiveClosedManifoldsWithoutSelfIntersections) {
    // Noise with many samples exactly at the isovalue: the hardest case for degeneracy.
    for (uint32_t seed = 1; seed <= 8; ++seed) {
        std::mt19937 rng(seed);
        Volume<float> f(grid(9, 8, 7, {1.0, 1.3, 0.7}));
        for (size_t i = 0; i < f.size(); ++i) f[i] = float(int(rng() % 5) - 2);  // -2..2, iso 0
        const auto m = isosurface(f, 0.0);
        ASSERT_GT(m.faces.size(), 0u);
        expect_clean(m);
        EXPECT_GT(meshpost::signed_volume_mm3(m), 0);
    }
}

TEST(MarchingCubes, PolygonizeClosesTheEndocastAgainstOtherLabels) {
    // A cavity of air (-1000) in bone (1000) whose lower half is labelled "other": the mesh must
    // close midway between the two labels, and stay clean.
    Volume<float> ct;
    Volume<uint8_t> labels;
    endocast::testing::half_other_cavity(ct, labels);
    const Geometry& g = ct.geometry();
    PolygonizeParams p;
    p.isovalue = 0;
    const auto r = polygonize(ct, labels, p);
    expect_clean(r.mesh);
    EXPECT_EQ(r.mask_voxels, 20u * 20u * 10u);
    EXPECT_DOUBLE_EQ(r.other_value, 1000.0);  // T + (T - median) = 0 + 1000
    // Box from 4.5 to 24.5 in x,y (bone crossing midway), z from 14.5 (other, midway) to 24.5.
    EXPECT_NEAR(meshpost::signed_volume_mm3(r.mesh), 20.0 * 20.0 * 10.0, 20.0 * 20 * 10 * 0.03);
    const auto bb = meshpost::bounding_box(r.mesh);
    EXPECT_NEAR(bb.min[2], 14.5, 0.01);
    EXPECT_NEAR(bb.max[2], 24.5, 0.01);
    EXPECT_THROW(polygonize(ct, Volume<uint8_t>(g, kBone), p), NoResult);
}
