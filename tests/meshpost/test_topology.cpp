#include <gtest/gtest.h>

#include <cmath>

#include "meshpost/measure.h"
#include "meshpost/topology.h"
#include "test_meshes.h"

using namespace meshpost;
using namespace meshpost::test;

TEST(Topology, CubeIsClosedManifoldGenus0) {
    const TopologyReport r = analyze_topology(cube());
    EXPECT_EQ(r.vertices, 8u);
    EXPECT_EQ(r.faces, 12u);
    EXPECT_EQ(r.edges, 18u);
    EXPECT_EQ(r.boundary_edges, 0u);
    EXPECT_EQ(r.nonmanifold_edges, 0u);
    EXPECT_EQ(r.nonmanifold_vertices, 0u);
    EXPECT_EQ(r.inconsistent_edges, 0u);
    EXPECT_EQ(r.isolated_vertices, 0u);
    EXPECT_EQ(r.degenerate_faces, 0u);
    EXPECT_EQ(r.components, 1u);
    EXPECT_EQ(r.genus, 0);
    EXPECT_TRUE(r.closed);
    EXPECT_TRUE(r.manifold);
    EXPECT_TRUE(r.oriented);
    EXPECT_TRUE(is_closed_manifold(r));
}

TEST(Topology, IcosphereGenus0AtEveryLevel) {
    for (int level = 0; level <= 4; ++level) {
        const TriangleMesh m = icosphere(3.0, level);
        const TopologyReport r = analyze_topology(m);
        EXPECT_TRUE(is_closed_manifold(r)) << "level " << level;
        EXPECT_EQ(r.genus, 0) << "level " << level;
        EXPECT_EQ(r.components, 1u);
        EXPECT_EQ(r.edges, m.faces.size() * 3 / 2);
    }
}

TEST(Topology, TorusGenus1) {
    const TriangleMesh t = torus(10.0, 3.0);
    EXPECT_GT(signed_volume_mm3(t), 0.0);  // the generator is outward oriented
    const TopologyReport r = analyze_topology(t);
    EXPECT_TRUE(is_closed_manifold(r));
    EXPECT_EQ(r.genus, 1);
    EXPECT_EQ(r.components, 1u);
}

TEST(Topology, GenusIsSummedOverComponents) {
    const TriangleMesh m = merged(merged(torus(10, 3), torus(10, 3, 24, 12, {50, 0, 0})), icosphere(2, 1, {0, 50, 0}));
    const TopologyReport r = analyze_topology(m);
    EXPECT_TRUE(is_closed_manifold(r));
    EXPECT_EQ(r.components, 3u);
    EXPECT_EQ(r.genus, 2);
}

TEST(Topology, HoleGivesThreeBoundaryEdges) {
    TriangleMesh m = icosphere(1.0, 2);
    m.faces.erase(m.faces.begin() + 7);
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.boundary_edges, 3u);
    EXPECT_FALSE(r.closed);
    EXPECT_TRUE(r.manifold);
    EXPECT_TRUE(r.oriented);
    EXPECT_FALSE(is_closed_manifold(r));
}

TEST(Topology, ThreeFacesOnOneEdgeIsNonManifoldEdge) {
    TriangleMesh m = cube();
    m.vertices.push_back({0.5, -1.0, -1.0});  // a fin hanging off edge 0-1
    m.faces.push_back({0, 1, 8});
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.nonmanifold_edges, 1u);
    EXPECT_EQ(r.boundary_edges, 2u);  // the fin's two free edges
    EXPECT_FALSE(r.manifold);
    EXPECT_FALSE(r.oriented);
    EXPECT_FALSE(is_closed_manifold(r));
    EXPECT_EQ(r.components, 1u);
}

TEST(Topology, TwoSolidsSharingOneVertexIsNonManifoldVertex) {
    // Two tetrahedra touching at vertex 0 only.
    TriangleMesh a = tetrahedron(1.0);
    TriangleMesh b = tetrahedron(-1.0);  // mirrored through the origin: flip to keep it outward
    b = flipped(b);
    TriangleMesh m = a;
    const uint32_t shift = static_cast<uint32_t>(m.vertices.size()) - 1;  // b's vertex 0 is a's vertex 0
    for (size_t i = 1; i < b.vertices.size(); ++i) m.vertices.push_back(b.vertices[i]);
    for (Face f : b.faces) {
        for (uint32_t& v : f) v = v == 0 ? 0 : v + shift;
        m.faces.push_back(f);
    }
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.vertices, 7u);
    EXPECT_EQ(r.nonmanifold_vertices, 1u);
    EXPECT_EQ(r.nonmanifold_edges, 0u);
    EXPECT_EQ(r.boundary_edges, 0u);
    EXPECT_EQ(r.components, 2u);  // components are face-connected through edges
    EXPECT_TRUE(r.closed);
    EXPECT_FALSE(r.manifold);
    EXPECT_FALSE(is_closed_manifold(r));
    EXPECT_NEAR(signed_volume_mm3(m), 2.0 / 6.0, 1e-12);
}

TEST(Topology, TwoCubesSharingOneVertex) {
    // Cube [0,1]^3 and cube [1,2]^3 share corner (1,1,1): vertex 7 of the first.
    TriangleMesh a = cube();
    TriangleMesh b = cube(1.0, {1, 1, 1});
    TriangleMesh m = a;
    std::vector<uint32_t> map(8);
    for (uint32_t i = 0; i < 8; ++i) {
        if (i == 0) {
            map[i] = 7;
        } else {
            map[i] = static_cast<uint32_t>(m.vertices.size());
            m.vertices.push_back(b.vertices[i]);
        }
    }
    for (const Face& f : b.faces) m.faces.push_back({map[f[0]], map[f[1]], map[f[2]]});
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.nonmanifold_vertices, 1u);
    EXPECT_EQ(r.nonmanifold_edges, 0u);
    EXPECT_EQ(r.components, 2u);
    EXPECT_FALSE(r.manifold);
}

TEST(Topology, FlippedFaceGivesThreeInconsistentEdges) {
    TriangleMesh m = icosphere(1.0, 2);
    std::swap(m.faces[11][1], m.faces[11][2]);
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.inconsistent_edges, 3u);
    EXPECT_TRUE(r.closed);
    EXPECT_TRUE(r.manifold);
    EXPECT_FALSE(r.oriented);
    EXPECT_FALSE(is_closed_manifold(r));
    EXPECT_EQ(r.genus, 0);  // the Euler characteristic does not depend on orientation
}

TEST(Topology, FullyInvertedMeshIsStillConsistent) {
    const TopologyReport r = analyze_topology(flipped(icosphere(1.0, 1)));
    EXPECT_TRUE(is_closed_manifold(r));  // orientation consistency, not direction
}

TEST(Topology, DegenerateFaces) {
    TriangleMesh m = cube();
    m.vertices.push_back({0, 0, 5});
    m.vertices.push_back({1, 1, 6});
    m.vertices.push_back({2, 2, 7});  // exactly collinear with the previous two
    m.faces.push_back({8, 9, 10});
    m.faces.push_back({0, 0, 1});     // repeated index
    m.faces.push_back({8, 8, 8});
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.degenerate_faces, 3u);
    EXPECT_FALSE(is_closed_manifold(r));
}

// analyze_connectivity reads no position: it counts the faces with a repeated index only, and
// count_collinear_faces the rest of analyze_topology's degenerate faces; all else is the same.
TEST(Topology, ConnectivityAndCollinearFacesMakeTheWholeAnalysis) {
    TriangleMesh m = cube();
    m.vertices.push_back({0, 0, 5});
    m.vertices.push_back({1, 1, 6});
    m.vertices.push_back({2, 2, 7});  // exactly collinear with the previous two
    m.vertices.push_back({9, 9, 9});  // isolated
    m.faces.push_back({8, 9, 10});
    m.faces.push_back({0, 0, 1});  // repeated index
    m.faces.push_back({1, 3, 3});
    for (const TriangleMesh& mesh : {m, flipped(icosphere(1.0, 2)), cube()}) {
        const TopologyReport whole = analyze_topology(mesh);
        TopologyReport faces = analyze_connectivity(mesh);
        const size_t collinear = count_collinear_faces(mesh);
        faces.degenerate_faces += collinear;
        EXPECT_EQ(faces.vertices, whole.vertices);
        EXPECT_EQ(faces.faces, whole.faces);
        EXPECT_EQ(faces.edges, whole.edges);
        EXPECT_EQ(faces.boundary_edges, whole.boundary_edges);
        EXPECT_EQ(faces.nonmanifold_edges, whole.nonmanifold_edges);
        EXPECT_EQ(faces.nonmanifold_vertices, whole.nonmanifold_vertices);
        EXPECT_EQ(faces.inconsistent_edges, whole.inconsistent_edges);
        EXPECT_EQ(faces.isolated_vertices, whole.isolated_vertices);
        EXPECT_EQ(faces.degenerate_faces, whole.degenerate_faces);
        EXPECT_EQ(faces.components, whole.components);
        EXPECT_EQ(faces.genus, whole.genus);
        EXPECT_EQ(faces.closed, whole.closed);
        EXPECT_EQ(faces.manifold, whole.manifold);
        EXPECT_EQ(faces.oriented, whole.oriented);
    }
    EXPECT_EQ(count_collinear_faces(m), 1u);
    EXPECT_EQ(analyze_connectivity(m).degenerate_faces, 2u);
    EXPECT_EQ(analyze_connectivity(m).isolated_vertices, 1u);
    // Positions do not matter to analyze_connectivity: every vertex at one point.
    TriangleMesh flat = cube();
    for (Point& p : flat.vertices) p = {1, 2, 3};
    EXPECT_TRUE(is_closed_manifold(analyze_connectivity(flat)));
    EXPECT_EQ(count_collinear_faces(flat), flat.faces.size());
    m.faces.push_back({0, 1, 99});
    for (auto fn : {+[](const TriangleMesh& x) { analyze_connectivity(x); }, +[](const TriangleMesh& x) { count_collinear_faces(x); }})
        EXPECT_THROW(fn(m), InvalidMesh);
}

TEST(Topology, CollinearityIsExact) {
    // Large offsets with tiny steps: exactly collinear, then one coordinate moved by one ulp.
    const double base = 1073741824.0;           // 2^30
    const double step = std::ldexp(1.0, -20);    // 2^-20
    auto pt = [&](double k) { return Point{base + k * step, base + 3 * k * step, base + 7 * k * step}; };
    TriangleMesh m;
    m.vertices = {pt(0), pt(1), pt(2)};
    m.faces = {{0, 1, 2}};
    EXPECT_EQ(analyze_topology(m).degenerate_faces, 1u);
    m.vertices[2][0] = std::nextafter(m.vertices[2][0], 2 * base);
    EXPECT_EQ(analyze_topology(m).degenerate_faces, 0u);
    // Identical points.
    m.vertices = {{0.1, 0.2, 0.3}, {0.1, 0.2, 0.3}, {5, 6, 7}};
    EXPECT_EQ(analyze_topology(m).degenerate_faces, 1u);
    // Collinear points whose differences are not exactly representable.
    m.vertices = {{0.1, 0.1, 0.1}, {0.7, 0.7, 0.7}, {1e10, 1e10, 1e10}};
    EXPECT_EQ(analyze_topology(m).degenerate_faces, 1u);
    m.vertices = {{0.1, 0.1, 0.1}, {0.7, 0.7, 0.7}, {1e10, 1e10, std::nextafter(1e10, 0.0)}};
    EXPECT_EQ(analyze_topology(m).degenerate_faces, 0u);
}

TEST(Topology, ComponentsAndIsolatedVertices) {
    TriangleMesh m = merged(merged(cube(), cube(1.0, {3, 0, 0})), tetrahedron(1.0, {0, 5, 0}));
    m.vertices.push_back({9, 9, 9});
    const TopologyReport r = analyze_topology(m);
    EXPECT_EQ(r.components, 3u);
    EXPECT_EQ(r.isolated_vertices, 1u);
    EXPECT_EQ(r.genus, 0);
    EXPECT_TRUE(is_closed_manifold(r));  // isolated vertices do not make a mesh non-manifold
}

TEST(Topology, EmptyMesh) {
    const TopologyReport r = analyze_topology(TriangleMesh{});
    EXPECT_EQ(r.faces, 0u);
    EXPECT_EQ(r.components, 0u);
    EXPECT_FALSE(r.closed);
    EXPECT_FALSE(is_closed_manifold(r));
}

TEST(Topology, OutOfRangeIndexThrows) {
    TriangleMesh m = cube();
    m.faces.push_back({0, 1, 99});
    EXPECT_THROW(analyze_topology(m), InvalidMesh);
}

TEST(Topology, LargeMesh) {
    const TriangleMesh m = icosphere(50.0, 8);  // 1.3 M faces
    ASSERT_EQ(m.faces.size(), 1310720u);
    const TopologyReport r = analyze_topology(m);
    EXPECT_TRUE(is_closed_manifold(r));
    EXPECT_EQ(r.genus, 0);
}

TEST(Topology, GenusWithinBallFindsTheHandleOnlyWhereItIs) {
    // A sphere of radius 40 and, beside it, a torus (R 10, r 3) centred at x = 100.
    const TriangleMesh m = merged(icosphere(40.0, 4), torus(10, 3, 48, 24, {100, 0, 0}));
    EXPECT_EQ(genus_within_ball(m, {100, 0, 0}, 20.0), 1);  // the whole torus
    EXPECT_EQ(genus_within_ball(m, {0, 0, 0}, 45.0), 0);    // the whole sphere
    EXPECT_EQ(genus_within_ball(m, {40, 0, 0}, 10.0), 0);   // a disc of the sphere
    // Part of the torus tube: a cylinder-like patch, no handle.
    EXPECT_EQ(genus_within_ball(m, {110, 0, 0}, 5.0), 0);
    EXPECT_EQ(genus_within_ball(m, {500, 0, 0}, 5.0), 0);   // empty
    // Both: the handle is counted once.
    EXPECT_EQ(genus_within_ball(m, {50, 0, 0}, 80.0), 1);
}
