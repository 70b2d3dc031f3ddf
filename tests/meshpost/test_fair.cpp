// membrane_positions (fair.h): free vertices go onto the membrane spanning the fixed ones.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "meshpost/fair.h"

using namespace meshpost;

namespace {

// An n x n grid of vertices 1 mm apart in the plane z = 0, each square split by a diagonal; the
// inner vertices raised by `bump` (mm) toward their middle (a dome).
TriangleMesh dented_grid(int n, double bump) {
    TriangleMesh m;
    const double c = 0.5 * (n - 1);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const bool inner = x > 0 && y > 0 && x < n - 1 && y < n - 1;
            const double r2 = ((x - c) * (x - c) + (y - c) * (y - c)) / (c * c);
            m.vertices.push_back({double(x), double(y), inner ? bump * (1 - r2) : 0.0});
        }
    auto at = [n](int x, int y) { return uint32_t(x + n * y); };
    for (int y = 0; y + 1 < n; ++y)
        for (int x = 0; x + 1 < n; ++x) {
            m.faces.push_back({at(x, y), at(x + 1, y), at(x + 1, y + 1)});
            m.faces.push_back({at(x, y), at(x + 1, y + 1), at(x, y + 1)});
        }
    return m;
}

std::vector<uint8_t> inner_vertices(int n) {
    std::vector<uint8_t> f(size_t(n * n), 0);
    for (int y = 1; y < n - 1; ++y)
        for (int x = 1; x < n - 1; ++x) f[size_t(x + n * y)] = 1;
    return f;
}

}  // namespace

TEST(Fair, MembraneOfAPlanarRimIsThePlaneAndTheGridComesBack) {
    const int n = 9;
    const TriangleMesh m = dented_grid(n, 3.0);
    const std::vector<Point> p = membrane_positions(m, inner_vertices(n));
    ASSERT_EQ(p.size(), m.vertices.size());
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            // Each inner vertex of this triangulation has its six neighbours symmetric about it:
            // the membrane is the flat grid itself.
            const Point& q = p[size_t(x + n * y)];
            EXPECT_NEAR(q[0], x, 1e-9);
            EXPECT_NEAR(q[1], y, 1e-9);
            EXPECT_NEAR(q[2], 0.0, 1e-9);
        }
}

TEST(Fair, FixedVerticesDoNotMoveAndATiltedRimGivesItsPlane) {
    const int n = 7;
    TriangleMesh m = dented_grid(n, -2.0);
    for (auto& v : m.vertices) v[2] += 0.5 * v[0];  // the plane z = x / 2, dented below it
    const std::vector<uint8_t> free = inner_vertices(n);
    const std::vector<Point> p = membrane_positions(m, free);
    for (size_t v = 0; v < p.size(); ++v) {
        if (!free[v]) {
            EXPECT_EQ(p[v], m.vertices[v]);
        } else {
            EXPECT_NEAR(p[v][2], 0.5 * p[v][0], 1e-9);  // harmonic: linear functions are reproduced
        }
    }
}

TEST(Fair, NothingFreeChangesNothing) {
    const TriangleMesh m = dented_grid(5, 1.0);
    EXPECT_EQ(membrane_positions(m, std::vector<uint8_t>(m.vertices.size(), 0)), m.vertices);
}

TEST(Fair, BadInputThrows) {
    const TriangleMesh m = dented_grid(5, 1.0);
    EXPECT_THROW(membrane_positions(m, std::vector<uint8_t>(3, 1)), InvalidMesh);
    // Every vertex free: nothing holds the membrane.
    EXPECT_THROW(membrane_positions(m, std::vector<uint8_t>(m.vertices.size(), 1)), InvalidMesh);
    TriangleMesh bad = m;
    bad.faces.push_back({0, 1, 99});
    EXPECT_THROW(membrane_positions(bad, inner_vertices(5)), InvalidMesh);
}

// A hole in a bowl z = k r^2: the thin plate (L(L x) = 0) closes it with the bowl itself, since
// the uniform Laplacian of a quadratic is constant on this grid; the membrane (L x = 0) spans it
// flatter, above the bowl's bottom (the chord over the foramen magnum's basin).
TEST(Fair, ThinPlateKeepsTheBowlTheMembraneFlattens) {
    const int n = 13;
    const double c = 6, k = 0.05;
    TriangleMesh m = dented_grid(n, 0.0);
    std::vector<uint8_t> free(m.vertices.size(), 0);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            Point& v = m.vertices[size_t(x + n * y)];
            v[2] = k * ((x - c) * (x - c) + (y - c) * (y - c));
            if (std::fabs(x - c) <= 3 && std::fabs(y - c) <= 3) {
                free[size_t(x + n * y)] = 1;
                v[2] += 1.0;  // the staircase to be faired
            }
        }
    const std::vector<Point> plate = thin_plate_positions(m, free);
    const std::vector<Point> membrane = membrane_positions(m, free);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const size_t v = size_t(x + n * y);
            const double bowl = k * ((x - c) * (x - c) + (y - c) * (y - c));
            if (!free[v]) {
                EXPECT_EQ(plate[v], m.vertices[v]);
                continue;
            }
            EXPECT_NEAR(plate[v][0], x, 1e-9);
            EXPECT_NEAR(plate[v][1], y, 1e-9);
            EXPECT_NEAR(plate[v][2], bowl, 1e-9);
        }
    const size_t middle = size_t(c + n * c);
    EXPECT_GT(membrane[middle][2], 0.5) << "the membrane spans the chord above the bowl's bottom (0)";
    EXPECT_THROW(thin_plate_positions(m, std::vector<uint8_t>(3, 1)), InvalidMesh);
    EXPECT_THROW(thin_plate_positions(m, std::vector<uint8_t>(m.vertices.size(), 1)), InvalidMesh);
    EXPECT_EQ(thin_plate_positions(m, std::vector<uint8_t>(m.vertices.size(), 0)), m.vertices);
}
