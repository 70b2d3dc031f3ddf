#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <omp.h>

#include "meshpost/cgal/self_intersections.h"
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

/// Every intersecting pair, by the grid and by CGAL's reference; the two must agree. Returns the
/// grid's count.
size_t expect_methods_agree(const TriangleMesh& m, const std::string& what) {
    SelfIntersectionOptions grid;
    grid.max_examples = size_t(-1);
    SelfIntersectionOptions ref = grid;
    ref.method = SelfIntersectionMethod::CgalReference;
    const SelfIntersectionReport g = find_self_intersections(m, grid);
    const SelfIntersectionReport r = find_self_intersections(m, ref);
    EXPECT_EQ(g.intersecting_pairs, r.intersecting_pairs) << what;
    EXPECT_EQ(g.examples, r.examples) << what;
    EXPECT_EQ(g.examples.size(), g.intersecting_pairs) << what;
    return g.intersecting_pairs;
}

/// Vertices moved by up to `amount` (uniform, fixed seed) and optionally rounded to multiples of
/// `snap`, which makes exactly coplanar, collinear and coincident configurations.
TriangleMesh jittered(TriangleMesh m, double amount, double snap, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-amount, amount);
    for (Point& p : m.vertices)
        for (double& c : p) {
            c += u(rng);
            if (snap > 0) c = snap * std::round(c / snap);
        }
    return m;
}

/// A z = 0 grid of n x n squares (two triangles each), spacing 1, plus `offset`.
TriangleMesh sheet(uint32_t n, Point offset) {
    TriangleMesh m;
    for (uint32_t y = 0; y <= n; ++y)
        for (uint32_t x = 0; x <= n; ++x) m.vertices.push_back({offset[0] + x, offset[1] + y, offset[2]});
    for (uint32_t y = 0; y < n; ++y)
        for (uint32_t x = 0; x < n; ++x) {
            const uint32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
            m.faces.push_back({a, b, d});
            m.faces.push_back({a, d, c});
        }
    return m;
}

}  // namespace

TEST(SelfIntersections, GridAgreesWithCgalReference) {
    EXPECT_EQ(expect_methods_agree(icosphere(10.0, 3), "icosphere"), 0u);
    EXPECT_EQ(expect_methods_agree(torus(10, 3), "torus"), 0u);
    EXPECT_GT(expect_methods_agree(merged(icosphere(5.0, 3), icosphere(5.0, 3, {5.0, 0.3, 0.2})), "two spheres"), 0u);
    EXPECT_EQ(expect_methods_agree(merged(icosphere(5.0, 3), bowtie({100, 100, 100})), "sphere and bowtie"), 0u);
    TriangleMesh folded = icosphere(5.0, 2);
    folded.vertices[0] = {-folded.vertices[0][0] * 1.5, -folded.vertices[0][1] * 1.5, -folded.vertices[0][2] * 1.5};
    EXPECT_GT(expect_methods_agree(folded, "folded"), 0u);
    TriangleMesh fin = cube();
    fin.vertices.push_back({0.5, 0.5, 0.0});
    fin.faces.push_back({0, 1, 8});
    EXPECT_GT(expect_methods_agree(fin, "fin in a face"), 0u);
    // Touching without shared indices: a face, an edge, a corner in common; exactly coplanar sheets.
    EXPECT_GT(expect_methods_agree(merged(cube(), cube(1.0, {1, 0, 0})), "cubes sharing a face"), 0u);
    EXPECT_GT(expect_methods_agree(merged(cube(), cube(1.0, {1, 1, 0})), "cubes sharing an edge"), 0u);
    EXPECT_GT(expect_methods_agree(merged(cube(), cube(1.0, {1, 1, 1})), "cubes sharing a corner"), 0u);
    EXPECT_GT(expect_methods_agree(merged(cube(2.0), cube(1.0, {0.5, 0.5, 2.0})), "cube on a cube"), 0u);
    EXPECT_GT(expect_methods_agree(merged(sheet(8, {0, 0, 0}), sheet(8, {0.5, 0.25, 0})), "coplanar sheets"), 0u);
    EXPECT_GT(expect_methods_agree(merged(sheet(8, {0, 0, 0}), sheet(8, {0, 0, 0})), "duplicated sheet"), 0u);
    EXPECT_EQ(expect_methods_agree(sheet(20, {0, 0, 0}), "sheet"), 0u);
    // Crafted intersections on meshes of many small faces: random jitter folds faces over their
    // neighbours; snapping to a coarse lattice adds exactly coplanar, collinear and coincident
    // cases (faces sharing an edge and overlapping, zero-area faces, touching vertices).
    for (unsigned seed = 1; seed <= 3; ++seed) {
        const std::string s = std::to_string(seed);
        const TriangleMesh sphere = icosphere(10.0, 4);
        EXPECT_GT(expect_methods_agree(jittered(sphere, 0.4, 0.0, seed), "jittered " + s), 0u);
        EXPECT_GT(expect_methods_agree(jittered(sphere, 0.3, 0.5, seed), "snapped " + s), 0u);
        EXPECT_GT(expect_methods_agree(jittered(torus(10, 3, 96, 48), 0.2, 0.25, seed), "snapped torus " + s), 0u);
    }
}

TEST(SelfIntersections, GridAgreesOnUnevenFaceSizes) {
    // Long slivers through a fine sphere: the grid would list the slivers in many cells (the
    // implementation then uses CGAL's boxes); the report is the same either way.
    TriangleMesh m = icosphere(10.0, 4);
    for (int i = 0; i < 400; ++i) {
        const double a = 0.0157 * i;
        const uint32_t k = static_cast<uint32_t>(m.vertices.size());
        m.vertices.push_back({-30.0, 30.0 * std::cos(a), 30.0 * std::sin(a)});
        m.vertices.push_back({30.0, -30.0 * std::cos(a), -30.0 * std::sin(a)});
        m.vertices.push_back({30.0, -30.0 * std::cos(a) + 0.1, -30.0 * std::sin(a)});
        m.faces.push_back({k, k + 1, k + 2});
    }
    EXPECT_GT(expect_methods_agree(m, "slivers"), 0u);
    // A few large faces among small ones stay on the grid.
    TriangleMesh few = icosphere(10.0, 4);
    const uint32_t k = static_cast<uint32_t>(few.vertices.size());
    few.vertices.push_back({-20, -20, 0.1});
    few.vertices.push_back({20, -20, 0.1});
    few.vertices.push_back({0, 20, 0.1});
    few.faces.push_back({k, k + 1, k + 2});
    EXPECT_GT(expect_methods_agree(few, "one large face"), 0u);
}

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

// A subject (the faces the extraction moved): only pairs with a flagged face count, on every path.
TEST(SelfIntersections, SubjectLimitsThePairsToFlaggedFaces) {
    const TriangleMesh a = icosphere(5.0, 3);
    const TriangleMesh m = merged(a, icosphere(5.0, 3, {5.0, 0.3, 0.2}));
    const SelfIntersectionReport all = find_self_intersections(m);
    ASSERT_GT(all.intersecting_pairs, 0u);
    // Every intersecting pair has one face in each sphere: flagging the first sphere finds them all.
    std::vector<uint8_t> first(m.faces.size(), 0);
    std::fill(first.begin(), first.begin() + std::ptrdiff_t(a.faces.size()), uint8_t(1));
    for (const SelfIntersectionMethod method : {SelfIntersectionMethod::Grid, SelfIntersectionMethod::CgalReference}) {
        SelfIntersectionOptions o;
        o.method = method;
        o.subject = &first;
        const SelfIntersectionReport r = find_self_intersections(m, o);
        EXPECT_EQ(r.intersecting_pairs, all.intersecting_pairs);
        EXPECT_EQ(r.examples, all.examples);
        // One flagged face: exactly the pairs it is in.
        const auto [f, g] = all.examples.front();
        std::vector<uint8_t> one(m.faces.size(), 0);
        one[f] = 1;
        o.subject = &one;
        const SelfIntersectionReport just = find_self_intersections(m, o);
        size_t expected = 0;
        SelfIntersectionOptions every;
        every.max_examples = all.intersecting_pairs;
        for (const auto& p : find_self_intersections(m, every).examples) expected += p.first == f || p.second == f;
        EXPECT_EQ(just.intersecting_pairs, expected);
        EXPECT_GE(expected, 1u);
        // Nothing flagged: nothing tested.
        const std::vector<uint8_t> none(m.faces.size(), 0);
        o.subject = &none;
        EXPECT_EQ(find_self_intersections(m, o).intersecting_pairs, 0u);
    }
    SelfIntersectionOptions bad;
    const std::vector<uint8_t> short_flags(3, 1);
    bad.subject = &short_flags;
    EXPECT_THROW(find_self_intersections(m, bad), InvalidMesh);
}

TEST(SelfIntersections, SubjectAgreesWithReferenceForScatteredFlags) {
    // The grid leaves out the faces whose boxes cannot meet a flagged face's: flags scattered over
    // both spheres (the union of their boxes spans the mesh), a few clustered ones, and a single
    // face give the reference's pairs and examples.
    const TriangleMesh m = merged(icosphere(5.0, 4), icosphere(4.0, 3, {4.0, 0.7, -0.4}));
    const size_t nf = m.faces.size();
    std::vector<std::vector<uint8_t>> subjects;
    for (size_t step : {3u, 37u, 401u}) {
        std::vector<uint8_t> flags(nf, 0);
        for (size_t f = 0; f < nf; f += step) flags[f] = 1;
        subjects.push_back(flags);
    }
    std::vector<uint8_t> cluster(nf, 0);
    for (size_t f = nf / 2; f < nf / 2 + 50; ++f) cluster[f] = 1;
    subjects.push_back(cluster);
    std::vector<uint8_t> last(nf, 0);
    last[nf - 1] = 1;
    subjects.push_back(last);
    size_t with_pairs = 0;
    for (const std::vector<uint8_t>& flags : subjects) {
        SelfIntersectionOptions grid, reference;
        grid.subject = reference.subject = &flags;
        grid.max_examples = reference.max_examples = 1000;
        reference.method = SelfIntersectionMethod::CgalReference;
        const SelfIntersectionReport a = find_self_intersections(m, grid), b = find_self_intersections(m, reference);
        EXPECT_EQ(a.intersecting_pairs, b.intersecting_pairs);
        EXPECT_EQ(a.examples, b.examples);
        with_pairs += a.intersecting_pairs > 0;
    }
    EXPECT_GE(with_pairs, 3u);  // the scattered flags meet the spheres' crossing
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
