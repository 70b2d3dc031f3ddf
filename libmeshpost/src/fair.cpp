// Membrane (uniform Laplace) fairing of a set of vertices with the others fixed (fair.h).
#include "meshpost/fair.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <string>
#include <utility>

namespace meshpost {
namespace {

// Solves A x = rhs (symmetric, one row per free vertex, numbered by `unknown`) and returns the
// mesh's vertices with the free ones moved to x; `who` names the caller in the error.
std::vector<Point> solved_positions(const TriangleMesh& mesh, const std::vector<int64_t>& unknown,
                                    const Eigen::SparseMatrix<double>& A, const Eigen::MatrixXd& rhs, const char* who) {
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
    const std::string no_fixed = std::string(who) + ": a group of free vertices has no fixed neighbour";
    if (solver.info() != Eigen::Success) throw InvalidMesh(no_fixed);
    const Eigen::MatrixXd x = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !x.allFinite()) throw InvalidMesh(no_fixed);
    std::vector<Point> out = mesh.vertices;
    for (size_t v = 0; v < out.size(); ++v)
        if (unknown[v] >= 0)
            for (int c = 0; c < 3; ++c) out[v][size_t(c)] = x(unknown[v], c);
    return out;
}

}  // namespace

std::vector<Point> membrane_positions(const TriangleMesh& mesh, const std::vector<uint8_t>& free_vertex) {
    const size_t nv = mesh.vertices.size();
    if (free_vertex.size() != nv)
        throw InvalidMesh("membrane_positions: " + std::to_string(free_vertex.size()) + " flags for " +
                          std::to_string(nv) + " vertices");
    std::vector<int64_t> unknown(nv, -1);
    int64_t n = 0;
    for (size_t v = 0; v < nv; ++v)
        if (free_vertex[v]) unknown[v] = n++;
    if (n == 0) return mesh.vertices;
    // Each free vertex's edge neighbours, once each (an edge is in two faces of a closed mesh).
    std::vector<std::pair<uint32_t, uint32_t>> edges;
    for (const Face& f : mesh.faces) {
        for (int a = 0; a < 3; ++a) {
            const uint32_t u = f[a], w = f[(a + 1) % 3];
            if (u >= nv || w >= nv) throw InvalidMesh("membrane_positions: a face references a vertex beyond the mesh");
            if (unknown[u] >= 0 || unknown[w] >= 0) edges.emplace_back(std::min(u, w), std::max(u, w));
        }
    }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    std::vector<Eigen::Triplet<double>> t;
    std::vector<double> degree(size_t(n), 0.0);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
    std::vector<uint8_t> anchored(size_t(n), 0);
    for (const auto& [u, w] : edges) {
        for (const auto& [a, b] : {std::pair{u, w}, std::pair{w, u}}) {
            const int64_t i = unknown[a];
            if (i < 0) continue;
            degree[size_t(i)] += 1;
            if (unknown[b] >= 0) {
                t.emplace_back(i, unknown[b], -1.0);
            } else {
                for (int c = 0; c < 3; ++c) rhs(i, c) += mesh.vertices[b][size_t(c)];
                anchored[size_t(i)] = 1;
            }
        }
    }
    for (int64_t i = 0; i < n; ++i) t.emplace_back(i, i, degree[size_t(i)]);
    if (std::find(anchored.begin(), anchored.end(), 1) == anchored.end())
        throw InvalidMesh("membrane_positions: a group of free vertices has no fixed neighbour");
    Eigen::SparseMatrix<double> L(n, n);
    L.setFromTriplets(t.begin(), t.end());
    return solved_positions(mesh, unknown, L, rhs, "membrane_positions");
}

std::vector<Point> thin_plate_positions(const TriangleMesh& mesh, const std::vector<uint8_t>& free_vertex) {
    const size_t nv = mesh.vertices.size();
    if (free_vertex.size() != nv)
        throw InvalidMesh("thin_plate_positions: " + std::to_string(free_vertex.size()) + " flags for " +
                          std::to_string(nv) + " vertices");
    std::vector<int64_t> unknown(nv, -1);
    int64_t n = 0;
    for (size_t v = 0; v < nv; ++v)
        if (free_vertex[v]) unknown[v] = n++;
    if (n == 0) return mesh.vertices;
    std::vector<std::pair<uint32_t, uint32_t>> edges;
    for (const Face& f : mesh.faces)
        for (int a = 0; a < 3; ++a) {
            const uint32_t u = f[a], w = f[(a + 1) % 3];
            if (u >= nv || w >= nv) throw InvalidMesh("thin_plate_positions: a face references a vertex beyond the mesh");
            edges.emplace_back(std::min(u, w), std::max(u, w));
        }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    if (std::none_of(edges.begin(), edges.end(), [&](const auto& e) { return (unknown[e.first] >= 0) != (unknown[e.second] >= 0); }))
        throw InvalidMesh("thin_plate_positions: a group of free vertices has no fixed neighbour");
    // The uniform Laplacian over the whole (sub)mesh, then its square's rows of the free vertices.
    std::vector<Eigen::Triplet<double>> t;
    std::vector<double> degree(nv, 0.0);
    for (const auto& [u, w] : edges) {
        t.emplace_back(int64_t(u), int64_t(w), 1.0);
        t.emplace_back(int64_t(w), int64_t(u), 1.0);
        degree[u] += 1;
        degree[w] += 1;
    }
    for (size_t v = 0; v < nv; ++v) t.emplace_back(int64_t(v), int64_t(v), -degree[v]);
    Eigen::SparseMatrix<double> L{Eigen::Index(nv), Eigen::Index(nv)};
    L.setFromTriplets(t.begin(), t.end());
    const Eigen::SparseMatrix<double> L2 = L * L;
    std::vector<Eigen::Triplet<double>> a;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
    for (int64_t c = 0; c < L2.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(L2, c); it; ++it) {
            const int64_t i = unknown[size_t(it.row())];
            if (i < 0) continue;
            const int64_t j = unknown[size_t(it.col())];
            if (j >= 0) a.emplace_back(i, j, it.value());
            else
                for (int k = 0; k < 3; ++k) rhs(i, k) -= it.value() * mesh.vertices[size_t(it.col())][size_t(k)];
        }
    Eigen::SparseMatrix<double> A(n, n);
    A.setFromTriplets(a.begin(), a.end());
    return solved_positions(mesh, unknown, A, rhs, "thin_plate_positions");
}

}  // namespace meshpost
