#include <gtest/gtest.h>

#include <omp.h>

#include <cmath>
#include <stdexcept>

#include "meshpost/cgal/deviation.h"
#include "test_meshes.h"

using namespace meshpost;

TEST(Deviation, ConcentricSpheresAreOneMillimetreApartBothWays) {
    const TriangleMesh a = test::icosphere(50.0, 5), b = test::icosphere(51.0, 5);
    const DeviationResult d = surface_deviation(a, b);
    EXPECT_NEAR(d.a_to_b.mean, 1.0, 0.01);
    EXPECT_NEAR(d.b_to_a.mean, 1.0, 0.01);
    EXPECT_NEAR(d.a_to_b.median, 1.0, 0.01);
    EXPECT_NEAR(d.a_to_b.rms, 1.0, 0.01);
    EXPECT_NEAR(d.hausdorff_mm, 1.0, 0.05);
    EXPECT_GE(d.a_to_b.p95, d.a_to_b.median);
    EXPECT_GE(d.a_to_b.max, d.a_to_b.p95);
    EXPECT_GT(d.a_to_b.samples, a.faces.size());  // sampled over faces, not only vertices
    EXPECT_GT(d.sampling_error_bound_mm, 0.0);
    EXPECT_LE(d.sampling_error_bound_mm, 2.0 / 3.0 * d.sample_spacing_mm + 1e-12);
    std::printf("[ numbers  ] icosphere r50 vs r51: mean a->b %.5f, b->a %.5f mm; hausdorff %.5f; samples %zu + %zu; "
                "bound %.4f mm\n",
                d.a_to_b.mean, d.b_to_a.mean, d.hausdorff_mm, d.a_to_b.samples, d.b_to_a.samples,
                d.sampling_error_bound_mm);
}

TEST(Deviation, IdenticalMeshesAreZeroApart) {
    const TriangleMesh a = test::torus(30.0, 10.0, 48, 24);
    const DeviationResult d = surface_deviation(a, a);
    EXPECT_LT(d.hausdorff_mm, 1e-9);
    EXPECT_LT(d.a_to_b.mean, 1e-12);
}

TEST(Deviation, FindsTheMaximumInsideAFaceNotAtAVertex) {
    // A single big triangle against a plane below a bump: samples over the face catch it.
    TriangleMesh flat;
    flat.vertices = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}};
    flat.faces = {{0, 1, 2}};
    TriangleMesh tent;  // a tent whose apex (2, 2, 1) lies above the face interior
    tent.vertices = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}, {2, 2, 1}};
    tent.faces = {{0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
    DeviationParams p;
    p.sample_spacing_mm = 0.05;
    const DeviationResult d = surface_deviation(flat, tent, p);
    // Every vertex of `flat` is on `tent`, but the apex is 1 mm above the face: b_to_a sees it.
    EXPECT_NEAR(d.b_to_a.max, 1.0, d.sampling_error_bound_mm + 1e-9);
    EXPECT_LE(d.b_to_a.max, 1.0 + 1e-9);
    EXPECT_NEAR(d.hausdorff_mm, 1.0, d.sampling_error_bound_mm + 1e-9);
}

TEST(Deviation, SpacingControlsSamplesAndBound) {
    const TriangleMesh a = test::icosphere(10.0, 2), b = test::icosphere(10.5, 2);
    DeviationParams coarse, fine;
    coarse.sample_spacing_mm = 2.0;
    fine.sample_spacing_mm = 0.25;
    const DeviationResult c = surface_deviation(a, b, coarse), f = surface_deviation(a, b, fine);
    EXPECT_GT(f.a_to_b.samples, 10 * c.a_to_b.samples);
    EXPECT_LT(f.sampling_error_bound_mm, c.sampling_error_bound_mm);
    EXPECT_LE(f.sampling_error_bound_mm, 2.0 / 3.0 * 0.25 + 1e-12);
    // The fine Hausdorff is within the coarse one's error bound.
    EXPECT_LE(f.hausdorff_mm, c.hausdorff_mm + c.sampling_error_bound_mm + 1e-12);
}

TEST(Deviation, QuantilesCanBeLeftOut) {
    const TriangleMesh a = test::icosphere(10.0, 2), b = test::icosphere(10.5, 3);
    DeviationParams p;
    p.sample_spacing_mm = 0.5;
    const DeviationResult with = surface_deviation(a, b, p);
    p.quantiles = false;
    const DeviationResult without = surface_deviation(a, b, p);
    EXPECT_GT(with.b_to_a.median, 0.0);
    EXPECT_EQ(without.a_to_b.median, 0.0);
    EXPECT_EQ(without.b_to_a.p95, 0.0);
    EXPECT_EQ(without.a_to_b.mean, with.a_to_b.mean);
    EXPECT_EQ(without.b_to_a.rms, with.b_to_a.rms);
    EXPECT_EQ(without.hausdorff_mm, with.hausdorff_mm);
}

TEST(Deviation, SameResultForAnyThreadCount) {
    const TriangleMesh a = test::torus(30.0, 10.0, 64, 32), b = test::icosphere(35.0, 4);
    DeviationParams p;
    p.sample_spacing_mm = 0.5;
    p.keep_samples = true;
    p.vertex_distances = true;
    const DeviationResult s = test::with_threads(1, [&] { return surface_deviation(a, b, p); });
    const DeviationResult m =
        test::with_threads(std::max(2, omp_get_max_threads()), [&] { return surface_deviation(a, b, p); });
    EXPECT_EQ(s.a_to_b.mean, m.a_to_b.mean);
    EXPECT_EQ(s.b_to_a.p95, m.b_to_a.p95);
    EXPECT_EQ(s.a_distances, m.a_distances);
    EXPECT_EQ(s.a_vertex_distances, m.a_vertex_distances);
    EXPECT_EQ(s.a_vertex_distances.size(), a.vertices.size());
}

TEST(Deviation, FarApartSurfacesUseTheTreeAndAgreeWithTheGrid) {
    // Samples of the big sphere lie ~190 mm (hundreds of grid cells) from the small one: the grid's
    // ring search leaves them to CGAL's tree. The small sphere's samples settle in the grid.
    const TriangleMesh small = test::icosphere(10.0, 3), big = test::icosphere(200.0, 3);
    DeviationParams p;
    p.sample_spacing_mm = 2.0;
    p.vertex_distances = true;
    const DeviationResult d = surface_deviation(big, small, p);
    EXPECT_NEAR(d.a_to_b.mean, 189.5, 0.5);  // the big sphere's faces lie inside radius 200
    EXPECT_NEAR(d.b_to_a.mean, 189.5, 0.5);
    // Every vertex of the big sphere is 190 mm from the small sphere's vertices, a bit less from
    // its faces (those lie inside the radius-10 sphere).
    for (double x : d.a_vertex_distances) {
        EXPECT_GE(x, 190.0 - 1e-9);
        EXPECT_LE(x, 190.5);
    }
}

TEST(Deviation, RejectsBadInput) {
    const TriangleMesh a = test::icosphere(1.0, 1);
    EXPECT_THROW(surface_deviation(TriangleMesh{}, a), InvalidMesh);
    TriangleMesh nan = a;
    nan.vertices[0][1] = std::nan("");
    EXPECT_THROW(surface_deviation(nan, a), InvalidMesh);
    TriangleMesh bad = a;
    bad.faces[0][2] = 999;
    EXPECT_THROW(surface_deviation(a, bad), InvalidMesh);
    DeviationParams p;
    p.sample_spacing_mm = -1;
    EXPECT_THROW(surface_deviation(a, a, p), std::invalid_argument);
    p.sample_spacing_mm = 1e-9;
    EXPECT_THROW(surface_deviation(a, a, p), std::invalid_argument);
}

TEST(Hausdorff, AgreesWithDenseSamplingFromFewerDistances) {
    // A coarse sphere against a finer, slightly bigger one: the largest distances lie inside
    // the coarse faces (their centres sink below radius 10).
    const TriangleMesh a = test::icosphere(10.0, 2), b = test::icosphere(10.3, 4);
    const HausdorffResult h = hausdorff_distance(a, b);
    DeviationParams fine;
    fine.sample_spacing_mm = 0.1;
    const DeviationResult d = surface_deviation(a, b, fine);
    // Both are lower bounds of the true distance, each within its error bound of it.
    EXPECT_LE(h.hausdorff_mm, d.hausdorff_mm + d.sampling_error_bound_mm + 1e-9);
    EXPECT_LE(d.hausdorff_mm, h.hausdorff_mm + h.sampling_error_bound_mm + 1e-9);
    EXPECT_GT(h.hausdorff_mm, 0.4);
    EXPECT_NEAR(h.mean_a_to_b_mm, d.a_to_b.mean, 0.02 * d.a_to_b.mean);
    EXPECT_NEAR(h.mean_b_to_a_mm, d.b_to_a.mean, 0.02 * d.b_to_a.mean);
    const DeviationResult dflt = surface_deviation(a, b);
    EXPECT_LE(h.sampling_error_bound_mm, dflt.sampling_error_bound_mm + 1e-12);
    EXPECT_LT(h.points, dflt.a_to_b.samples + dflt.b_to_a.samples);
}

TEST(Hausdorff, FindsTheMaximumInsideFacesWhenEveryVertexIsShared) {
    // One bent quad split along either diagonal: all vertices lie on both surfaces (the
    // vertices' distances are 0), the diagonals do not.
    TriangleMesh a, b;
    a.vertices = b.vertices = {{0, 0, 0}, {10, 0, 0}, {10, 10, 2}, {0, 10, 0}};
    a.faces = {{0, 1, 2}, {0, 2, 3}};
    b.faces = {{0, 1, 3}, {1, 2, 3}};
    HausdorffParams p;
    p.sample_spacing_mm = 0.5;
    const HausdorffResult h = hausdorff_distance(a, b, p);
    DeviationParams fine;
    fine.sample_spacing_mm = 0.02;
    const DeviationResult d = surface_deviation(a, b, fine);
    EXPECT_GT(h.hausdorff_mm, 0.5);
    EXPECT_LE(h.hausdorff_mm, d.hausdorff_mm + d.sampling_error_bound_mm + 1e-9);
    EXPECT_LE(d.hausdorff_mm, h.hausdorff_mm + h.sampling_error_bound_mm + 1e-9);
}

TEST(Hausdorff, SameResultForAnyThreadCount) {
    const TriangleMesh a = test::torus(30.0, 10.0, 64, 32), b = test::icosphere(35.0, 4);
    const HausdorffResult s = test::with_threads(1, [&] { return hausdorff_distance(a, b); });
    const HausdorffResult m =
        test::with_threads(std::max(2, omp_get_max_threads()), [&] { return hausdorff_distance(a, b); });
    EXPECT_EQ(s.hausdorff_mm, m.hausdorff_mm);
    EXPECT_EQ(s.sampling_error_bound_mm, m.sampling_error_bound_mm);
    EXPECT_EQ(s.mean_a_to_b_mm, m.mean_a_to_b_mm);
    EXPECT_EQ(s.mean_b_to_a_mm, m.mean_b_to_a_mm);
    EXPECT_EQ(s.points, m.points);
}

TEST(Hausdorff, FarApartSurfacesUseTheTree) {
    const TriangleMesh small = test::icosphere(10.0, 3), big = test::icosphere(200.0, 3);
    const HausdorffResult h = hausdorff_distance(big, small);
    EXPECT_NEAR(h.hausdorff_mm, 190.0, 0.5);
    EXPECT_NEAR(h.mean_a_to_b_mm, 189.5, 0.5);
    EXPECT_NEAR(h.mean_b_to_a_mm, 189.5, 0.5);
    EXPECT_THROW(hausdorff_distance(TriangleMesh{}, small), InvalidMesh);
}
