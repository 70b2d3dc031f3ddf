// Surface deviation: exact nearest-triangle distances from a TriangleGrid, with CGAL's AABB tree
// (GPL target) for the samples that lie too far from the other surface for the grid's ring search.
// See deviation.h for the sampling scheme and the error bound.
#include "meshpost/deviation.h"
#include "meshpost/triangle_grid.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>
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

/// The faces of a mesh that are not degenerate (zero area); throws when every one is.
TriangleMesh nondegenerate(const TriangleMesh& m) {
    TriangleMesh out;
    out.vertices = m.vertices;
    out.faces.reserve(m.faces.size());
    for (const Face& f : m.faces)
        if (tri_area(m.vertices[f[0]], m.vertices[f[1]], m.vertices[f[2]]) > 0) out.faces.push_back(f);
    if (out.faces.empty())
        throw InvalidMesh("surface_deviation: every face of a mesh is degenerate (zero area)");
    return out;
}

/// The distances from points to a surface: exact, from the grid's ring search, or from CGAL's
/// AABB tree for the points that search leaves open (farther than kMaxRings cells from the
/// surface).
class SurfaceDistance {
public:
    explicit SurfaceDistance(const TriangleMesh& m) : mesh_(nondegenerate(m)), grid_(mesh_, cell_size(mesh_)) {}

    std::vector<double> operator()(const std::vector<Point>& pts) const {
        std::vector<double> d(pts.size(), -1.0);
        const long n = static_cast<long>(pts.size());
        long open = 0;
#pragma omp parallel reduction(+ : open)
        {
            uint32_t hint = UINT32_MAX;  // the previous point's triangle: only speeds the search up
#pragma omp for schedule(static)
            for (long i = 0; i < n; ++i) {
                double d2;
                if (grid_.nearest(pts[size_t(i)].data(), kMaxRings, d2, hint)) d[size_t(i)] = std::sqrt(d2);
                else ++open;
            }
        }
        if (open == 0) return d;
        std::vector<Tri> tris;
        tris.reserve(mesh_.faces.size());
        for (const Face& f : mesh_.faces) {
            const Point &a = mesh_.vertices[f[0]], &b = mesh_.vertices[f[1]], &c = mesh_.vertices[f[2]];
            tris.emplace_back(P3(a[0], a[1], a[2]), P3(b[0], b[1], b[2]), P3(c[0], c[1], c[2]));
        }
        Tree tree(tris.begin(), tris.end());
        tree.build();
        tree.accelerate_distance_queries();
#pragma omp parallel for schedule(dynamic, 64)
        for (long i = 0; i < n; ++i)
            if (d[size_t(i)] < 0) {
                const Point& p = pts[size_t(i)];
                d[size_t(i)] = std::sqrt(tree.squared_distance(P3(p[0], p[1], p[2])));
            }
        return d;
    }

private:
    /// Cells of the mean edge length (0.5 to 1.5 of it timed alike on CThead): a point on or near
    /// the surface finds its nearest triangle within one ring.
    static double cell_size(const TriangleMesh& m) {
        double sum = 0;
        for (const Face& f : m.faces) sum += dist(m.vertices[f[0]], m.vertices[f[1]]);
        const double mean = sum / double(m.faces.size());
        return mean > 0 ? mean : 1.0;
    }

    static constexpr int kMaxRings = 3;
    TriangleMesh mesh_;
    TriangleGrid grid_;
};

struct Samples {
    std::vector<Point> points;
    std::vector<double> weights;
    double error_bound = 0;
};

/// (2/3) of the longest median of triangle abc: the largest distance from its centroid to a
/// point of it.
double centroid_reach(const Point& a, const Point& b, const Point& c) {
    const double ab = dist(a, b), bc = dist(b, c), ca = dist(c, a);
    const double ma = 0.5 * std::sqrt(std::max(0.0, 2 * ab * ab + 2 * ca * ca - bc * bc));
    const double mb = 0.5 * std::sqrt(std::max(0.0, 2 * ab * ab + 2 * bc * bc - ca * ca));
    const double mc = 0.5 * std::sqrt(std::max(0.0, 2 * bc * bc + 2 * ca * ca - ab * ab));
    return (2.0 / 3.0) * std::max({ma, mb, mc});
}

/// Splits per face at spacing h, n = ceil(longest edge / h) (at least 1), and the error bound
/// they give: the largest centroid_reach(face) / n. Throws when they would make more than
/// kMaxSamples samples.
double spacing_bound(const TriangleMesh& m, double h) {
    size_t total = 0;
    double bound = 0;
    for (const Face& f : m.faces) {
        const Point &a = m.vertices[f[0]], &b = m.vertices[f[1]], &c = m.vertices[f[2]];
        const double longest = std::max({dist(a, b), dist(b, c), dist(c, a)});
        const double n = std::max(1.0, std::ceil(longest / h));
        if (n * n > double(kMaxSamples) || total + size_t(n * n) > kMaxSamples)
            throw std::invalid_argument("surface_deviation: sample spacing " + std::to_string(h) +
                                        " mm needs more than 100 million samples");
        total += static_cast<size_t>(n * n);
        bound = std::max(bound, centroid_reach(a, b, c) / n);
    }
    return bound;
}

/// Samples of m: each face split into n x n with the smallest n (at most its split at spacing h)
/// that keeps its centroid_reach / n within `bound`.
Samples sample(const TriangleMesh& m, double h, double bound) {
    std::vector<uint32_t> nsub(m.faces.size());
    size_t total = 0;
    for (size_t f = 0; f < m.faces.size(); ++f) {
        const Point &a = m.vertices[m.faces[f][0]], &b = m.vertices[m.faces[f][1]], &c = m.vertices[m.faces[f][2]];
        const double longest = std::max({dist(a, b), dist(b, c), dist(c, a)});
        const double at_h = std::max(1.0, std::ceil(longest / h));  // spacing_bound() checked the total
        const double reach = centroid_reach(a, b, c);
        const double n = bound > 0 ? std::min(at_h, std::max(1.0, std::ceil(reach / bound))) : at_h;
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
        // The sub-triangles are similar to the face, scaled by 1/n.
        s.error_bound = std::max(s.error_bound, centroid_reach(a, b, c) / double(n));
        auto emit = [&](double u, double v) {  // barycentric: a + u (b - a) + v (c - a)
            s.points.push_back({a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]),
                                a[1] + u * (b[1] - a[1]) + v * (c[1] - a[1]),
                                a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2])});
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

/// Area-weighted statistics; uniform weights when the weights sum to zero. Median and p95 only
/// with `quantiles`.
DistanceStats stats(const std::vector<double>& d, std::vector<double> w, bool quantiles) {
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
    if (!quantiles) return s;
    // The weighted quantile q: the distance of the first sample, in ascending order of distance
    // (ties in sample order), at which the cumulative weight reaches q W. Found by bisection with
    // nth_element (linear time; a full sort took a second for 3 million samples).
    std::vector<std::pair<double, size_t>> order(d.size());
    for (size_t i = 0; i < d.size(); ++i) order[i] = {d[i], i};
    auto quantile = [&](double q) {
        size_t lo = 0, hi = order.size();
        double before = 0;  // weight of the samples ahead of order[lo]
        while (hi - lo > 1) {
            const size_t mid = lo + (hi - lo) / 2;
            std::nth_element(order.begin() + long(lo), order.begin() + long(mid), order.begin() + long(hi));
            double left = 0;
            for (size_t k = lo; k < mid; ++k) left += w[order[k].second];
            if (before + left >= q * W) {
                hi = mid;
            } else {
                before += left;
                lo = mid;
            }
        }
        return order[lo].first;
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

    // The bound that spacing h gives on the worst face of either mesh is the bound for both, and
    // every face is split no finer than it needs to stay within it (at spacing h, faces whose
    // edges fall just above a multiple of h, and well-shaped faces, were split finer than the
    // worst face needed: 18 % of the samples on a simplified CThead endocast and its input).
    const double bound = std::max(spacing_bound(a, h), spacing_bound(b, h));
    const SurfaceDistance to_a(a), to_b(b);
    Samples sa = sample(a, h, bound);
    std::vector<double> da = to_b(sa.points);
    sa.points = {};
    Samples sb = sample(b, h, bound);
    std::vector<double> db = to_a(sb.points);
    sb.points = {};

    r.a_to_b = stats(da, sa.weights, params.quantiles);
    r.b_to_a = stats(db, sb.weights, params.quantiles);
    r.hausdorff_mm = std::max(r.a_to_b.max, r.b_to_a.max);
    r.sampling_error_bound_mm = std::max(sa.error_bound, sb.error_bound);
    if (params.vertex_distances) {
        r.a_vertex_distances = to_b(a.vertices);
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
