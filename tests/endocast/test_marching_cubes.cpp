#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "endocast/stages/marching_cubes.h"
#include "endocast/stages/polygonize.h"
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

namespace {

// Planes [z0, z1) of f as a volume of their own (the geometry's origin is not used by the stream).
Volume<float> planes_of(const Volume<float>& f, int64_t z0, int64_t z1) {
    Geometry g = f.geometry();
    g.dims[2] = z1 - z0;
    Volume<float> p(g);
    std::copy(&f(0, 0, z0), &f(0, 0, z0) + p.size(), p.data());
    return p;
}

}  // namespace

TEST(MarchingCubes, StreamedSlabsGiveTheWholeFieldsMeshExactly) {
    // Several spheres (some cut by the border) on an anisotropic, rotated, left-handed grid, fed in
    // slabs of 1, 3 and 7 layers, each with a few extra planes around it: the same vertices (bit for
    // bit) and faces as isosurface() on the whole field.
    auto g = grid(30, 26, 23, {0.7, 0.5, 1.1});
    g.origin = {-10, 5, 20};
    g.direction = {0, 1, 0, 1, 0, 0, 0, 0, 1};
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> noise(-0.3f, 0.3f);
    Volume<float> f(g);
    const double c[3][3] = {{8, 9, 4}, {20, 15, 12}, {29, 3, 22}};
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                double best = 1e9;
                for (const auto& q : c)
                    best = std::min(best, std::hypot((x - q[0]) * 0.7, (y - q[1]) * 0.5, (z - q[2]) * 1.1));
                f(x, y, z) = float(best) + noise(rng);
            }
    const auto whole = isosurface(f, 4.0);
    ASSERT_GT(whole.faces.size(), 1000u);
    for (int64_t step : {1, 3, 7}) {
        IsosurfaceStream s(g, 4.0);
        const int64_t nz = g.dims[2];
        while (s.next_layer() < nz) {
            const int64_t first = s.next_layer(), end = std::min(nz, first + step);
            const int64_t z0 = std::max<int64_t>(0, first - 2), z1 = std::min(nz, end + 3);
            s.add(planes_of(f, z0, z1), z0, end);
        }
        const auto m = s.finish();
        ASSERT_EQ(m.vertices.size(), whole.vertices.size()) << step;
        ASSERT_EQ(m.faces.size(), whole.faces.size()) << step;
        EXPECT_TRUE(m.vertices == whole.vertices) << step;
        EXPECT_TRUE(m.faces == whole.faces) << step;
    }
}

TEST(MarchingCubes, StreamRefusesMissingPlanesAndUnfinishedLayers) {
    const auto f = sphere_field(grid(12, 12, 12), {6, 6, 6});
    IsosurfaceStream s(f.geometry(), 4.0);
    EXPECT_THROW(s.add(planes_of(f, 1, 6), 1, 4), InvalidParameter);  // layer -1..0 need plane 0
    s.add(planes_of(f, 0, 6), 0, 4);
    EXPECT_THROW(s.add(planes_of(f, 6, 12), 6, 12), InvalidParameter);  // layer 4 needs plane 4
    EXPECT_THROW(s.finish(), InvalidParameter);
    s.add(planes_of(f, 4, 12), 4, 12);
    EXPECT_EQ(s.finish().faces.size(), isosurface(f, 4.0).faces.size());
}
