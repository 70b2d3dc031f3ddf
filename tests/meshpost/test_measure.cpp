#include <gtest/gtest.h>

#include <cmath>

#include "meshpost/measure.h"
#include "test_meshes.h"

using namespace meshpost;
using namespace meshpost::test;

namespace {
const double kPi = std::acos(-1.0);
}

TEST(Measure, CubeExact) {
    const TriangleMesh m = cube(2.0);
    EXPECT_EQ(signed_volume_mm3(m), 8.0);
    EXPECT_EQ(surface_area_mm2(m), 24.0);
    const BoundingBox b = bounding_box(m);
    EXPECT_EQ(b.min, (Point{0, 0, 0}));
    EXPECT_EQ(b.max, (Point{2, 2, 2}));
    EXPECT_EQ(volume_centroid(m), (Point{1, 1, 1}));
}

TEST(Measure, FarFromOriginCubeStaysExact) {
    // The bounding-box centre reference point removes the cancellation of large coordinates.
    const TriangleMesh m = cube(0.5, {1e6, -2e6, 3e6});
    EXPECT_EQ(signed_volume_mm3(m), 0.125);
    EXPECT_EQ(surface_area_mm2(m), 1.5);
    const Point c = volume_centroid(m);
    EXPECT_EQ(c, (Point{1e6 + 0.25, -2e6 + 0.25, 3e6 + 0.25}));
}

TEST(Measure, IcosphereApproachesSphere) {
    const double r = 10.0;
    const double sphere_v = 4.0 / 3.0 * kPi * r * r * r, sphere_a = 4.0 * kPi * r * r;
    double prev_verr = 1.0, prev_aerr = 1.0;
    for (int level = 2; level <= 6; ++level) {
        const TriangleMesh m = icosphere(r, level);
        const double v = signed_volume_mm3(m), a = surface_area_mm2(m);
        // Inscribed polyhedron: always below the sphere, error shrinks ~4x per level (O(h^2)).
        EXPECT_LT(v, sphere_v);
        EXPECT_LT(a, sphere_a);
        const double verr = (sphere_v - v) / sphere_v, aerr = (sphere_a - a) / sphere_a;
        const double h = 1.1 / std::pow(2.0, level);  // icosahedron edge on the unit sphere ~ 1.05
        EXPECT_LT(verr, h * h) << "level " << level;
        EXPECT_LT(aerr, h * h) << "level " << level;
        EXPECT_LT(verr, prev_verr / 3.0) << "level " << level;
        EXPECT_LT(aerr, prev_aerr / 3.0) << "level " << level;
        prev_verr = verr;
        prev_aerr = aerr;
    }
    EXPECT_LT(prev_verr, 1e-3);
}

TEST(Measure, InwardSphereHasNegativeVolume) {
    const TriangleMesh out = icosphere(5.0, 3, {1, 2, 3});
    const TriangleMesh in = flipped(out);
    EXPECT_LT(signed_volume_mm3(in), 0.0);
    EXPECT_NEAR(signed_volume_mm3(in), -signed_volume_mm3(out), 1e-9);
    EXPECT_NEAR(surface_area_mm2(in), surface_area_mm2(out), 1e-9);
}

TEST(Measure, CentroidOfTranslatedSphere) {
    const Point c{12.5, -3.0, 100.0};
    const Point g = volume_centroid(icosphere(4.0, 3, c));
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(g[i], c[i], 1e-9);
    const BoundingBox b = bounding_box(icosphere(4.0, 3, c));
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(b.min[i], c[i] - 4.0, 1e-12);
        EXPECT_NEAR(b.max[i], c[i] + 4.0, 1e-12);
    }
}

TEST(Measure, CentroidOfUnionWeightsByVolume) {
    // Cube of volume 1 at [0,1]^3 and cube of volume 8 at [10,12]^3.
    const TriangleMesh m = merged(cube(1.0), cube(2.0, {10, 10, 10}));
    EXPECT_EQ(signed_volume_mm3(m), 9.0);
    const Point g = volume_centroid(m);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(g[i], (0.5 * 1 + 11.0 * 8) / 9.0, 1e-12);
}

TEST(Measure, EmptyAndInvalid) {
    const TriangleMesh empty;
    EXPECT_EQ(signed_volume_mm3(empty), 0.0);
    EXPECT_EQ(surface_area_mm2(empty), 0.0);
    EXPECT_EQ(bounding_box(empty).min, (Point{0, 0, 0}));
    EXPECT_THROW(volume_centroid(empty), InvalidMesh);
    TriangleMesh bad = cube();
    bad.faces.push_back({0, 1, 8});
    EXPECT_THROW(signed_volume_mm3(bad), InvalidMesh);
    EXPECT_THROW(surface_area_mm2(bad), InvalidMesh);
    EXPECT_THROW(volume_centroid(bad), InvalidMesh);
}
