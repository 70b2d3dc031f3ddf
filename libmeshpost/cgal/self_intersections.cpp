// Self-intersection test with CGAL (GPL): Polygon_mesh_processing::self_intersections on a
// Surface_mesh when the faces form a valid polygon mesh, otherwise the same face-pair test run
// directly on the triangle soup with CGAL's box intersection and exact predicates.
#include "meshpost/self_intersections.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/box_intersection_d.h>

#include <boost/iterator/function_output_iterator.hpp>

#include <omp.h>

#include <algorithm>
#include <cmath>
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
    explicit PairCollector(size_t max_examples = kMaxExamples) : max_(max_examples) {}
    void add(size_t a, size_t b) {
        if (a == b) return;  // CGAL reports each degenerate face f as (f, f): not an intersection pair
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

SelfIntersectionReport on_surface_mesh_serial(const SurfaceMesh& sm, size_t max_examples) {
    PairCollector collector(max_examples);
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
SelfIntersectionReport on_surface_mesh_parallel(const SurfaceMesh& sm, int threads, size_t max_examples) {
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
    std::vector<PairCollector> collectors(static_cast<size_t>(threads), PairCollector(max_examples));
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
    PairCollector all(max_examples);
    for (const PairCollector& c : collectors) all.merge(c);
    return all.report();
}

SelfIntersectionReport on_surface_mesh(const SurfaceMesh& sm, size_t max_examples) {
    const int threads = omp_get_max_threads();
    if (threads <= 1 || sm.number_of_faces() < 10000) return on_surface_mesh_serial(sm, max_examples);
    return on_surface_mesh_parallel(sm, threads, max_examples);
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

SelfIntersectionReport on_soup(const TriangleMesh& mesh, const std::vector<Point3>& pts, size_t max_examples) {
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

    PairCollector collector(max_examples);
    auto callback = [&](const Box* x, const Box* y) {
        if (soup_faces_intersect(mesh.faces[x->info()], mesh.faces[y->info()], pts))
            collector.add(x->info(), y->info());
    };
    CGAL::box_self_intersection_d<CGAL::Sequential_tag>(box_ptr.begin(), box_ptr.end(), callback, std::ptrdiff_t(2000));
    return collector.report();
}

}  // namespace

SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh) {
    return find_self_intersections(mesh, kMaxExamples);
}

SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh, size_t max_examples) {
    const size_t nv = mesh.vertices.size();
    std::vector<Point3> points;
    points.reserve(nv);
    for (size_t v = 0; v < nv; ++v) {
        const Point& p = mesh.vertices[v];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            throw InvalidMesh("find_self_intersections: vertex " + std::to_string(v) + " has a non-finite coordinate");
        points.emplace_back(p[0], p[1], p[2]);
    }
    for (size_t f = 0; f < mesh.faces.size(); ++f)
        for (uint32_t v : mesh.faces[f])
            if (v >= nv)
                throw InvalidMesh("find_self_intersections: face " + std::to_string(f) + " references vertex " +
                                  std::to_string(v) + " but the mesh has " + std::to_string(nv) + " vertices");
    if (mesh.faces.empty()) return {};

    // A valid polygon mesh: edge- and vertex-manifold, consistently oriented, no repeated index.
    const TopologyReport topo = analyze_topology(mesh);
    bool polygon_mesh = topo.manifold && topo.oriented;
    for (size_t f = 0; f < mesh.faces.size() && polygon_mesh; ++f) {
        const Face& t = mesh.faces[f];
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) polygon_mesh = false;
    }
    if (polygon_mesh) {
        SurfaceMesh sm;
        if (build_surface_mesh(mesh, points, sm)) return on_surface_mesh(sm, max_examples);
    }
    return on_soup(mesh, points, max_examples);
}

}  // namespace meshpost
