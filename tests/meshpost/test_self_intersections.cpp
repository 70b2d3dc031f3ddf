#include <gtest/gtest.h>

#include <cstdio>

#include <omp.h>

#include "meshpost/self_intersections.h"
#include "meshpost/topology.h"
#include "test_meshes.h"

using namespace meshpost;
using namespace meshpost::test;

namespace {

/// Two tetrahedra sharing one vertex, far from everything else: a non-manifold part that forces the
/// triangle-soup code path but intersects nothing.
TriangleMesh bowtie(Point at) {
    TriangleMesh a = tetrahedron(1.0, at);
    const TriangleMesh b = flipped(tetrahedron(-1.0, at));
    const uint32_t shift = static_cast<uint32_t>(a.vertices.size()) - 1;
    for (size_t i = 1; i < b.vertices.size(); ++i) a.vertices.push_back(b.vertices[i]);
    for (Face f : b.faces) {
        for (uint32_t& v : f) v = v == 0 ? 0 : v + shift;
        a.faces.push_back(f);
    }
    return a;
}

}  // namespace

TEST(SelfIntersections, CleanIcosphereHasNone) {
    const SelfIntersectionReport r = find_self_intersections(icosphere(10.0, 3));
    EXPECT_EQ(r.intersecting_pairs, 0u);
    EXPECT_TRUE(r.examples.empty());
}

TEST(SelfIntersections, CubeAndTorusHaveNone) {
    EXPECT_EQ(find_self_intersections(cube()).intersecting_pairs, 0u);
    EXPECT_EQ(find_self_intersections(torus(10, 3)).intersecting_pairs, 0u);
}

TEST(SelfIntersections, DisjointSpheresHaveNone) {
    const TriangleMesh m = merged(icosphere(5.0, 3), icosphere(5.0, 3, {10.5, 0, 0}));
    EXPECT_EQ(find_self_intersections(m).intersecting_pairs, 0u);
}

TEST(SelfIntersections, InterpenetratingSpheres) {
    const TriangleMesh a = icosphere(5.0, 3);
    const TriangleMesh m = merged(a, icosphere(5.0, 3, {5.0, 0.3, 0.2}));
    const SelfIntersectionReport r = find_self_intersections(m);
    EXPECT_GT(r.intersecting_pairs, 0u);
    ASSERT_EQ(r.examples.size(), 20u);
    for (const auto& [f, g] : r.examples) {
        EXPECT_LT(f, g);
        EXPECT_LT(f, a.faces.size());   // one face from each sphere
        EXPECT_GE(g, a.faces.size());
    }
    EXPECT_TRUE(std::is_sorted(r.examples.begin(), r.examples.end()));
    // Deterministic.
    const SelfIntersectionReport again = find_self_intersections(m);
    EXPECT_EQ(again.intersecting_pairs, r.intersecting_pairs);
    EXPECT_EQ(again.examples, r.examples);
}

TEST(SelfIntersections, SoupPathAgreesWithSurfaceMeshPath) {
    // Adding a non-manifold, non-intersecting part switches to the triangle-soup implementation.
    const TriangleMesh spheres = merged(icosphere(5.0, 3), icosphere(5.0, 3, {5.0, 0.3, 0.2}));
    const TriangleMesh with_bowtie = merged(spheres, bowtie({100, 100, 100}));
    ASSERT_FALSE(analyze_topology(with_bowtie).manifold);
    const SelfIntersectionReport mesh_path = find_self_intersections(spheres);
    const SelfIntersectionReport soup_path = find_self_intersections(with_bowtie);
    EXPECT_EQ(soup_path.intersecting_pairs, mesh_path.intersecting_pairs);
    EXPECT_EQ(soup_path.examples, mesh_path.examples);
    // Clean non-manifold input.
    EXPECT_EQ(find_self_intersections(bowtie({0, 0, 0})).intersecting_pairs, 0u);
}

TEST(SelfIntersections, NonManifoldFinOverlappingAFace) {
    TriangleMesh m = cube();
    m.vertices.push_back({0.5, 0.5, 0.0});  // in the bottom face's plane, inside it
    m.faces.push_back({0, 1, 8});
    const SelfIntersectionReport r = find_self_intersections(m);
    EXPECT_GT(r.intersecting_pairs, 0u);
    // A fin sticking out of the cube touches it only along the shared edge.
    m.vertices.back() = {0.5, -1.0, -1.0};
    EXPECT_EQ(find_self_intersections(m).intersecting_pairs, 0u);
}

TEST(SelfIntersections, FoldedSurface) {
    // A vertex of the icosphere pushed through the opposite side.
    TriangleMesh m = icosphere(5.0, 2);
    m.vertices[0] = {-m.vertices[0][0] * 1.5, -m.vertices[0][1] * 1.5, -m.vertices[0][2] * 1.5};
    EXPECT_GT(find_self_intersections(m).intersecting_pairs, 0u);
}

TEST(SelfIntersections, EmptyAndInvalid) {
    EXPECT_EQ(find_self_intersections(TriangleMesh{}).intersecting_pairs, 0u);
    TriangleMesh bad = cube();
    bad.faces.push_back({0, 1, 42});
    EXPECT_THROW(find_self_intersections(bad), InvalidMesh);
}

TEST(SelfIntersections, MillionFaces) {
#ifdef NDEBUG
    const int level = 8;  // 1.3 M faces
#else
    const int level = 6;  // debug builds run CGAL's internal checks: keep the test short
#endif
    TriangleMesh m = icosphere(50.0, level);
    for (int path = 0; path < 2; ++path) {
        if (path == 1) {
            // A fin on an edge makes the mesh non-manifold: the triangle-soup implementation.
            m.vertices.push_back({200, 200, 200});
            m.faces.push_back({m.faces[0][0], m.faces[0][1], static_cast<uint32_t>(m.vertices.size() - 1)});
        }
        const SelfIntersectionReport r = find_self_intersections(m);
        EXPECT_EQ(r.intersecting_pairs, 0u);
    }
}

TEST(SelfIntersections, SameReportForAnyThreadCount) {
    // Large enough for the slab-parallel path; interpenetrating spheres give many pairs.
    const TriangleMesh a = icosphere(5.0, 5);
    const TriangleMesh m = merged(a, icosphere(5.0, 5, {5.0, 0.3, 0.2}));
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const SelfIntersectionReport one = find_self_intersections(m);
    for (int t : {2, 3, 7}) {
        omp_set_num_threads(t);
        const SelfIntersectionReport r = find_self_intersections(m);
        EXPECT_EQ(r.intersecting_pairs, one.intersecting_pairs) << t << " threads";
        EXPECT_EQ(r.examples, one.examples) << t << " threads";
    }
    omp_set_num_threads(saved);
    EXPECT_GT(one.intersecting_pairs, 100u);
}
