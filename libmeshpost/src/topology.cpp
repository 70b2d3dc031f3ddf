// Combinatorial mesh analysis: edge map, manifoldness, orientation, components, genus.
#include "meshpost/topology.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace meshpost {
namespace {

// ---- Exact collinearity (Shewchuk-style expansion arithmetic; assumes no overflow/underflow) ----

inline void two_sum(double a, double b, double& x, double& y) {
    x = a + b;
    const double bv = x - a;
    const double av = x - bv;
    y = (a - av) + (b - bv);
}

inline void two_diff(double a, double b, double& x, double& y) {
    x = a - b;
    const double bv = a - x;
    const double av = x + bv;
    y = (a - av) + (bv - b);
}

inline void two_product(double a, double b, double& x, double& y) {
    x = a * b;
    y = std::fma(a, b, -x);
}

/// Exact sign of the sum of n doubles (n <= 16) via a growing nonoverlapping expansion.
int exact_sign_of_sum(const double* terms, int n) {
    double e[40];
    double h[40];
    int m = 0;
    for (int i = 0; i < n; ++i) {
        double q = terms[i];
        int k = 0;
        for (int j = 0; j < m; ++j) {
            double s, err;
            two_sum(q, e[j], s, err);
            if (err != 0.0) h[k++] = err;
            q = s;
        }
        if (q != 0.0 || k == 0) h[k++] = q;
        std::copy(h, h + k, e);
        m = k;
    }
    if (m == 0) return 0;
    return (e[m - 1] > 0) - (e[m - 1] < 0);
}

/// Exact sign of (bu-au)(cv-av) - (bv-av)(cu-au): the orientation of a 2D projection.
int orient2d_sign(double au, double av, double bu, double bv, double cu, double cv) {
    const double left = (bu - au) * (cv - av);
    const double right = (bv - av) * (cu - au);
    const double det = left - right;
    const double bound = 3.3306690738754716e-16 * (std::fabs(left) + std::fabs(right));  // Shewchuk ccwerrboundA
    if (std::fabs(det) > bound) return (det > 0) - (det < 0);
    // Exact: each difference is a two-term expansion, each product of expansions four two-terms.
    double d[4][2];
    two_diff(bu, au, d[0][0], d[0][1]);
    two_diff(cv, av, d[1][0], d[1][1]);
    two_diff(bv, av, d[2][0], d[2][1]);
    two_diff(cu, au, d[3][0], d[3][1]);
    double terms[16];
    int n = 0;
    for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) {
            two_product(d[0][i], d[1][j], terms[n], terms[n + 1]);
            n += 2;
            two_product(-d[2][i], d[3][j], terms[n], terms[n + 1]);
            n += 2;
        }
    }
    return exact_sign_of_sum(terms, n);
}

/// True when the three points are exactly collinear (or coincide), or a coordinate is not finite.
bool exactly_collinear(const Point& a, const Point& b, const Point& c) {
    for (int i = 0; i < 3; ++i)
        if (!std::isfinite(a[i]) || !std::isfinite(b[i]) || !std::isfinite(c[i])) return true;
    // Collinear iff the cross product vanishes, i.e. all three axis projections are degenerate.
    for (int axis = 0; axis < 3; ++axis) {
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        if (orient2d_sign(a[u], a[v], b[u], b[v], c[u], c[v]) != 0) return false;
    }
    return true;
}

// ---- Union-find ----

class UnionFind {
public:
    explicit UnionFind(size_t n) : parent_(n) {
        for (size_t i = 0; i < n; ++i) parent_[i] = static_cast<uint32_t>(i);
    }
    uint32_t find(uint32_t x) {
        while (parent_[x] != x) {
            parent_[x] = parent_[parent_[x]];
            x = parent_[x];
        }
        return x;
    }
    /// Returns true when two different sets were merged.
    bool unite(uint32_t a, uint32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) return false;
        if (a < b) parent_[b] = a;
        else parent_[a] = b;
        return true;
    }

private:
    std::vector<uint32_t> parent_;
};

// Half-edge h = 3f + k goes from faces[f][k] to faces[f][(k + 1) % 3]; `other` is its larger endpoint.
struct HalfEdge {
    uint32_t other;
    uint32_t he;
};

// An undirected edge: a face of it, and whether it is a boundary or non-manifold edge.
struct EdgeInfo {
    uint32_t face;
    bool bad;
};

// Throws InvalidMesh for more faces than 32-bit corner indices hold or an index beyond the vertices.
void check_indices(const TriangleMesh& mesh, const char* fn) {
    const size_t nv = mesh.vertices.size(), nf = mesh.faces.size();
    if (nf > (static_cast<size_t>(UINT32_MAX) - 3) / 3)
        throw InvalidMesh(std::string(fn) + ": too many faces (" + std::to_string(nf) + ") for 32-bit corner indices");
    const size_t f = first_face_with_bad_index(mesh);
    if (f == nf) return;
    for (uint32_t v : mesh.faces[f])
        if (v >= nv)
            throw InvalidMesh(std::string(fn) + ": face " + std::to_string(f) + " references vertex " +
                              std::to_string(v) + " but the mesh has " + std::to_string(nv) + " vertices");
}

// Counts the faces with a repeated index (degenerate) and the isolated vertices; returns per face
// whether it takes part in the combinatorial analysis (those with a repeated index do not).
std::vector<uint8_t> valid_faces(const TriangleMesh& mesh, TopologyReport& r) {
    const size_t nv = mesh.vertices.size(), nf = mesh.faces.size();
    std::vector<uint8_t> used(nv, 0);
    std::vector<uint8_t> valid(nf, 0);
    for (size_t f = 0; f < nf; ++f) {
        const Face& t = mesh.faces[f];
        for (uint32_t v : t) used[v] = 1;
        const bool repeated = t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
        if (repeated) {
            ++r.degenerate_faces;
            continue;
        }
        valid[f] = 1;
    }
    for (size_t v = 0; v < nv; ++v)
        if (!used[v]) ++r.isolated_vertices;
    return valid;
}

// The valid faces' half-edges bucketed by their smaller endpoint (counting sort): those of vertex
// v are hes[start[v] .. start[v + 1]).
void bucket_half_edges(const TriangleMesh& mesh, const std::vector<uint8_t>& valid, std::vector<uint32_t>& start,
                       std::vector<HalfEdge>& hes) {
    const size_t nv = mesh.vertices.size(), nf = mesh.faces.size();
    start.assign(nv + 1, 0);
    for (size_t f = 0; f < nf; ++f) {
        if (!valid[f]) continue;
        const Face& t = mesh.faces[f];
        for (int k = 0; k < 3; ++k) ++start[std::min(t[k], t[(k + 1) % 3]) + 1];
    }
    for (size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
    hes.assign(start[nv], HalfEdge{});
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t f = 0; f < nf; ++f) {
        if (!valid[f]) continue;
        const Face& t = mesh.faces[f];
        for (uint32_t k = 0; k < 3; ++k) {
            const uint32_t a = t[k], b = t[(k + 1) % 3];
            hes[fill[std::min(a, b)]++] = {std::max(a, b), static_cast<uint32_t>(3 * f) + k};
        }
    }
}

// Each bucket sorted by the larger endpoint: runs of equal (min, max) are the undirected edges.
// Unites the faces along each edge, and at a manifold edge the corners of both faces at each
// endpoint (one fan; `merges` counts the successful unions per vertex); counts boundary,
// non-manifold and inconsistently oriented edges. Returns the edges.
std::vector<EdgeInfo> walk_edges(const TriangleMesh& mesh, const std::vector<uint32_t>& start, std::vector<HalfEdge>& hes,
                                 UnionFind& faces_uf, std::vector<uint32_t>& merges, TopologyReport& r) {
    const size_t nv = mesh.vertices.size();
    UnionFind corners_uf(3 * mesh.faces.size());
    std::vector<EdgeInfo> edges;
    edges.reserve(hes.size() / 2 + 1);
    for (size_t v = 0; v < nv; ++v) {
        const auto first = hes.begin() + start[v], last = hes.begin() + start[v + 1];
        std::sort(first, last, [](const HalfEdge& x, const HalfEdge& y) {
            return x.other != y.other ? x.other < y.other : x.he < y.he;
        });
        for (auto it = first; it != last;) {
            auto run_end = it;
            while (run_end != last && run_end->other == it->other) ++run_end;
            const size_t n = static_cast<size_t>(run_end - it);
            const uint32_t f0 = it->he / 3;
            for (auto jt = it + 1; jt != run_end; ++jt) faces_uf.unite(f0, jt->he / 3);
            edges.push_back({f0, n != 2});
            if (n == 1) {
                ++r.boundary_edges;
            } else if (n > 2) {
                ++r.nonmanifold_edges;
            } else {
                uint32_t corner_min[2], corner_max[2];
                bool forward[2];
                for (int i = 0; i < 2; ++i) {
                    const uint32_t he = (it + i)->he, f = he / 3, k = he % 3;
                    forward[i] = mesh.faces[f][k] == v;  // traverses min -> max
                    const uint32_t ck = 3 * f + k, cnext = 3 * f + (k + 1) % 3;
                    corner_min[i] = forward[i] ? ck : cnext;
                    corner_max[i] = forward[i] ? cnext : ck;
                }
                if (forward[0] == forward[1]) ++r.inconsistent_edges;
                if (corners_uf.unite(corner_min[0], corner_min[1])) ++merges[v];
                if (corners_uf.unite(corner_max[0], corner_max[1])) ++merges[it->other];
            }
            it = run_end;
        }
    }
    return edges;
}

// The components (faces joined across edges) and the genus summed over those that are manifold:
// per component V - E + F = 2 - 2g. `corners`: valid corners per vertex, `any_face` one face of
// each, `vertex_bad`: non-manifold vertices.
void components_and_genus(const TriangleMesh& mesh, const std::vector<uint8_t>& valid, UnionFind& faces_uf,
                          const std::vector<EdgeInfo>& edges, const std::vector<uint32_t>& corners,
                          const std::vector<uint32_t>& any_face, const std::vector<uint8_t>& vertex_bad,
                          TopologyReport& r) {
    const size_t nv = mesh.vertices.size(), nf = mesh.faces.size();
    std::vector<uint32_t> comp_of_root(nf, UINT32_MAX);
    std::vector<uint32_t> comp(nf, UINT32_MAX);
    size_t ncomp = 0;
    for (size_t f = 0; f < nf; ++f) {
        if (!valid[f]) continue;
        const uint32_t root = faces_uf.find(static_cast<uint32_t>(f));
        if (comp_of_root[root] == UINT32_MAX) comp_of_root[root] = static_cast<uint32_t>(ncomp++);
        comp[f] = comp_of_root[root];
    }
    r.components = ncomp;
    std::vector<int64_t> V(ncomp, 0), E(ncomp, 0), F(ncomp, 0);
    std::vector<uint8_t> comp_bad(ncomp, 0);
    for (size_t f = 0; f < nf; ++f) {
        if (!valid[f]) continue;
        ++F[comp[f]];
        for (uint32_t v : mesh.faces[f])
            if (vertex_bad[v]) comp_bad[comp[f]] = 1;
    }
    for (const EdgeInfo& e : edges) {
        ++E[comp[e.face]];
        if (e.bad) comp_bad[comp[e.face]] = 1;
    }
    for (size_t v = 0; v < nv; ++v)
        if (corners[v] > 0) ++V[comp[any_face[v]]];
    for (size_t c = 0; c < ncomp; ++c) {
        if (comp_bad[c]) continue;
        const int64_t chi = V[c] - E[c] + F[c];
        r.genus += static_cast<long>((2 - chi) / 2);
    }
}

// The faces with distinct indices whose points are exactly collinear (count_collinear_faces).
size_t collinear_faces(const TriangleMesh& mesh) {
    const int64_t nf = int64_t(mesh.faces.size());
    size_t n = 0;
#pragma omp parallel for schedule(static) reduction(+ : n)
    for (int64_t f = 0; f < nf; ++f) {
        const Face& t = mesh.faces[size_t(f)];
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
        n += exactly_collinear(mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]);
    }
    return n;
}

// analyze_connectivity, the indices checked.
TopologyReport connectivity(const TriangleMesh& mesh) {
    TopologyReport r;
    const size_t nv = mesh.vertices.size();
    const size_t nf = mesh.faces.size();
    r.vertices = nv;
    r.faces = nf;
    const std::vector<uint8_t> valid = valid_faces(mesh, r);
    std::vector<uint32_t> start;
    std::vector<HalfEdge> hes;
    bucket_half_edges(mesh, valid, start, hes);
    UnionFind faces_uf(nf);
    std::vector<uint32_t> merges(nv, 0);  // successful corner unions at each vertex
    const std::vector<EdgeInfo> edges = walk_edges(mesh, start, hes, faces_uf, merges, r);
    r.edges = edges.size();

    // Fans per vertex = corners - successful unions among them.
    std::vector<uint32_t> corners(nv, 0);
    std::vector<uint32_t> any_face(nv, 0);
    for (size_t f = 0; f < nf; ++f) {
        if (!valid[f]) continue;
        for (uint32_t v : mesh.faces[f]) {
            ++corners[v];
            any_face[v] = static_cast<uint32_t>(f);
        }
    }
    std::vector<uint8_t> vertex_bad(nv, 0);
    for (size_t v = 0; v < nv; ++v) {
        if (corners[v] > 0 && corners[v] - merges[v] > 1) {
            ++r.nonmanifold_vertices;
            vertex_bad[v] = 1;
        }
    }
    components_and_genus(mesh, valid, faces_uf, edges, corners, any_face, vertex_bad, r);

    r.closed = r.boundary_edges == 0 && nf > 0;
    r.manifold = r.nonmanifold_edges == 0 && r.nonmanifold_vertices == 0;
    r.oriented = r.inconsistent_edges == 0 && r.manifold;
    return r;
}

}  // namespace

TopologyReport analyze_topology(const TriangleMesh& mesh) {
    check_indices(mesh, "analyze_topology");
    TopologyReport r = connectivity(mesh);
    r.degenerate_faces += collinear_faces(mesh);
    return r;
}

TopologyReport analyze_connectivity(const TriangleMesh& mesh) {
    check_indices(mesh, "analyze_connectivity");
    return connectivity(mesh);
}

size_t count_collinear_faces(const TriangleMesh& mesh) {
    check_indices(mesh, "count_collinear_faces");
    return collinear_faces(mesh);
}

bool is_closed_manifold(const TopologyReport& r) {
    return r.closed && r.manifold && r.oriented && r.degenerate_faces == 0 && r.faces > 0;
}

long genus_within_ball(const TriangleMesh& mesh, const Point& centre, double radius) {
    const size_t nv = mesh.vertices.size();
    std::vector<uint8_t> inside(nv, 0);
    const double r2 = radius * radius;
    for (size_t v = 0; v < nv; ++v) {
        const Point& p = mesh.vertices[v];
        const double dx = p[0] - centre[0], dy = p[1] - centre[1], dz = p[2] - centre[2];
        inside[v] = dx * dx + dy * dy + dz * dz <= r2;
    }
    // Edges of the patch's faces as sorted (a, b) pairs; each one's face count.
    std::vector<std::pair<uint32_t, uint32_t>> edges;
    size_t faces = 0;
    for (const Face& f : mesh.faces) {
        if (f[0] >= nv || f[1] >= nv || f[2] >= nv)
            throw InvalidMesh("genus_within_ball: a face references a vertex index >= " + std::to_string(nv));
        if (!inside[f[0]] || !inside[f[1]] || !inside[f[2]]) continue;
        ++faces;
        for (int k = 0; k < 3; ++k) edges.push_back(std::minmax(f[k], f[(k + 1) % 3]));
    }
    if (faces == 0) return 0;
    std::sort(edges.begin(), edges.end());
    // Union-find over vertices: all edges join components; boundary edges (used once) join loops.
    std::vector<uint32_t> comp(nv), loop(nv);
    for (uint32_t v = 0; v < nv; ++v) comp[v] = loop[v] = v;
    auto find = [](std::vector<uint32_t>& parent, uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    std::vector<uint8_t> used(nv, 0), on_boundary(nv, 0);
    long n_edges = 0;
    for (size_t i = 0; i < edges.size();) {
        size_t j = i;
        while (j < edges.size() && edges[j] == edges[i]) ++j;
        const auto [a, b] = edges[i];
        ++n_edges;
        used[a] = used[b] = 1;
        comp[find(comp, a)] = find(comp, b);
        if (j - i == 1) {
            on_boundary[a] = on_boundary[b] = 1;
            loop[find(loop, a)] = find(loop, b);
        }
        i = j;
    }
    long n_vertices = 0, components = 0, loops = 0;
    for (uint32_t v = 0; v < nv; ++v) {
        if (!used[v]) continue;
        ++n_vertices;
        if (find(comp, v) == v) ++components;
        if (on_boundary[v] && find(loop, v) == v) ++loops;
    }
    const long chi = n_vertices - n_edges + long(faces);
    return (2 * components - loops - chi) / 2;
}

}  // namespace meshpost
