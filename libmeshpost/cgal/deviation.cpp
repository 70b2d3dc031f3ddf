// Surface deviation with CGAL's AABB tree (GPL target). See deviation.h for the sampling scheme and
// the error bound.
#include "meshpost/deviation.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

namespace meshpost {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using P3 = Kernel::Point_3;
using Tri = Kernel::Triangle_3;
using Primitive = CGAL::AABB_triangle_primitive<Kernel, std::vector<Tri>::const_iterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;

constexpr size_t kMaxSamples = 100'000'000;

void check_mesh(const TriangleMesh& m, const char* name) {
    if (m.faces.empty()) throw InvalidMesh(std::string("surface_deviation: mesh ") + name + " has no faces");
    const size_t nv = m.vertices.size();
    for (size_t f = 0; f < m.faces.size(); ++f)
        for (uint32_t v : m.faces[f])
            if (v >= nv)
                throw InvalidMesh(std::string("surface_deviation: mesh ") + name + ": face " + std::to_string(f) +
                                  " references vertex " + std::to_string(v) + " of " + std::to_string(nv));
    for (size_t v = 0; v < nv; ++v)
        for (double c : m.vertices[v])
            if (!std::isfinite(c))
                throw InvalidMesh(std::string("surface_deviation: mesh ") + name + ": vertex " + std::to_string(v) +
                                  " has a non-finite coordinate");
}

double dist(const Point& a, const Point& b) {
    return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

double tri_area(const Point& a, const Point& b, const Point& c) {
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    return 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

double area(const TriangleMesh& m) {
    double s = 0;
    for (const Face& f : m.faces) s += tri_area(m.vertices[f[0]], m.vertices[f[1]], m.vertices[f[2]]);
    return s;
}

/// The triangles of a mesh that are not degenerate (all of them when every one is degenerate, so
/// that the tree is never empty; CGAL projects onto degenerate triangles as segments then).
std::vector<Tri> triangles(const TriangleMesh& m) {
    std::vector<Tri> out, all;
    out.reserve(m.faces.size());
    for (const Face& f : m.faces) {
        const Point &a = m.vertices[f[0]], &b = m.vertices[f[1]], &c = m.vertices[f[2]];
        Tri t(P3(a[0], a[1], a[2]), P3(b[0], b[1], b[2]), P3(c[0], c[1], c[2]));
        if (!t.is_degenerate()) out.push_back(t);
    }
    if (out.empty())
        throw InvalidMesh("surface_deviation: every face of a mesh is degenerate (zero area)");
    return out;
}

struct Samples {
    std::vector<P3> points;
    std::vector<double> weights;
    double error_bound = 0;
};

Samples sample(const TriangleMesh& m, double h) {
    // First pass: counts (to reserve and to refuse absurd sizes before allocating).
    size_t total = 0;
    std::vector<uint32_t> nsub(m.faces.size());
    for (size_t f = 0; f < m.faces.size(); ++f) {
        const Point &a = m.vertices[m.faces[f][0]], &b = m.vertices[m.faces[f][1]], &c = m.vertices[m.faces[f][2]];
        const double longest = std::max({dist(a, b), dist(b, c), dist(c, a)});
        const double n = std::max(1.0, std::ceil(longest / h));
        if (n * n > double(kMaxSamples) || total + size_t(n * n) > kMaxSamples)
            throw std::invalid_argument("surface_deviation: sample spacing " + std::to_string(h) +
                                        " mm needs more than 100 million samples");
        nsub[f] = static_cast<uint32_t>(n);
        total += static_cast<size_t>(n * n);
    }
    Samples s;
    s.points.reserve(total);
    s.weights.reserve(total);
    for (size_t f = 0; f < m.faces.size(); ++f) {
        const Point &a = m.vertices[m.faces[f][0]], &b = m.vertices[m.faces[f][1]], &c = m.vertices[m.faces[f][2]];
        const uint32_t n = nsub[f];
        const double w = tri_area(a, b, c) / double(n) / double(n);
        // Longest median of the sub-triangle (similar to the face, scaled by 1/n); 2/3 of it is the
        // largest distance from the centroid to a point of the sub-triangle.
        const double ab = dist(a, b), bc = dist(b, c), ca = dist(c, a);
        const double ma = 0.5 * std::sqrt(std::max(0.0, 2 * ab * ab + 2 * ca * ca - bc * bc));
        const double mb = 0.5 * std::sqrt(std::max(0.0, 2 * ab * ab + 2 * bc * bc - ca * ca));
        const double mc = 0.5 * std::sqrt(std::max(0.0, 2 * bc * bc + 2 * ca * ca - ab * ab));
        s.error_bound = std::max(s.error_bound, (2.0 / 3.0) * std::max({ma, mb, mc}) / double(n));
        auto emit = [&](double u, double v) {  // barycentric: a + u (b - a) + v (c - a)
            s.points.emplace_back(a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]),
                                  a[1] + u * (b[1] - a[1]) + v * (c[1] - a[1]),
                                  a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]));
            s.weights.push_back(w);
        };
        for (uint32_t i = 0; i < n; ++i)
            for (uint32_t j = 0; i + j < n; ++j) {
                emit((i + 1.0 / 3.0) / n, (j + 1.0 / 3.0) / n);                      // upright
                if (i + j + 2 <= n) emit((i + 2.0 / 3.0) / n, (j + 2.0 / 3.0) / n);  // inverted
            }
    }
    return s;
}

std::vector<double> distances(const Tree& tree, const std::vector<P3>& pts) {
    std::vector<double> d(pts.size());
    const long n = static_cast<long>(pts.size());
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) d[i] = std::sqrt(tree.squared_distance(pts[i]));
    return d;
}

/// Area-weighted statistics; uniform weights when the weights sum to zero.
DistanceStats stats(const std::vector<double>& d, std::vector<double> w) {
    DistanceStats s;
    s.samples = d.size();
    if (d.empty()) return s;
    double W = 0;
    for (double x : w) W += x;
    if (!(W > 0)) {
        std::fill(w.begin(), w.end(), 1.0);
        W = double(w.size());
    }
    double sum = 0, sum2 = 0;
    for (size_t i = 0; i < d.size(); ++i) {
        sum += w[i] * d[i];
        sum2 += w[i] * d[i] * d[i];
        s.max = std::max(s.max, d[i]);
    }
    s.mean = sum / W;
    s.rms = std::sqrt(sum2 / W);
    std::vector<size_t> order(d.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(), [&](size_t x, size_t y) { return d[x] < d[y] || (d[x] == d[y] && x < y); });
    auto quantile = [&](double q) {
        double cum = 0;
        for (size_t k = 0; k < order.size(); ++k) {
            cum += w[order[k]];
            if (cum >= q * W) return d[order[k]];
        }
        return d[order.back()];
    };
    s.median = quantile(0.5);
    s.p95 = quantile(0.95);
    return s;
}

}  // namespace

DeviationResult surface_deviation(const TriangleMesh& a, const TriangleMesh& b, const DeviationParams& params) {
    check_mesh(a, "A");
    check_mesh(b, "B");
    if (!(params.sample_spacing_mm >= 0.0) || !std::isfinite(params.sample_spacing_mm))
        throw std::invalid_argument("surface_deviation: sample spacing must be >= 0 mm (0 = automatic)");
    DeviationResult r;
    double h = params.sample_spacing_mm;
    if (h == 0.0) {
        const double target = double(std::max<size_t>(params.target_samples, 1));
        h = std::sqrt(std::max(area(a), area(b)) / target);
        if (!(h > 0)) h = 1.0;  // zero-area meshes: one sample per face anyway
    }
    r.sample_spacing_mm = h;

    const std::vector<Tri> ta = triangles(a), tb = triangles(b);
    Tree tree_a(ta.begin(), ta.end()), tree_b(tb.begin(), tb.end());
    tree_a.build();
    tree_b.build();
    tree_a.accelerate_distance_queries();
    tree_b.accelerate_distance_queries();

    Samples sa = sample(a, h);
    std::vector<double> da = distances(tree_b, sa.points);
    sa.points = {};
    Samples sb = sample(b, h);
    std::vector<double> db = distances(tree_a, sb.points);
    sb.points = {};

    r.a_to_b = stats(da, sa.weights);
    r.b_to_a = stats(db, sb.weights);
    r.hausdorff_mm = std::max(r.a_to_b.max, r.b_to_a.max);
    r.sampling_error_bound_mm = std::max(sa.error_bound, sb.error_bound);
    if (params.vertex_distances) {
        std::vector<P3> vp;
        vp.reserve(a.vertices.size());
        for (const Point& p : a.vertices) vp.emplace_back(p[0], p[1], p[2]);
        r.a_vertex_distances = distances(tree_b, vp);
    }
    if (params.keep_samples) {
        r.a_distances = std::move(da);
        r.a_weights = std::move(sa.weights);
        r.b_distances = std::move(db);
        r.b_weights = std::move(sb.weights);
    }
    return r;
}

}  // namespace meshpost
