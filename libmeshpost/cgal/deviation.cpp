// Surface deviation: exact nearest-triangle distances from a TriangleGrid, with CGAL's AABB tree
// (GPL target) for the samples that lie too far from the other surface for the grid's ring search.
// See deviation.h for the sampling scheme and the error bound.
#include "meshpost/cgal/deviation.h"
#include "meshpost/triangle_grid.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
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
        const Tree& tree = this->tree();
#pragma omp parallel for schedule(dynamic, 64)
        for (long i = 0; i < n; ++i)
            if (d[size_t(i)] < 0) {
                const Point& p = pts[size_t(i)];
                d[size_t(i)] = std::sqrt(tree.squared_distance(P3(p[0], p[1], p[2])));
            }
        return d;
    }

    /// Distance from p to the surface, and its nearest triangle (`tri`; on entry a hint that only
    /// speeds the search up). Thread-safe.
    double nearest(const Point& p, uint32_t& tri) const {
        double d2;
        if (grid_.nearest(p.data(), kMaxRings, d2, tri)) return std::sqrt(d2);
        const P3 q(p[0], p[1], p[2]);
        const auto hit = tree().closest_point_and_primitive(q);
        tri = uint32_t(hit.second - tris_.begin());
        return std::sqrt(CGAL::squared_distance(q, hit.first));
    }

    /// Whichever of triangles s and t lies nearer to p (a hint for nearest()).
    uint32_t closer(const Point& p, uint32_t s, uint32_t t) const {
        if (s == t || t >= grid_.size()) return s;
        if (s >= grid_.size()) return t;
        return sq_dist(t, p) < sq_dist(s, p) ? t : s;
    }

    /// Squared distance from p to triangle t (HUGE_VAL for a triangle without a normal: the
    /// corner distance sq_dist_point_triangle gives then is not convex along the piece).
    double sq_dist(uint32_t t, const Point& p) const {
        const TriangleGrid::Tri& x = grid_.triangle(t);
        if (x.n[0] == 0 && x.n[1] == 0 && x.n[2] == 0) return HUGE_VAL;
        return sq_dist_point_triangle(p.data(), x.p[0], x.p[1], x.p[2]);
    }

private:
    /// CGAL's AABB tree of the triangles, built on first use (by one thread; thread-safe).
    const Tree& tree() const {
        std::call_once(tree_once_, [this] {
            tris_.reserve(mesh_.faces.size());
            for (const Face& f : mesh_.faces) {
                const Point &a = mesh_.vertices[f[0]], &b = mesh_.vertices[f[1]], &c = mesh_.vertices[f[2]];
                tris_.emplace_back(P3(a[0], a[1], a[2]), P3(b[0], b[1], b[2]), P3(c[0], c[1], c[2]));
            }
            tree_ = std::make_unique<Tree>(tris_.begin(), tris_.end());
            tree_->build();
            tree_->accelerate_distance_queries();
        });
        return *tree_;
    }

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
    mutable std::once_flag tree_once_;
    mutable std::vector<Tri> tris_;
    mutable std::unique_ptr<Tree> tree_;
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

/// Largest distance from a point of triangle abc to its nearest corner: the circumradius of an
/// acute triangle, half the longest edge otherwise (a degenerate one included).
double cover_radius(const Point& a, const Point& b, const Point& c) {
    double e[3] = {dist(b, c), dist(c, a), dist(a, b)};
    for (double& x : e) x *= x;
    std::sort(e, e + 3);
    if (e[2] >= e[0] + e[1]) return 0.5 * std::sqrt(e[2]);
    return std::sqrt(e[0] * e[1] * e[2]) / (4.0 * tri_area(a, b, c));
}

/// One direction of hausdorff_distance: the faces of `m` against `other`, given the distance
/// and nearest triangle of each vertex of m and the threshold M.
class FaceCertifier {
public:
    FaceCertifier(const SurfaceDistance& other, double threshold, double bound)
        : other_(other), m_(threshold), bound_(bound) {}

    struct Corner {
        Point p;
        double d;
        uint32_t t;
    };
    double max = 0;     ///< largest distance computed
    double reach = 0;   ///< largest cover radius of a sampled piece
    size_t points = 0;  ///< distances computed
    bool split = false;  ///< whether the face was split (its edges' midpoints computed)
    double mid_sum = 0;  ///< then the sum of their distances

    /// Piece abc: proven within m_ (see hausdorff_distance), sampled, or split in 4.
    void certify(const Corner& a, const Corner& b, const Corner& c) {
        const double r = cover_radius(a.p, b.p, c.p);
        m_ = std::max(m_, max);  // the face's own largest distance so far counts too
        if (std::max({a.d, b.d, c.d}) + r <= m_) return;
        if (within(a.t, a, b, c) || within(b.t, a, b, c) || within(c.t, a, b, c)) return;
        if (r <= bound_) {
            reach = std::max(reach, r);
            return;
        }
        const Corner ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
        if (!split) {  // the first split is the face's
            split = true;
            mid_sum = ab.d + bc.d + ca.d;
        }
        certify(ab, bc, ca);
        certify(a, ab, ca);
        certify(ab, b, bc);
        certify(ca, bc, c);
    }

private:
    /// True when a, b, c all lie within m_ of triangle t (so does all of abc: convexity).
    bool within(uint32_t t, const Corner& a, const Corner& b, const Corner& c) const {
        const double m2 = m_ * m_;
        for (const Corner* x : {&a, &b, &c})
            if (other_.sq_dist(t, x->p) > m2) return false;
        return true;
    }
    Corner mid(const Corner& a, const Corner& b) {
        Corner r;
        for (int k = 0; k < 3; ++k) r.p[k] = 0.5 * (a.p[k] + b.p[k]);
        r.t = other_.closer(r.p, a.t, b.t);
        r.d = other_.nearest(r.p, r.t);
        max = std::max(max, r.d);
        ++points;
        return r;
    }

    const SurfaceDistance& other_;
    double m_, bound_;
};

/// The vertices' distances (and nearest triangles) of m to `other`.
void vertex_distances(const TriangleMesh& m, const SurfaceDistance& other, std::vector<double>& d,
                      std::vector<uint32_t>& t) {
    d.assign(m.vertices.size(), 0.0);
    t.assign(m.vertices.size(), UINT32_MAX);
    std::vector<char> used(m.vertices.size(), 0);
    for (const Face& f : m.faces)
        for (uint32_t v : f) used[v] = 1;
    const long n = long(m.vertices.size());
#pragma omp parallel
    {
        uint32_t hint = UINT32_MAX;  // the previous vertex's triangle: only speeds the search up
#pragma omp for schedule(dynamic, 1024)
        for (long v = 0; v < n; ++v)
            if (used[size_t(v)]) {
                d[size_t(v)] = other.nearest(m.vertices[size_t(v)], hint);
                t[size_t(v)] = hint;
            }
    }
}

/// The faces of m against `other` (FaceCertifier); returns the area-weighted mean distance
/// (each face's from its centroid, corners and edge midpoints) and raises `max`, `reach`, `points`.
double certify_faces(const TriangleMesh& m, const SurfaceDistance& other, const std::vector<double>& vd,
                     const std::vector<uint32_t>& vt, double threshold, double bound, double& max, double& reach,
                     size_t& points) {
    struct PerFace {
        double max, reach, mean;
        size_t points;
    };
    std::vector<PerFace> r(m.faces.size());
    const long n = long(m.faces.size());
#pragma omp parallel for schedule(dynamic, 256)
    for (long i = 0; i < n; ++i) {
        const Face& f = m.faces[size_t(i)];
        FaceCertifier fc(other, threshold, bound);
        FaceCertifier::Corner c[3];
        for (int k = 0; k < 3; ++k) c[k] = {m.vertices[f[k]], vd[f[k]], vt[f[k]]};
        fc.certify(c[0], c[1], c[2]);
        Point g;
        for (int k = 0; k < 3; ++k) g[k] = (c[0].p[k] + c[1].p[k] + c[2].p[k]) / 3.0;
        uint32_t t = other.closer(g, other.closer(g, c[0].t, c[1].t), c[2].t);
        const double dg = other.nearest(g, t);
        // The face's mean distance: a rule exact for cubic functions when its edges' midpoints
        // are known, for quadratic ones otherwise.
        const double corners = c[0].d + c[1].d + c[2].d;
        const double mean = fc.split ? 0.45 * dg + fc.mid_sum * 2.0 / 15.0 + corners / 20.0 : 0.75 * dg + corners / 12.0;
        r[size_t(i)] = {std::max(fc.max, dg), fc.reach, mean, fc.points + 1};
    }
    double sum = 0, w = 0;
    for (size_t i = 0; i < r.size(); ++i) {
        max = std::max(max, r[i].max);
        reach = std::max(reach, r[i].reach);
        points += r[i].points;
        const Face& f = m.faces[i];
        const double area = tri_area(m.vertices[f[0]], m.vertices[f[1]], m.vertices[f[2]]);
        sum += area * r[i].mean;
        w += area;
    }
    return w > 0 ? sum / w : 0.0;
}

/// Sample spacing: params' or, when 0, sqrt(area / target) of the larger surface.
double auto_spacing(const TriangleMesh& a, const TriangleMesh& b, double spacing, size_t target_samples) {
    if (!(spacing >= 0.0) || !std::isfinite(spacing))
        throw std::invalid_argument("surface_deviation: sample spacing must be >= 0 mm (0 = automatic)");
    if (spacing > 0.0) return spacing;
    const double target = double(std::max<size_t>(target_samples, 1));
    const double h = std::sqrt(std::max(area(a), area(b)) / target);
    return h > 0 ? h : 1.0;  // zero-area meshes: one sample per face anyway
}

}  // namespace

DeviationResult surface_deviation(const TriangleMesh& a, const TriangleMesh& b, const DeviationParams& params) {
    check_mesh(a, "A");
    check_mesh(b, "B");
    DeviationResult r;
    const double h = auto_spacing(a, b, params.sample_spacing_mm, params.target_samples);
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

HausdorffResult hausdorff_distance(const TriangleMesh& a, const TriangleMesh& b, const HausdorffParams& params) {
    check_mesh(a, "A");
    check_mesh(b, "B");
    const double h = auto_spacing(a, b, params.sample_spacing_mm, params.target_samples);
    const double bound = std::max(spacing_bound(a, h), spacing_bound(b, h));
    const SurfaceDistance to_a(a), to_b(b);
    std::vector<double> da, db;
    std::vector<uint32_t> ta, tb;
    vertex_distances(a, to_b, da, ta);
    vertex_distances(b, to_a, db, tb);
    HausdorffResult r;
    const double m = std::max(*std::max_element(da.begin(), da.end()), *std::max_element(db.begin(), db.end()));
    r.hausdorff_mm = m;
    r.points = a.vertices.size() + b.vertices.size();
    r.mean_b_to_a_mm = certify_faces(b, to_a, db, tb, m, bound, r.hausdorff_mm, r.sampling_error_bound_mm, r.points);
    r.mean_a_to_b_mm = certify_faces(a, to_b, da, ta, r.hausdorff_mm, bound, r.hausdorff_mm, r.sampling_error_bound_mm, r.points);
    return r;
}

}  // namespace meshpost
