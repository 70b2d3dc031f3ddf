// Self-intersection test with CGAL's exact predicates (GPL).
//
// Grid method (the default): every non-degenerate face gets its bounding box; a uniform grid with
// cells about as large as the mean face extent lists, for each cell, the faces whose box meets it
// (counting sort, so each list is in face order). Each pair of faces of a cell whose closed boxes
// overlap is tested in one cell only: the cell holding the low corner of the overlap of their
// boxes (the cell index is monotone in each coordinate, so that cell is in both faces' ranges).
// Cells are processed in parallel, each thread counting pairs and keeping the smallest examples;
// merging those does not depend on the order, so the report is the same for any thread count. The
// face-pair test is CGAL's (see soup_faces_intersect), so the report equals the reference's:
// CGAL::Polygon_mesh_processing::self_intersections on a Surface_mesh when the faces form a valid
// polygon mesh, otherwise the same face-pair test on the triangle soup with CGAL's box
// intersection. For a marching-cubes surface (faces of about one voxel, a few per cell) the grid
// tests the same pairs as CGAL's box intersection at a fraction of its cost, and in parallel.
// With a subject (only pairs with a flagged face count), the faces whose boxes cannot meet a flagged
// face's are left out before the grid is built (far_from_subject): the same pairs, from the few
// per cent of the faces near the flagged ones.
#include "meshpost/cgal/self_intersections.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/box_intersection_d.h>

#include <boost/iterator/function_output_iterator.hpp>

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "meshpost/topology.h"

namespace meshpost {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point3 = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point3>;

constexpr size_t kMaxExamples = 20;

/// Counts pairs and keeps the kMaxExamples lexicographically smallest (deterministic whatever the
/// order in which pairs are found).
class PairCollector {
public:
    explicit PairCollector(size_t max_examples = kMaxExamples, const std::vector<uint8_t>* subject = nullptr)
        : max_(max_examples), subject_(subject) {}
    void add(size_t a, size_t b) {
        if (a == b) return;  // CGAL reports each degenerate face f as (f, f): not an intersection pair
        if (subject_ && !(*subject_)[a] && !(*subject_)[b]) return;  // vouched for by the caller
        if (a > b) std::swap(a, b);
        ++count_;
        keep({a, b});
    }
    /// Adds the pairs counted by another collector (disjoint from this one's).
    void merge(const PairCollector& o) {
        count_ += o.count_;
        for (const auto& p : o.best_) keep(p);
    }
    SelfIntersectionReport report() const {
        SelfIntersectionReport r;
        r.intersecting_pairs = count_;
        r.examples = best_;
        std::sort(r.examples.begin(), r.examples.end());
        return r;
    }

private:
    void keep(const std::pair<size_t, size_t>& p) {
        if (best_.size() < max_) {
            best_.push_back(p);
            std::push_heap(best_.begin(), best_.end());
        } else if (!best_.empty() && p < best_.front()) {
            std::pop_heap(best_.begin(), best_.end());
            best_.back() = p;
            std::push_heap(best_.begin(), best_.end());
        }
    }
    size_t max_;
    size_t count_ = 0;
    std::vector<std::pair<size_t, size_t>> best_;  ///< max-heap
    const std::vector<uint8_t>* subject_ = nullptr;  ///< SelfIntersectionOptions::subject
};

/// Builds a Surface_mesh with face i == input face i; false when the faces do not form one.
bool build_surface_mesh(const TriangleMesh& mesh, const std::vector<Point3>& points, SurfaceMesh& sm) {
    sm.reserve(static_cast<SurfaceMesh::size_type>(points.size()),
               static_cast<SurfaceMesh::size_type>(3 * mesh.faces.size() / 2 + 1),
               static_cast<SurfaceMesh::size_type>(mesh.faces.size()));
    for (const Point3& p : points) sm.add_vertex(p);
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
        const Face& t = mesh.faces[f];
        const SurfaceMesh::Face_index fi =
            sm.add_face(SurfaceMesh::Vertex_index(t[0]), SurfaceMesh::Vertex_index(t[1]), SurfaceMesh::Vertex_index(t[2]));
        if (fi == SurfaceMesh::null_face() || static_cast<size_t>(fi.idx()) != f) return false;
    }
    return CGAL::is_valid_polygon_mesh(sm);
}

SelfIntersectionReport on_surface_mesh_serial(const SurfaceMesh& sm, size_t max_examples, const std::vector<uint8_t>* subject) {
    PairCollector collector(max_examples, subject);
    auto sink = [&collector](const std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>& p) {
        collector.add(static_cast<size_t>(p.first.idx()), static_cast<size_t>(p.second.idx()));
    };
    CGAL::Polygon_mesh_processing::self_intersections<CGAL::Sequential_tag>(
        sm, boost::make_function_output_iterator(sink));
    return collector.report();
}

/// The same test as on_surface_mesh_serial (CGAL's boxes, box intersection and face-pair filter),
/// run on `threads` slabs of x in parallel. A box goes to every slab its x-range meets; a pair of
/// boxes is reported only by the slab holding the larger of their lower x bounds, a point of both
/// ranges, so every intersecting pair is tested exactly once. The collectors are merged (count and
/// smallest examples do not depend on order): the report is the same for any thread count.
SelfIntersectionReport on_surface_mesh_parallel(const SurfaceMesh& sm, int threads, size_t max_examples, const std::vector<uint8_t>* subject) {
    namespace PMP = CGAL::Polygon_mesh_processing;
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, SurfaceMesh::Face_index,
                                                          CGAL::Box_intersection_d::ID_FROM_BOX_ADDRESS>;
    using VPM = typename boost::property_map<SurfaceMesh, CGAL::vertex_point_t>::const_type;
    std::vector<Box> boxes;
    boxes.reserve(sm.number_of_faces());
    const VPM vpm = get(CGAL::vertex_point, sm);
    for (SurfaceMesh::Face_index f : sm.faces()) {
        const auto h = sm.halfedge(f);
        const Point3& p = get(vpm, sm.target(h));
        const Point3& q = get(vpm, sm.target(sm.next(h)));
        const Point3& r = get(vpm, sm.target(sm.prev(h)));
        if (CGAL::collinear(p, q, r)) continue;  // CGAL reports (f, f): not a pair
        boxes.push_back(Box(p.bbox() + q.bbox() + r.bbox(), f));
    }
    // Slab bounds: quantiles of the lower x bounds.
    std::vector<double> lows(boxes.size());
    for (size_t i = 0; i < boxes.size(); ++i) lows[i] = boxes[i].min_coord(0);
    std::sort(lows.begin(), lows.end());
    std::vector<double> cut(size_t(threads) + 1);
    cut[0] = -std::numeric_limits<double>::infinity();
    cut[size_t(threads)] = std::numeric_limits<double>::infinity();
    for (int k = 1; k < threads; ++k) cut[size_t(k)] = lows.empty() ? 0.0 : lows[lows.size() * size_t(k) / size_t(threads)];
    std::vector<double>().swap(lows);
    auto slab_of = [&](double x) {  // k with cut[k] <= x < cut[k+1]
        return int(std::upper_bound(cut.begin() + 1, cut.end() - 1, x) - (cut.begin() + 1));
    };
    std::vector<PairCollector> collectors(static_cast<size_t>(threads), PairCollector(max_examples, subject));
#pragma omp parallel for schedule(static, 1) num_threads(threads)
    for (int k = 0; k < threads; ++k) {
        std::vector<const Box*> mine;
        for (const Box& b : boxes)
            if (b.max_coord(0) >= cut[size_t(k)] && b.min_coord(0) < cut[size_t(k) + 1]) mine.push_back(&b);
        PairCollector& col = collectors[size_t(k)];
        auto sink = [&col](const std::pair<SurfaceMesh::Face_index, SurfaceMesh::Face_index>& p) {
            col.add(static_cast<size_t>(p.first.idx()), static_cast<size_t>(p.second.idx()));
        };
        using Out = decltype(boost::make_function_output_iterator(sink));
        PMP::internal::Strict_intersect_faces<Box, SurfaceMesh, VPM, Kernel, Out> filter(
            sm, vpm, Kernel(), boost::make_function_output_iterator(sink));
        auto callback = [&](const Box* a, const Box* b) {
            if (slab_of(std::max(a->min_coord(0), b->min_coord(0))) != k) return;
            filter(a, b);
        };
        CGAL::box_self_intersection_d<CGAL::Sequential_tag>(mine.begin(), mine.end(), callback,
                                                            std::ptrdiff_t(2000));
    }
    PairCollector all(max_examples, subject);
    for (const PairCollector& c : collectors) all.merge(c);
    return all.report();
}

SelfIntersectionReport on_surface_mesh(const SurfaceMesh& sm, size_t max_examples, const std::vector<uint8_t>* subject) {
    const int threads = omp_get_max_threads();
    if (threads <= 1 || sm.number_of_faces() < 10000) return on_surface_mesh_serial(sm, max_examples, subject);
    return on_surface_mesh_parallel(sm, threads, max_examples, subject);
}

/// The face-pair test of CGAL::Polygon_mesh_processing::self_intersections, with adjacency taken
/// from shared vertex indices instead of a halfedge structure.
bool soup_faces_intersect(const Face& a, const Face& b, const std::vector<Point3>& pts) {
    int shared = 0;
    int ia[3], ib[3];
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            if (a[i] == b[j]) {
                ia[shared] = i;
                ib[shared] = j;
                ++shared;
            }
        }
    }
    const Point3 &a0 = pts[a[0]], &a1 = pts[a[1]], &a2 = pts[a[2]];
    const Point3 &b0 = pts[b[0]], &b1 = pts[b[1]], &b2 = pts[b[2]];
    if (shared >= 3) return true;  // the same triangle twice
    if (shared == 2) {
        // Shared edge: they overlap when coplanar with both third vertices on the same side of it.
        const Point3& p = pts[a[ia[0]]];
        const Point3& q = pts[a[ia[1]]];
        const Point3& ra = pts[a[3 - ia[0] - ia[1]]];
        const Point3& rb = pts[b[3 - ib[0] - ib[1]]];
        return CGAL::coplanar(p, q, ra, rb) && CGAL::coplanar_orientation(p, q, ra, rb) == CGAL::POSITIVE;
    }
    const Kernel::Triangle_3 ta(a0, a1, a2), tb(b0, b1, b2);
    if (shared == 1) {
        // Shared vertex: they intersect elsewhere when the edge opposite it in one meets the other.
        const int i = ia[0], j = ib[0];
        const Kernel::Segment_3 sa(pts[a[(i + 1) % 3]], pts[a[(i + 2) % 3]]);
        const Kernel::Segment_3 sb(pts[b[(j + 1) % 3]], pts[b[(j + 2) % 3]]);
        return CGAL::do_intersect(ta, sb) || CGAL::do_intersect(tb, sa);
    }
    return CGAL::do_intersect(ta, tb);
}

SelfIntersectionReport on_soup(const TriangleMesh& mesh, const std::vector<Point3>& pts, size_t max_examples, const std::vector<uint8_t>* subject) {
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, size_t, CGAL::Box_intersection_d::ID_FROM_BOX_ADDRESS>;
    std::vector<Box> boxes;
    boxes.reserve(mesh.faces.size());
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
        const Face& t = mesh.faces[f];
        const Point3 &p = pts[t[0]], &q = pts[t[1]], &r = pts[t[2]];
        if (CGAL::collinear(p, q, r)) continue;  // degenerate faces are skipped, as CGAL does
        boxes.emplace_back(p.bbox() + q.bbox() + r.bbox(), f);
    }
    std::vector<const Box*> box_ptr;
    box_ptr.reserve(boxes.size());
    for (const Box& b : boxes) box_ptr.push_back(&b);

    PairCollector collector(max_examples, subject);
    auto callback = [&](const Box* x, const Box* y) {
        if (soup_faces_intersect(mesh.faces[x->info()], mesh.faces[y->info()], pts))
            collector.add(x->info(), y->info());
    };
    CGAL::box_self_intersection_d<CGAL::Sequential_tag>(box_ptr.begin(), box_ptr.end(), callback, std::ptrdiff_t(2000));
    return collector.report();
}

/// Which side of the plane through o, a, b a point lies on, when a floating-point determinant
/// decides it: the determinant of (a - o, b - o, p - o) expanded along the last row, with
/// Shewchuk's error bound for orient3d ((7 + 56 eps) eps times the permanent, rounded up to 1e-15):
/// the sign of the exact determinant (+1 or -1) when the bound makes it certain, 0 when not (or
/// when tiny or non-finite values could make the bound wrong).
class PlaneSide {
public:
    PlaneSide() = default;
    PlaneSide(const Point& o, const Point& a, const Point& b) : o_(&o) {
        const double ax = a[0] - o[0], ay = a[1] - o[1], az = a[2] - o[2];
        const double bx = b[0] - o[0], by = b[1] - o[1], bz = b[2] - o[2];
        m_[0] = ay * bz - az * by;
        m_[1] = az * bx - ax * bz;
        m_[2] = ax * by - ay * bx;
        pm_[0] = std::fabs(ay * bz) + std::fabs(az * by);
        pm_[1] = std::fabs(az * bx) + std::fabs(ax * bz);
        pm_[2] = std::fabs(ax * by) + std::fabs(ay * bx);
    }
    int operator()(const Point& p) const {
        const Point& o = *o_;
        const double px = p[0] - o[0], py = p[1] - o[1], pz = p[2] - o[2];
        const double det = px * m_[0] + py * m_[1] + pz * m_[2];
        const double perm = std::fabs(px) * pm_[0] + std::fabs(py) * pm_[1] + std::fabs(pz) * pm_[2];
        if (!(perm > 1e-200) || !(perm < 1e200)) return 0;  // underflow / overflow: let CGAL decide
        const double bound = 1e-15 * perm;
        return det > bound ? 1 : det < -bound ? -1 : 0;
    }

private:
    const Point* o_ = nullptr;
    double m_[3] = {}, pm_[3] = {};
};

/// True when one component of (q - p) x (r - p) is certainly non-zero in floating point
/// (Shewchuk's orient2d error bound, (3 + 16 eps) eps times the permanent, rounded up to 1e-15).
bool surely_not_collinear(const Point& p, const Point& q, const Point& r) {
    const double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    const double w[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
    for (int a = 0; a < 3; ++a) {
        const int i = (a + 1) % 3, j = (a + 2) % 3;
        const double left = u[i] * w[j], right = u[j] * w[i];
        const double perm = std::fabs(left) + std::fabs(right);
        if (!(perm > 1e-200) || !(perm < 1e200)) continue;
        if (std::fabs(left - right) > 1e-15 * perm) return true;
    }
    return false;
}

/// True when PlaneSide shows that the segment pq misses the triangle (t0, t1, t2): p and q
/// strictly on one side of its plane, or strictly on both sides with the line pq passing outside
/// an edge (two of the orientations of (p, q, edge) certain and opposite). False: undecided.
/// `plane`: PlaneSide of the triangle's plane (through any of its vertices).
bool segment_surely_misses(const Point& p, const Point& q, const PlaneSide& plane, const Point& t0,
                           const Point& t1, const Point& t2) {
    const int sp = plane(p);
    if (sp == 0) return false;
    const int sq = plane(q);
    if (sq == sp) return true;
    if (sq == 0) return false;
    // pq crosses the plane at one point: inside the (closed) triangle iff no two of these
    // orientations are strictly opposite.
    const int e0 = PlaneSide(p, q, t0)(t1);
    const int e1 = PlaneSide(p, q, t1)(t2);
    const int e2 = PlaneSide(p, q, t2)(t0);
    return (e0 * e1 < 0) || (e1 * e2 < 0) || (e0 * e2 < 0);
}

/// True when a cheap exact argument shows that soup_faces_intersect(a, b) is false: faces sharing
/// an edge that are certainly not coplanar; faces sharing one vertex whose opposite edges each lie
/// strictly on one side of the other face's plane; other faces with one face strictly on one side
/// of the other's plane. Otherwise false (undecided: run the full test).
/// `pa`, `pb`: PlaneSide of each face's plane.
bool surely_apart(const Face& a, const Face& b, const std::vector<Point>& v, const PlaneSide& pa,
                  const PlaneSide& pb) {
    int shared = 0, ia = 0, ib = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (a[i] == b[j]) {
                if (shared == 0) {
                    ia = i;
                    ib = j;
                }
                ++shared;
            }
    if (shared == 2) {
        // Not coplanar: b's vertex off the shared edge is off a's plane.
        int rb = 0;
        while (b[rb] == a[0] || b[rb] == a[1] || b[rb] == a[2]) ++rb;
        return pa(v[b[rb]]) != 0;
    }
    if (shared == 1) {
        // One face strictly on one side of the other's plane, apart from the shared vertex: they
        // meet only there (a point of both would lie in that plane, so it would be the vertex).
        const Point& o = v[a[ia]];
        const Point &a1 = v[a[(ia + 1) % 3]], &a2 = v[a[(ia + 2) % 3]];
        const Point &b1 = v[b[(ib + 1) % 3]], &b2 = v[b[(ib + 2) % 3]];
        const int s1 = pa(b1);
        if (s1 != 0 && pa(b2) == s1) return true;
        const int t1 = pb(a1);
        if (t1 != 0 && pb(a2) == t1) return true;
        return segment_surely_misses(b1, b2, pa, o, a1, a2) && segment_surely_misses(a1, a2, pb, o, b1, b2);
    }
    if (shared == 0) {
        const int s = pa(v[b[0]]);
        if (s != 0 && pa(v[b[1]]) == s && pa(v[b[2]]) == s) return true;
        const int t = pb(v[a[0]]);
        return t != 0 && pb(v[a[1]]) == t && pb(v[a[2]]) == t;
    }
    return false;
}

/// A face's bounding box (its vertices' coordinates, as CGAL's bbox of them).
struct FaceBox {
    double lo[3], hi[3];
};
FaceBox face_box(const TriangleMesh& mesh, const Face& t) {
    const Point &p = mesh.vertices[t[0]], &q = mesh.vertices[t[1]], &r = mesh.vertices[t[2]];
    FaceBox b;
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::min({p[a], q[a], r[a]});
        b.hi[a] = std::max({p[a], q[a], r[a]});
    }
    return b;
}

/// With a subject: per face, 1 when its bounding box certainly meets no flagged face's, 0 when it
/// may (every face whose box meets one gets 0). The flagged faces' boxes are marked in a coarse
/// grid over their union (cells at least twice their mean largest side, at most 64 a side); a face
/// is kept when its box meets the union and the cells its box spans (clamped to the grid, monotone
/// in each coordinate, so two overlapping boxes share a cell) hold a mark. One pass over the
/// faces' vertices: the grid, planes and pairs then cover the few per cent of faces near the
/// flagged ones instead of the whole mesh.
std::vector<uint8_t> far_from_subject(const TriangleMesh& mesh, const std::vector<uint8_t>& subject) {
    const int64_t nf = static_cast<int64_t>(mesh.faces.size());
    auto box_of = [&](int64_t f) { return face_box(mesh, mesh.faces[size_t(f)]); };
    std::vector<int64_t> flagged;
    for (int64_t f = 0; f < nf; ++f)
        if (subject[size_t(f)]) flagged.push_back(f);
    std::vector<uint8_t> far(size_t(nf), 1);
    if (flagged.empty()) return far;
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL}, extent_sum = 0;
    for (int64_t f : flagged) {
        const FaceBox b = box_of(f);
        double e = 0;
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], b.lo[a]);
            hi[a] = std::max(hi[a], b.hi[a]);
            e = std::max(e, b.hi[a] - b.lo[a]);
        }
        extent_sum += e;
    }
    int64_t n[3];
    double inv[3];
    for (int a = 0; a < 3; ++a) {
        const double span = hi[a] - lo[a];
        double cell = std::max(2.0 * extent_sum / double(flagged.size()), span / 64.0);
        if (!(cell > 0) || !std::isfinite(cell)) cell = 1.0;
        n[a] = std::clamp<int64_t>(int64_t(std::floor(span / cell)) + 1, 1, 64);
        inv[a] = 1.0 / cell;
    }
    auto cell_of = [&](double x, int a) {  // monotone in x, clamped to the grid
        const double c = std::floor((x - lo[a]) * inv[a]);
        return c < 0 ? int64_t(0) : c >= double(n[a] - 1) ? n[a] - 1 : int64_t(c);
    };
    std::vector<uint8_t> marked(size_t(n[0] * n[1] * n[2]), 0);
    auto for_cells = [&](const FaceBox& b, auto&& fn) {
        int64_t c0[3], c1[3];
        for (int a = 0; a < 3; ++a) c0[a] = cell_of(b.lo[a], a), c1[a] = cell_of(b.hi[a], a);
        for (int64_t z = c0[2]; z <= c1[2]; ++z)
            for (int64_t y = c0[1]; y <= c1[1]; ++y)
                for (int64_t x = c0[0]; x <= c1[0]; ++x)
                    if (fn(size_t(x + n[0] * (y + n[1] * z)))) return;
    };
    for (int64_t f : flagged) for_cells(box_of(f), [&](size_t c) { return marked[c] = 1, false; });
#pragma omp parallel for schedule(static)
    for (int64_t f = 0; f < nf; ++f) {
        const FaceBox b = box_of(f);
        if (b.lo[0] > hi[0] || b.lo[1] > hi[1] || b.lo[2] > hi[2] || b.hi[0] < lo[0] || b.hi[1] < lo[1] || b.hi[2] < lo[2])
            continue;
        bool meets = false;
        for_cells(b, [&](size_t c) { return meets = marked[c] != 0; });
        far[size_t(f)] = !meets;
    }
    return far;
}

/// Candidate pairs from a uniform grid, tested with surely_apart and then soup_faces_intersect,
/// cells in parallel.
/// Returns false (and leaves `out` alone) when the grid would hold more than 16 entries per face.
bool on_grid(const TriangleMesh& mesh, const std::vector<Point3>& pts, size_t max_examples,
             const std::vector<uint8_t>* subject, SelfIntersectionReport& out) {
    const int64_t nf = static_cast<int64_t>(mesh.faces.size());
    // Boxes and cell ranges default-initialised (not zeroed: a 2 M-face mesh's are 150 MB), each
    // written in parallel before it is read; a skipped face's are never read.
    const std::unique_ptr<FaceBox[]> box(new FaceBox[size_t(nf)]);
    // With a subject, the faces that cannot meet a flagged one are skipped (far_from_subject).
    std::vector<uint8_t> skip = subject ? far_from_subject(mesh, *subject) : std::vector<uint8_t>(size_t(nf), 0);
    std::vector<double> extent(static_cast<size_t>(nf), 0.0);  // a face's largest box side (0 when skipped)
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    int64_t used = 0;
#pragma omp parallel for schedule(static) reduction(min : lo[:3]) reduction(max : hi[:3]) reduction(+ : used)
    for (int64_t f = 0; f < nf; ++f) {
        if (skip[size_t(f)]) continue;
        const Face& t = mesh.faces[size_t(f)];
        const Point3 &p = pts[t[0]], &q = pts[t[1]], &r = pts[t[2]];
        if (!surely_not_collinear(mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]) &&
            CGAL::collinear(p, q, r)) {  // degenerate faces are skipped, as CGAL does
            skip[size_t(f)] = 1;
            continue;
        }
        const FaceBox& b = box[size_t(f)] = face_box(mesh, t);
        double e = 0;
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], b.lo[a]);
            hi[a] = std::max(hi[a], b.hi[a]);
            e = std::max(e, b.hi[a] - b.lo[a]);
        }
        extent[size_t(f)] = e;
        ++used;
    }
    // Grid: origin at the low corner of all boxes, cell edge 1.5 times the mean largest box extent
    // (the extents summed in face order: the same for any thread count; 1 to 3 times gave about
    // the same time on marching-cubes meshes), enlarged until the grid has at most 4 cells per face.
    double extent_sum = 0;
    for (int64_t f = 0; f < nf; ++f)
        if (!skip[size_t(f)]) extent_sum += extent[size_t(f)];
    if (used < 2) {
        out = PairCollector(max_examples, subject).report();
        return true;
    }
    double h = 1.5 * extent_sum / double(used);
    const double span[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    const double max_cells = 4.0 * double(used) + 64.0;
    if (!(h > 0)) h = std::max({span[0], span[1], span[2]});
    if (!(h > 0)) h = 1.0;
    for (;;) {  // grow h until the grid has at most max_cells cells
        double cells = 1;
        for (int a = 0; a < 3; ++a) cells *= std::floor(span[a] / h) + 1;
        if (cells <= max_cells) break;
        h *= 1.25;
    }
    int64_t n[3];
    for (int a = 0; a < 3; ++a) n[a] = static_cast<int64_t>(std::floor(span[a] / h)) + 1;
    const double inv_h = 1.0 / h;
    auto cell_of = [&](double x, int a) {  // monotone in x
        const double c = std::floor((x - lo[a]) * inv_h);
        return std::clamp(static_cast<int64_t>(c), int64_t(0), n[a] - 1);
    };
    // Cell ranges per face; the low cells also give the dedup cell of a pair.
    struct Range {
        int32_t c0[3], c1[3];
    };
    const std::unique_ptr<Range[]> range(new Range[size_t(nf)]);
    int64_t entries = 0;
#pragma omp parallel for schedule(static) reduction(+ : entries)
    for (int64_t f = 0; f < nf; ++f) {
        if (skip[size_t(f)]) continue;
        Range& r = range[size_t(f)];
        int64_t k = 1;
        for (int a = 0; a < 3; ++a) {
            r.c0[a] = static_cast<int32_t>(cell_of(box[size_t(f)].lo[a], a));
            r.c1[a] = static_cast<int32_t>(cell_of(box[size_t(f)].hi[a], a));
            k *= r.c1[a] - r.c0[a] + 1;
        }
        entries += k;
    }
    if (entries > 16 * used) return false;
    const int64_t ncells = n[0] * n[1] * n[2];
    auto cell_index = [&](int64_t x, int64_t y, int64_t z) { return (z * n[1] + y) * n[0] + x; };
    // With a subject, only pairs with a flagged face are tested, so only the cells a flagged face
    // meets ("hot") are visited: a pair is tested in the cell at the low corner of the overlap of
    // its boxes, which lies in the flagged face's range. The faces in play are those meeting a hot
    // cell (a few per cent of a mesh whose dips moved a few patches), listed by the other cells of
    // their range too, and only they get a plane; without a subject every face is in play.
    std::vector<uint8_t> hot;
    std::vector<uint32_t> play;
    auto for_cells = [&](const Range& r, auto&& fn) {
        for (int64_t z = r.c0[2]; z <= r.c1[2]; ++z)
            for (int64_t y = r.c0[1]; y <= r.c1[1]; ++y)
                for (int64_t x = r.c0[0]; x <= r.c1[0]; ++x) fn(cell_index(x, y, z));
    };
    if (subject) {
        hot.assign(size_t(ncells), 0);
        for (int64_t f = 0; f < nf; ++f)
            if (!skip[size_t(f)] && (*subject)[size_t(f)]) for_cells(range[size_t(f)], [&](int64_t c) { hot[size_t(c)] = 1; });
        std::vector<uint8_t> meets(static_cast<size_t>(nf), 0);
#pragma omp parallel for schedule(static)
        for (int64_t f = 0; f < nf; ++f) {
            if (skip[size_t(f)]) continue;
            bool m = false;
            for_cells(range[size_t(f)], [&](int64_t c) { m = m || hot[size_t(c)]; });
            meets[size_t(f)] = m;
        }
        for (int64_t f = 0; f < nf; ++f)
            if (meets[size_t(f)]) play.push_back(static_cast<uint32_t>(f));
    } else {
        play.reserve(static_cast<size_t>(used));
        for (int64_t f = 0; f < nf; ++f)
            if (!skip[size_t(f)]) play.push_back(static_cast<uint32_t>(f));
    }
    // The planes of the faces in play, face f's at plane[slot[f]].
    std::vector<uint32_t> slot(static_cast<size_t>(nf), 0);
    std::vector<PlaneSide> plane(play.size());
    const int64_t nplay = static_cast<int64_t>(play.size());
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < nplay; ++i) {
        const uint32_t f = play[size_t(i)];
        const Face& t = mesh.faces[f];
        slot[f] = static_cast<uint32_t>(i);
        plane[size_t(i)] = PlaneSide(mesh.vertices[t[0]], mesh.vertices[t[1]], mesh.vertices[t[2]]);
    }
    // Counting sort of (cell, face) over the faces in play and the cells visited, faces in
    // increasing order within a cell. The cells visited are numbered by slots: with a subject the
    // hot cells in increasing order (a few thousand of the grid's millions), else every cell.
    std::vector<int64_t> hot_cells;
    if (!hot.empty())
        for (int64_t c = 0; c < ncells; ++c)
            if (hot[size_t(c)]) hot_cells.push_back(c);
    const int64_t nslots = hot.empty() ? ncells : int64_t(hot_cells.size());
    auto slot_of = [&](int64_t c) -> int64_t {  // -1: not visited
        if (hot.empty()) return c;
        if (!hot[size_t(c)]) return -1;
        return int64_t(std::lower_bound(hot_cells.begin(), hot_cells.end(), c) - hot_cells.begin());
    };
    auto cell_of_slot = [&](int64_t k) { return hot.empty() ? k : hot_cells[size_t(k)]; };
    std::vector<uint32_t> start(size_t(nslots) + 1, 0);
    for (uint32_t f : play)
        for_cells(range[f], [&](int64_t c) {
            if (const int64_t k = slot_of(c); k >= 0) ++start[size_t(k) + 1];
        });
    std::vector<int64_t> occupied;  // slots of visited cells with two faces or more
    for (int64_t k = 0; k < nslots; ++k) {
        if (start[size_t(k) + 1] >= 2) occupied.push_back(k);
        start[size_t(k) + 1] += start[size_t(k)];
    }
    std::vector<uint32_t> faces_of(start[size_t(nslots)]);
    {
        std::vector<uint32_t> fill(start.begin(), start.end() - 1);
        for (uint32_t f : play)
            for_cells(range[f], [&](int64_t c) {
                if (const int64_t k = slot_of(c); k >= 0) faces_of[fill[size_t(k)]++] = f;
            });
    }
    std::vector<PairCollector> collectors;
    const int64_t nocc = static_cast<int64_t>(occupied.size());
#pragma omp parallel
    {
#pragma omp single
        collectors.assign(size_t(omp_get_num_threads()), PairCollector(max_examples, subject));
        PairCollector& col = collectors[size_t(omp_get_thread_num())];
#pragma omp for schedule(dynamic, 256)
        for (int64_t i = 0; i < nocc; ++i) {
            const int64_t k = occupied[size_t(i)], c = cell_of_slot(k);
            const int32_t cx = static_cast<int32_t>(c % n[0]);
            const int32_t cy = static_cast<int32_t>((c / n[0]) % n[1]);
            const int32_t cz = static_cast<int32_t>(c / (n[0] * n[1]));
            const uint32_t* first = faces_of.data() + start[size_t(k)];
            const uint32_t* last = faces_of.data() + start[size_t(k) + 1];
            for (const uint32_t* a = first; a != last; ++a) {
                const FaceBox& ba = box[*a];
                const Range& ra = range[*a];
                const bool a_subject = !subject || (*subject)[*a];
                for (const uint32_t* b = a + 1; b != last; ++b) {
                    if (!a_subject && !(*subject)[*b]) continue;
                    const FaceBox& bb = box[*b];
                    if (ba.lo[0] > bb.hi[0] || bb.lo[0] > ba.hi[0] || ba.lo[1] > bb.hi[1] ||
                        bb.lo[1] > ba.hi[1] || ba.lo[2] > bb.hi[2] || bb.lo[2] > ba.hi[2])
                        continue;
                    const Range& rb = range[*b];
                    if (std::max(ra.c0[0], rb.c0[0]) != cx || std::max(ra.c0[1], rb.c0[1]) != cy ||
                        std::max(ra.c0[2], rb.c0[2]) != cz)
                        continue;  // tested in another cell
                    const Face &fa = mesh.faces[*a], &fb = mesh.faces[*b];
                    if (!surely_apart(fa, fb, mesh.vertices, plane[slot[*a]], plane[slot[*b]]) &&
                        soup_faces_intersect(fa, fb, pts))
                        col.add(*a, *b);
                }
            }
        }
    }
    PairCollector all(max_examples, subject);
    for (const PairCollector& c : collectors) all.merge(c);
    out = all.report();
    return true;
}

}  // namespace

SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh) {
    return find_self_intersections(mesh, SelfIntersectionOptions{});
}

SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh, size_t max_examples) {
    SelfIntersectionOptions o;
    o.max_examples = max_examples;
    return find_self_intersections(mesh, o);
}

SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh, const SelfIntersectionOptions& options) {
    const size_t max_examples = options.max_examples;
    const size_t nv = mesh.vertices.size();
    // Converted on all threads; the first vertex with a non-finite coordinate is the one named.
    std::vector<Point3> points(nv);
    int64_t first_bad = int64_t(nv);
#pragma omp parallel for schedule(static) reduction(min : first_bad)
    for (int64_t v = 0; v < int64_t(nv); ++v) {
        const Point& p = mesh.vertices[size_t(v)];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) first_bad = std::min(first_bad, v);
        else points[size_t(v)] = Point3(p[0], p[1], p[2]);
    }
    if (first_bad < int64_t(nv))
        throw InvalidMesh("find_self_intersections: vertex " + std::to_string(first_bad) + " has a non-finite coordinate");
    if (const size_t f = first_face_with_bad_index(mesh); f < mesh.faces.size())
        for (uint32_t v : mesh.faces[f])
            if (v >= nv)
                throw InvalidMesh("find_self_intersections: face " + std::to_string(f) + " references vertex " +
                                  std::to_string(v) + " but the mesh has " + std::to_string(nv) + " vertices");
    if (options.subject && options.subject->size() != mesh.faces.size())
        throw InvalidMesh("find_self_intersections: " + std::to_string(options.subject->size()) +
                               " subject flags for " + std::to_string(mesh.faces.size()) + " faces, expected one per face");
    if (mesh.faces.empty()) return {};
    if (options.subject && std::none_of(options.subject->begin(), options.subject->end(), [](uint8_t f) { return f != 0; }))
        return {};  // no flagged face: nothing to test
    if (mesh.faces.size() > size_t(UINT32_MAX))
        throw InvalidMesh("find_self_intersections: too many faces (" + std::to_string(mesh.faces.size()) + ")");

    if (options.method == SelfIntersectionMethod::Grid) {
        SelfIntersectionReport r;
        if (on_grid(mesh, points, max_examples, options.subject, r)) return r;
    }

    // A valid polygon mesh: edge- and vertex-manifold, consistently oriented, no repeated index.
    const TopologyReport topo = analyze_topology(mesh);
    bool polygon_mesh = topo.manifold && topo.oriented;
    for (size_t f = 0; f < mesh.faces.size() && polygon_mesh; ++f) {
        const Face& t = mesh.faces[f];
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) polygon_mesh = false;
    }
    if (polygon_mesh) {
        SurfaceMesh sm;
        if (build_surface_mesh(mesh, points, sm)) return on_surface_mesh(sm, max_examples, options.subject);
    }
    return on_soup(mesh, points, max_examples, options.subject);
}

size_t count_self_intersections(const TriangleMesh& mesh, const std::vector<uint8_t>* subject) {
    SelfIntersectionOptions options;
    options.subject = subject;
    return find_self_intersections(mesh, options).intersecting_pairs;
}

}  // namespace meshpost
