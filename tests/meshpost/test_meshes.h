#pragma once
// Meshes generated in code for the meshpost tests, and a helper to run code with a thread count.
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost::test {

/// Axis-aligned cube [0, side]^3 (plus `offset`), 8 vertices, 12 outward-oriented triangles.
inline TriangleMesh cube(double side = 1.0, Point offset = {0, 0, 0}) {
    TriangleMesh m;
    for (int i = 0; i < 8; ++i)
        m.vertices.push_back({offset[0] + side * (i & 1), offset[1] + side * ((i >> 1) & 1),
                              offset[2] + side * ((i >> 2) & 1)});
    m.faces = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
               {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
    return m;
}

/// Regular tetrahedron-like solid with corners `offset` + {0, e_x, e_y, e_z} * size, outward.
inline TriangleMesh tetrahedron(double size = 1.0, Point offset = {0, 0, 0}) {
    TriangleMesh m;
    m.vertices = {offset,
                  {offset[0] + size, offset[1], offset[2]},
                  {offset[0], offset[1] + size, offset[2]},
                  {offset[0], offset[1], offset[2] + size}};
    m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
}

/// Icosphere: icosahedron subdivided `level` times, vertices projected onto the sphere,
/// faces oriented outward. 20 * 4^level faces.
inline TriangleMesh icosphere(double radius, int level, Point centre = {0, 0, 0}) {
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<Point> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                            {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<Face> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                           {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                           {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    auto normalize = [](Point p) {
        const double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        return Point{p[0] / n, p[1] / n, p[2] / n};
    };
    for (Point& p : v) p = normalize(p);
    for (int l = 0; l < level; ++l) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto key = std::minmax(a, b);
            const auto it = mid.find(key);
            if (it != mid.end()) return it->second;
            const uint32_t idx = static_cast<uint32_t>(v.size());
            v.push_back(normalize({v[a][0] + v[b][0], v[a][1] + v[b][1], v[a][2] + v[b][2]}));
            mid.emplace(key, idx);
            return idx;
        };
        std::vector<Face> next;
        next.reserve(f.size() * 4);
        for (const Face& tri : f) {
            const uint32_t ab = midpoint(tri[0], tri[1]), bc = midpoint(tri[1], tri[2]), ca = midpoint(tri[2], tri[0]);
            next.push_back({tri[0], ab, ca});
            next.push_back({tri[1], bc, ab});
            next.push_back({tri[2], ca, bc});
            next.push_back({ab, bc, ca});
        }
        f.swap(next);
    }
    TriangleMesh m;
    m.vertices.reserve(v.size());
    for (const Point& p : v)
        m.vertices.push_back({centre[0] + radius * p[0], centre[1] + radius * p[1], centre[2] + radius * p[2]});
    // Orient every face outward (the unit sphere is convex and centred on the origin).
    for (Face& tri : f) {
        const Point &a = v[tri[0]], &b = v[tri[1]], &c = v[tri[2]];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        if (n[0] * (a[0] + b[0] + c[0]) + n[1] * (a[1] + b[1] + c[1]) + n[2] * (a[2] + b[2] + c[2]) < 0)
            std::swap(tri[1], tri[2]);
    }
    m.faces = std::move(f);
    return m;
}

/// Torus around the z axis (major radius R, minor radius r) as an nu x nv quad grid split into
/// triangles, outward oriented. Genus 1.
inline TriangleMesh torus(double R, double r, uint32_t nu = 24, uint32_t nv = 12, Point offset = {0, 0, 0}) {
    TriangleMesh m;
    const double pi = std::acos(-1.0);
    for (uint32_t i = 0; i < nu; ++i) {
        const double u = 2 * pi * i / nu;
        for (uint32_t j = 0; j < nv; ++j) {
            const double w = 2 * pi * j / nv;
            m.vertices.push_back({offset[0] + (R + r * std::cos(w)) * std::cos(u),
                                  offset[1] + (R + r * std::cos(w)) * std::sin(u), offset[2] + r * std::sin(w)});
        }
    }
    auto id = [&](uint32_t i, uint32_t j) { return (i % nu) * nv + (j % nv); };
    for (uint32_t i = 0; i < nu; ++i) {
        for (uint32_t j = 0; j < nv; ++j) {
            // With u around z and w around the tube, (du, dw) is outward for this winding.
            m.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    }
    return m;
}

/// Faces reversed (inward orientation for a closed outward mesh).
inline TriangleMesh flipped(TriangleMesh m) {
    for (Face& f : m.faces) std::swap(f[1], f[2]);
    return m;
}

/// Disjoint union of two meshes (indices of `b` shifted).
inline TriangleMesh merged(const TriangleMesh& a, const TriangleMesh& b) {
    TriangleMesh m = a;
    const uint32_t shift = static_cast<uint32_t>(a.vertices.size());
    m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (const Face& f : b.faces) m.faces.push_back({f[0] + shift, f[1] + shift, f[2] + shift});
    return m;
}

/// f() run with `threads` OpenMP threads (the previous count restored afterwards).
template <class F>
auto with_threads(int threads, F&& f) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    auto r = f();
    omp_set_num_threads(saved);
    return r;
}

}  // namespace meshpost::test
