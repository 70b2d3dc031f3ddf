// Quadric-error simplification on OpenMesh's mesh with a two-sided distance bound (see simplify.h).
#include "meshpost/simplify.h"

// OpenMesh properties push_back default-constructed (uninitialised) VectorT values, which GCC 12
// reports as maybe-uninitialized when inlined; the values are always assigned before use.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/Geometry/QuadricT.hh>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "meshpost/measure.h"
#include "meshpost/patches.h"
#include "meshpost/triangle_grid.h"

namespace meshpost {
namespace {

struct DoubleTraits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
using BaseMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

/// OpenMesh's mesh with its own collapse test: OpenMesh 9's TriConnectivity::is_collapse_ok looks
/// a property up by name on every call, which made it half of the decimation time; this one (the
/// link condition, with a vertex stamp array instead of property lookups) replaces it.
class OMesh : public BaseMesh {
public:
    /// True when collapsing halfedge h (v0 -> v1, v0 removed) keeps the surface a manifold of the
    /// same topology: the common neighbours of v0 and v1 are exactly the opposite vertices vl, vr
    /// of the edge's faces (vertex link condition) and boundaries are not pinched. (The edge link
    /// condition, which only fails for a tetrahedron, is tested by Decimator::legal.)
    /// `stamp`, `current`: the caller's scratch marks (one per vertex; each thread its own).
    bool is_collapse_ok(HalfedgeHandle h, std::vector<uint32_t>& stamp, uint32_t& current) const {
        const HalfedgeHandle o = opposite_halfedge_handle(h);
        if ((*estatus_)[edge_handle(h).idx()].deleted()) return false;
        const VertexHandle v0 = to_vertex_handle(o), v1 = to_vertex_handle(h);
        if ((*vstatus_)[v0.idx()].deleted() || (*vstatus_)[v1.idx()].deleted()) return false;
        VertexHandle vl, vr;
        if (!is_boundary(h)) {
            vl = to_vertex_handle(next_halfedge_handle(h));
            // Both other edges of the face on the boundary: the collapse would leave a dangling edge.
            if (is_boundary(opposite_halfedge_handle(next_halfedge_handle(h))) &&
                is_boundary(opposite_halfedge_handle(prev_halfedge_handle(h))))
                return false;
        }
        if (!is_boundary(o)) {
            vr = to_vertex_handle(next_halfedge_handle(o));
            if (is_boundary(opposite_halfedge_handle(next_halfedge_handle(o))) &&
                is_boundary(opposite_halfedge_handle(prev_halfedge_handle(o))))
                return false;
        }
        if (vl == vr) return false;  // both invalid, or the same vertex
        // An interior edge between two boundary vertices would pinch the surface.
        if (is_boundary(v0) && is_boundary(v1) && !is_boundary(h) && !is_boundary(o)) return false;
        if (stamp.size() < n_vertices()) stamp.resize(n_vertices(), 0);
        if (++current == 0) {  // wrapped around: clear
            std::fill(stamp.begin(), stamp.end(), 0);
            current = 1;
        }
        for (const VertexHandle v : vv_range(v0)) stamp[v.idx()] = current;
        for (const VertexHandle v : vv_range(v1))
            if (stamp[v.idx()] == current && v != vl && v != vr) return false;
        return true;
    }

    /// Caches the vertex and edge status arrays (OpenMesh 9 compares a property's name on every
    /// typed access, which took a tenth of the decimation time); call after requesting them and
    /// before is_collapse_ok. Collapses and status changes keep the arrays in place.
    void cache_status() {
        vstatus_ = &property(vertex_status_pph()).data_vector();
        estatus_ = &property(edge_status_pph()).data_vector();
    }
    const OpenMesh::Attributes::StatusInfo& vstatus(VertexHandle v) const { return (*vstatus_)[v.idx()]; }
    const OpenMesh::Attributes::StatusInfo& estatus(EdgeHandle e) const { return (*estatus_)[e.idx()]; }

private:
    std::vector<OpenMesh::Attributes::StatusInfo>*vstatus_ = nullptr, *estatus_ = nullptr;
};

/// Vertices per region: meshes with fewer than twice this are decimated in one piece.
constexpr size_t kRegionMinVertices = 20000;
/// Number of regions (at most; a fixed number, so the result does not depend on the threads).
constexpr size_t kRegions = 8;
/// Rounds of each parallel pass (see decimate_regions).
constexpr int kRounds = 3;

/// OpenMesh's copy of the input, its elements stored half slab by half slab (see slab_regions).
struct Prepared {
    OMesh om;
    size_t regions = 1;                 ///< slabs (1: no parallel passes)
    std::vector<uint16_t> half;         ///< each vertex's half slab (2 per slab; 0 when 1 slab)
    std::vector<uint32_t> input_face;   ///< each face's index in the input
};

/// The slab of each used input vertex (`used` non-zero): the vertices ordered along the longest
/// side of their bounding box (ties by index) and cut into `regions` runs of equal length.
std::vector<uint16_t> slab_regions(const TriangleMesh& in, const std::vector<char>& used, size_t regions) {
    std::vector<uint32_t> order;
    for (uint32_t v = 0; v < in.vertices.size(); ++v)
        if (used[v]) order.push_back(v);
    std::vector<uint16_t> owner(in.vertices.size(), 0);
    if (regions < 2) return owner;
    Point lo = in.vertices[order[0]], hi = lo;
    for (const uint32_t v : order)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], in.vertices[v][k]);
            hi[k] = std::max(hi[k], in.vertices[v][k]);
        }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        const double x = in.vertices[a][axis], y = in.vertices[b][axis];
        return x < y || (x == y && a < b);
    });
    for (size_t i = 0; i < order.size(); ++i) owner[order[i]] = uint16_t(i * regions / order.size());
    return owner;
}

/// `locked`: empty, or one flag per input vertex (non-zero: the vertex is locked). The vertices
/// and faces are added half slab by half slab (a face in that of its first vertex), keeping the
/// input's order within one, so that each region's elements (in either pass, see
/// decimate_in_parallel) lie together in memory.
Prepared to_openmesh(const TriangleMesh& in, const std::vector<uint8_t>& locked) {
    const size_t nv = in.vertices.size();
    std::vector<char> used(nv, 0);
    for (size_t f = 0; f < in.faces.size(); ++f)
        for (uint32_t v : in.faces[f]) {
            if (v >= nv)
                throw InvalidMesh("simplify: face " + std::to_string(f) + " references vertex " + std::to_string(v) +
                                  " but the mesh has " + std::to_string(nv) + " vertices");
            used[v] = 1;
        }
    for (size_t v = 0; v < nv; ++v) {
        const Point& p = in.vertices[v];
        if (used[v] && (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])))
            throw InvalidMesh("simplify: vertex " + std::to_string(v) + " has a non-finite coordinate");
    }
    Prepared r;
    const size_t n_used = size_t(std::count(used.begin(), used.end(), 1));
    r.regions = std::max<size_t>(1, std::min(kRegions, n_used / kRegionMinVertices));
    const size_t halves = r.regions < 2 ? 1 : 2 * r.regions;
    const std::vector<uint16_t> region = slab_regions(in, used, halves);
    // Counting sort of the vertices and faces by half slab.
    std::vector<size_t> vstart(halves + 1, 0), fstart(halves + 1, 0);
    for (size_t v = 0; v < nv; ++v)
        if (used[v]) ++vstart[region[v] + 1];
    for (const Face& t : in.faces) ++fstart[region[t[0]] + 1];
    for (size_t k = 0; k < halves; ++k) {
        vstart[k + 1] += vstart[k];
        fstart[k + 1] += fstart[k];
    }
    std::vector<uint32_t> vorder(n_used), forder(in.faces.size());
    for (uint32_t v = 0; v < nv; ++v)
        if (used[v]) vorder[vstart[region[v]]++] = v;
    for (uint32_t f = 0; f < in.faces.size(); ++f) forder[fstart[region[in.faces[f][0]]]++] = f;

    OMesh& om = r.om;
    std::vector<OMesh::VertexHandle> vh(nv);
    r.half.reserve(n_used);
    for (const uint32_t v : vorder) {
        const Point& p = in.vertices[v];
        vh[v] = om.add_vertex(OMesh::Point(p[0], p[1], p[2]));
        r.half.push_back(region[v]);
    }
    if (!locked.empty()) {
        om.request_vertex_status();
        for (size_t v = 0; v < nv; ++v)
            if (used[v] && locked[v]) om.status(vh[v]).set_locked(true);
    }
    r.input_face = std::move(forder);
    for (const uint32_t f : r.input_face) {
        const Face& t = in.faces[f];
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
            throw InvalidMesh("simplify: face " + std::to_string(f) + " repeats a vertex (degenerate face)");
        const OMesh::FaceHandle fh = om.add_face(vh[t[0]], vh[t[1]], vh[t[2]]);
        if (!fh.is_valid())
            throw InvalidMesh("simplify: face " + std::to_string(f) +
                              " makes the mesh non-manifold or inconsistently oriented; simplify needs an "
                              "oriented 2-manifold (see `endocast inspect`)");
    }
    return r;
}

TriangleMesh from_openmesh(const OMesh& om) {
    TriangleMesh out;
    std::vector<uint32_t> index(om.n_vertices(), UINT32_MAX);
    out.vertices.reserve(om.n_vertices());
    for (const auto v : om.vertices()) {
        index[v.idx()] = static_cast<uint32_t>(out.vertices.size());
        const auto& p = om.point(v);
        out.vertices.push_back({p[0], p[1], p[2]});
    }
    out.faces.reserve(om.n_faces());
    for (const auto f : om.faces()) {
        Face t{};
        int k = 0;
        for (const auto v : om.fv_range(f)) t[k++] = index[v.idx()];
        out.faces.push_back(t);
    }
    return out;
}



using Vec3 = OpenMesh::Vec3d;

/// When the distance bound stops the decimation short of the target, it is multiplied by
/// kRelaxFactor and the decimation goes on, at most kMaxRelaxations times.
constexpr double kRelaxFactor = 1.25;
constexpr int kMaxRelaxations = 20;

double sq_dist_point_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    return meshpost::sq_dist_point_triangle(p.data(), a.data(), b.data(), c.data());
}

/// The input surface for "is there an input triangle within `tol` of p?": a TriangleGrid and the
/// triangles' edge neighbours for a greedy walk from the last triangle found.
class InputSurface {
public:
    InputSurface(const TriangleMesh& m, double cell)
        : grid_(m, cell, size_t(1) << 24), adjacent_(face_neighbours(m)) {}

    /// True when some input triangle lies within `tol` of p; then `dist` is that triangle's distance
    /// (not necessarily the smallest) and `hint` its index. The search walks from `hint` (when
    /// valid) towards p over edge neighbours, then scans the grid cells within tol of p.
    bool within(const Vec3& p, double tol, uint32_t& hint, double& dist) const {
        dist = HUGE_VAL;
        double d;
        if (hint < grid_.size()) {
            const uint32_t cur = walk(hint, p);
            if (test(cur, p, tol, d)) {
                dist = d;
                hint = cur;
                return true;
            }
        }
        const Vec3 lo = p - Vec3(tol, tol, tol), hi = p + Vec3(tol, tol, tol);
        grid_.for_triangles_in_box(lo.data(), hi.data(), [&](uint32_t i) {
            if (!test(i, p, tol, d)) return false;
            dist = d;
            hint = i;
            return true;
        });
        return dist <= tol;
    }

    /// True when triangle t (an index, or UINT32_MAX: false) lies within tol of both p and q.
    bool covers(uint32_t t, const Vec3& p, const Vec3& q, double tol) const {
        if (t >= grid_.size()) return false;
        const double tol2 = tol * tol;
        return grid_.sq_dist_within(t, p.data(), tol2) <= tol2 && grid_.sq_dist_within(t, q.data(), tol2) <= tol2;
    }

private:
    /// Walks from triangle t towards p (a few steps): across the edge beyond which p lies
    /// farthest, seen in the triangle's plane, until p's projection falls inside the triangle or
    /// the surface ends there. Reads one triangle a step (a descent that tested the three
    /// neighbours' distances at each step read three).
    uint32_t walk(uint32_t t, const Vec3& p) const {
        for (int step = 0; step < kWalkSteps; ++step) {
            const TriangleGrid::Tri& tri = grid_.triangle(t);
            int across = -1;
            double worst = 0;
            for (int e = 0; e < 3; ++e) {  // edge e runs from corner e to corner e + 1
                const double* a = tri.p[e];
                const double* b = tri.p[(e + 1) % 3];
                const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
                const double w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
                // (u x w) . n: negative when p lies outside this edge; scaled by the edge length.
                const double side = (u[1] * w[2] - u[2] * w[1]) * tri.n[0] + (u[2] * w[0] - u[0] * w[2]) * tri.n[1] +
                                    (u[0] * w[1] - u[1] * w[0]) * tri.n[2];
                const double len2 = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
                if (side < 0 && side * side > worst * len2) {
                    worst = side * side / len2;
                    across = e;
                }
            }
            if (across < 0 || adjacent_[t][size_t(across)] == kNoFace) break;
            t = adjacent_[t][size_t(across)];
        }
        return t;
    }

    bool test(uint32_t i, const Vec3& p, double tol, double& dist) const {
        const TriangleGrid::Tri& t = grid_.triangle(i);
        const double plane = (p[0] - t.p[0][0]) * t.n[0] + (p[1] - t.p[0][1]) * t.n[1] + (p[2] - t.p[0][2]) * t.n[2];
        if (std::fabs(plane) > tol) return false;
        const double d2 = meshpost::sq_dist_point_triangle(p.data(), t.p[0], t.p[1], t.p[2]);
        if (d2 > tol * tol) return false;
        dist = std::sqrt(d2);
        return true;
    }

    static constexpr int kWalkSteps = 6;
    TriangleGrid grid_;
    std::vector<std::array<uint32_t, 3>> adjacent_;  ///< edge neighbours (patches.h; kNoFace: none)
};

/// Min-heap (4-ary) of halfedge indices keyed by collapse cost, with positions for updates; ties
/// go to the smaller index (deterministic order). The keys live in the heap's entries and a
/// node's four children lie side by side (64 bytes), so a sift over the 1.3 M halfedges of CThead
/// misses the cache once or twice per level, on half the levels of a binary heap.
class HalfedgeHeap {
public:
    struct Entry {
        double key;
        uint32_t h;
    };
    explicit HalfedgeHeap(size_t n) : pos_(n, -1) {}
    bool empty() const { return heap_.empty(); }
    double top_key() const { return heap_[0].key; }
    uint32_t top() const { return heap_[0].h; }
    void set(uint32_t h, double key) {
        if (pos_[h] < 0) {
            pos_[h] = int32_t(heap_.size());
            heap_.push_back({key, h});
        } else if (heap_[size_t(pos_[h])].key == key) {
            return;  // unchanged
        } else {
            heap_[size_t(pos_[h])].key = key;
        }
        down(up(size_t(pos_[h])));
    }
    void remove(uint32_t h) {
        if (pos_[h] < 0) return;
        const size_t i = size_t(pos_[h]);
        pos_[h] = -1;
        const Entry last = heap_.back();
        heap_.pop_back();
        if (i < heap_.size()) {
            place(i, last);
            down(up(i));
        }
    }
    /// Replaces the contents by `entries` (distinct halfedges) in linear time.
    void assign(std::vector<Entry> entries) {
        for (const Entry& e : heap_) pos_[e.h] = -1;
        heap_ = std::move(entries);
        for (size_t i = 0; i < heap_.size(); ++i) pos_[heap_[i].h] = int32_t(i);
        for (size_t i = heap_.size() / kArity + 1; i-- > 0;)
            if (i < heap_.size()) down(i);
    }

private:
    static constexpr size_t kArity = 4;
    static bool less(const Entry& a, const Entry& b) { return a.key < b.key || (a.key == b.key && a.h < b.h); }
    void place(size_t i, const Entry& e) {
        heap_[i] = e;
        pos_[e.h] = int32_t(i);
    }
    size_t up(size_t i) {
        const Entry e = heap_[i];
        while (i > 0 && less(e, heap_[(i - 1) / kArity])) {
            place(i, heap_[(i - 1) / kArity]);
            i = (i - 1) / kArity;
        }
        place(i, e);
        return i;
    }
    void down(size_t i) {
        const Entry e = heap_[i];
        for (;;) {
            const size_t first = kArity * i + 1;
            if (first >= heap_.size()) break;
            const size_t last = std::min(first + kArity, heap_.size());
            size_t c = first;
            for (size_t k = first + 1; k < last; ++k)
                if (less(heap_[k], heap_[c])) c = k;
            if (!less(heap_[c], e)) break;
            place(i, heap_[c]);
            i = c;
        }
        place(i, e);
    }

    std::vector<int32_t> pos_;
    std::vector<Entry> heap_;
};

double aspect_ratio(const Vec3& a, const Vec3& b, const Vec3& c) {  // longest edge / its height
    const double l2 = std::max({(a - b).sqrnorm(), (b - c).sqrnorm(), (c - a).sqrnorm()});
    const double a2 = ((b - a) % (c - a)).sqrnorm();
    return a2 > 0 ? l2 / std::sqrt(a2) : HUGE_VAL;
}

using Quadric = OpenMesh::Geometry::Quadricd;

/// What every worker of a decimation shares: the mesh and the per-element data that collapses
/// update (each collapse only touches the elements around it, so collapses in parts of the mesh
/// that are more than two rings apart can run at once; see Decimator::run_region).
struct DecimationState {
    /// `input_face`: the input face of each face of `mesh`.
    DecimationState(OMesh& mesh, const std::vector<uint32_t>& input_face, const TriangleMesh& input,
                    const SimplifyParams& p)
        : om(mesh), pts(mesh.points()), tol(p.max_error_mm) {
        om.cache_status();
        min_cos = std::cos(p.max_normal_deviation_deg * M_PI / 180.0);
        max_aspect = p.max_aspect_ratio;
        faces = om.n_faces();
        // The input's search structure is built beside the per-element data (both read only
        // the input and the mesh).
#pragma omp parallel sections
        {
#pragma omp section
            {
                if (tol > 0) surface = std::make_unique<InputSurface>(input, 2 * tol);
            }
#pragma omp section
            {
                normals.resize(om.n_faces());
                for (const auto f : om.faces()) normals[f.idx()] = face_normal(f);
                quadrics.assign(om.n_vertices(), Quadric());
                for (const auto f : om.faces()) {
                    auto fv = om.cfv_begin(f);
                    const Vec3 a = pts[fv->idx()], b = pts[(++fv)->idx()], c = pts[(++fv)->idx()];
                    Vec3 n = (b - a) % (c - a);
                    double area = n.norm();
                    if (area > FLT_MIN) {
                        n /= area;
                        area *= 0.5;
                    }
                    Quadric q(n[0], n[1], n[2], -(a | n));
                    q *= area;
                    for (const auto v : om.fv_range(f)) quadrics[v.idx()] += q;
                }
                if (tol > 0) {
                    on_triangle.assign(om.n_vertices(), UINT32_MAX);
                    points.resize(om.n_faces());
                    for (const auto f : om.faces()) {
                        Vec3 c(0, 0, 0);
                        for (const auto v : om.fv_range(f)) {
                            on_triangle[v.idx()] = input_face[size_t(f.idx())];
                            c += pts[v.idx()];
                        }
                        points[f.idx()].push_back(c / 3.0);
                    }
                }
            }
        }
    }

    Vec3 face_normal(OMesh::FaceHandle f) const {
        auto fv = om.cfv_begin(f);
        const Vec3 a = pts[fv->idx()], b = pts[(++fv)->idx()], c = pts[(++fv)->idx()];
        const Vec3 n = (b - a) % (c - a);
        const double len = n.norm();
        return len > 0 ? n / len : Vec3(0, 0, 0);
    }

    OMesh& om;
    const Vec3* pts;  ///< om's points (collapses move none)
    double tol;       ///< the distance bound in force, mm (0: off)
    double min_cos = 0.5, max_aspect = 0;
    size_t faces = 0;  ///< faces left
    std::vector<Vec3> normals;  ///< unit face normals, updated after each collapse
    std::vector<Quadric> quadrics;
    std::unique_ptr<InputSurface> surface;
    std::vector<std::vector<Vec3>> points;  ///< input points carried by each face
    /// For each vertex, an input triangle it is a corner of (the vertices stay at their input
    /// positions): the distance 0 to start the output -> input test of a new face from.
    std::vector<uint32_t> on_triangle;
};

/// Halfedge-collapse decimation ordered by quadric error; see simplify.h for the rules. The
/// distance bound (tol > 0) is checked lazily, only for the collapse at the top of the heap: a
/// collapse that fails it leaves the heap until a collapse changes its neighbourhood. A worker:
/// its heap and scratch arrays are its own, the mesh and its data are shared (DecimationState).
class Decimator {
    using VH = OMesh::VertexHandle;

public:
    explicit Decimator(DecimationState& s) : s_(s), om_(s.om), pts_(s.pts), heap_(s.om.n_halfedges()) {}

    /// Collapses over the whole mesh until `target` faces remain or no legal collapse is left;
    /// returns how many collapses the distance bound refused.
    size_t run(size_t target) {
        size_t refused = 0;
        std::vector<HalfedgeHeap::Entry> all;
        all.reserve(om_.n_halfedges());
        for (const auto h : om_.halfedges())
            if (queued(h)) all.push_back({cost(h), uint32_t(h.idx())});
        heap_.assign(std::move(all));
        removed_ = 0;
        while (s_.faces - removed_ > target && !heap_.empty()) {
            const HH h(int(heap_.top()));
            heap_.remove(uint32_t(h.idx()));
            if (!legal(h)) continue;
            if (s_.tol > 0 && !distance_ok(h)) {
                ++refused;
                continue;
            }
            if (!embedded_after(h)) continue;
            collapse(h);
        }
        s_.faces -= removed_;
        return refused;
    }

    /// Collapses inside one region (`owner[v] == region` for its vertices `verts`; `border`
    /// marks the vertices with a neighbour in another region) until `remove` faces are gone or no
    /// legal collapse is left, taking only collapses whose removed vertex has its two rings of
    /// neighbours in the region (see inside()): such a collapse reads and writes only elements
    /// around vertices of the region, and no other region changes them, so regions can be
    /// decimated at the same time (each by its own worker) and each region's result depends on
    /// the region alone. Returns the faces removed; the caller subtracts them from the state's
    /// count.
    size_t run_region(const std::vector<uint32_t>& verts, const std::vector<uint16_t>& owner,
                      const std::vector<uint8_t>& border, uint16_t region, size_t remove, double max_cost) {
        border_ = &border;
        std::vector<HalfedgeHeap::Entry> all;
        for (const uint32_t v : verts)
            for (const HH h : om_.voh_range(VH(int(v))))
                if (owner[size_t(om_.to_vertex_handle(h).idx())] == region && queued(h))
                    all.push_back({cost(h), uint32_t(h.idx())});
        heap_.assign(std::move(all));
        removed_ = 0;
        while (removed_ < remove && !heap_.empty() && heap_.top_key() <= max_cost) {
            const HH h(int(heap_.top()));
            heap_.remove(uint32_t(h.idx()));
            if (!inside(h) || !legal(h)) continue;
            if (s_.tol > 0 && !distance_ok(h)) continue;
            if (!embedded_after(h)) continue;
            collapse(h);
        }
        heap_.assign({});
        border_ = nullptr;
        return removed_;
    }

    /// The cheapest queued collapse of vertex v (HUGE_VAL: none).
    double min_cost(VH v) const {
        double c = HUGE_VAL;
        for (const HH h : om_.voh_range(v))
            if (queued(h)) c = std::min(c, cost(h));
        return c;
    }

private:
    using HH = OMesh::HalfedgeHandle;
    using FH = OMesh::FaceHandle;

    /// Region mode: whether v0 of h and its two rings of neighbours all belong to h's region, i.e.
    /// neither v0 nor a neighbour of it is a border vertex (one with a neighbour in another
    /// region; a region never collapses a border vertex or a neighbour of one, so the border
    /// vertices' links to the other regions stay as they are). Reads v0's neighbours only.
    bool inside(HH h) const {
        const VH v0 = om_.from_vertex_handle(h);
        if ((*border_)[size_t(v0.idx())]) return false;
        for (const VH w : om_.vv_range(v0))
            if ((*border_)[size_t(w.idx())]) return false;
        return true;
    }

    /// Whether h belongs in the queue: its edge is not deleted and its origin not locked.
    bool queued(HH h) const {
        return !om_.estatus(om_.edge_handle(h)).deleted() && !om_.vstatus(om_.from_vertex_handle(h)).locked();
    }
    /// The quadric error of collapsing h (at the surviving vertex's position).
    double cost(HH h) const {
        const VH v0 = om_.from_vertex_handle(h), v1 = om_.to_vertex_handle(h);
        Quadric q = s_.quadrics[v0.idx()];
        q += s_.quadrics[v1.idx()];
        return q(pts_[v1.idx()]);
    }

    /// Queues h by its quadric cost; its legality is checked when it reaches the top.
    void evaluate(HH h) {
        if (queued(h)) heap_.set(uint32_t(h.idx()), cost(h));
        else heap_.remove(uint32_t(h.idx()));
    }

    /// The cheap rules: topology (as OpenMesh's decimater), locks, normals, aspect ratio.
    bool legal(HH h) {
        if (om_.estatus(om_.edge_handle(h)).deleted()) return false;
        const HH o = om_.opposite_halfedge_handle(h);
        const VH v0 = om_.to_vertex_handle(o), v1 = om_.to_vertex_handle(h);
        if (om_.vstatus(v0).locked() || !om_.is_collapse_ok(h, link_stamp_, link_current_)) return false;
        const VH vl = om_.is_boundary(h) ? VH() : om_.to_vertex_handle(om_.next_halfedge_handle(h));
        const VH vr = om_.is_boundary(o) ? VH() : om_.to_vertex_handle(om_.next_halfedge_handle(o));
        if (vl.is_valid() && vr.is_valid() && om_.find_halfedge(vl, vr).is_valid() && om_.valence(vl) == 3 &&
            om_.valence(vr) == 3)
            return false;  // the edge link condition (a tetrahedron)
        if (om_.is_boundary(v0) && (!om_.is_boundary(v1) || (vl.is_valid() && vr.is_valid()))) return false;
        if (om_.cw_rotated_halfedge_handle(om_.cw_rotated_halfedge_handle(h)) == h) return false;
        const FH fl = om_.face_handle(h), fr = om_.face_handle(o);
        const Vec3 p1 = pts_[v1.idx()];
        double worst_before = 0, worst_after = 0;
        for (const FH f : om_.vf_range(v0)) {
            Vec3 before[3], after[3];
            int k = 0;
            for (const VH v : om_.fv_range(f)) {
                before[k] = pts_[v.idx()];
                after[k++] = v == v0 ? p1 : pts_[v.idx()];
            }
            if (s_.max_aspect > 0) worst_before = std::max(worst_before, aspect_ratio(before[0], before[1], before[2]));
            if (f == fl || f == fr) continue;
            Vec3 n = (after[1] - after[0]) % (after[2] - after[0]);
            const double len = n.norm();
            if (!(len > 0) || ((n / len) | s_.normals[f.idx()]) < s_.min_cos) return false;
            if (s_.max_aspect > 0) worst_after = std::max(worst_after, aspect_ratio(after[0], after[1], after[2]));
        }
        return !(s_.max_aspect > 0 && !(worst_after < worst_before || worst_after < s_.max_aspect));
    }

    /// The vertices of halfedge h (v0 -> v1, v0 removed by its collapse) and the faces beside it.
    struct Ends {
        VH v0, v1;
        FH fl, fr;
    };
    Ends ends(HH h) const {
        const HH o = om_.opposite_halfedge_handle(h);
        return {om_.to_vertex_handle(o), om_.to_vertex_handle(h), om_.face_handle(h), om_.face_handle(o)};
    }

    /// The distance bound for collapsing h: every sample of the new faces lies within tol of the
    /// input surface, and every input point carried by the faces around v0 (and v0 itself) lies
    /// within tol of the faces around v1 after the collapse. Fills moved_ with those points and
    /// their nearest face.
    bool distance_ok(HH h) {
        const auto [v0, v1, fl, fr] = ends(h);
        around_.clear();
        for (const VH v : {v0, v1})
            for (const FH f : om_.vf_range(v)) {
                if (f == fl || f == fr) continue;
                Around a;
                a.f = f;
                int k = 0;
                for (const VH u : om_.fv_range(f)) {
                    const VH w = u == v0 ? v1 : u;
                    a.p[k] = pts_[w.idx()];
                    a.t[k++] = s_.on_triangle[w.idx()];
                }
                a.n = (a.p[1] - a.p[0]) % (a.p[2] - a.p[0]);
                const double len = a.n.norm();
                a.n = len > 0 ? a.n / len : Vec3(0, 0, 0);
                a.moved = v == v0;
                a.lo = a.hi = a.p[0];
                for (int j = 1; j < 3; ++j) {
                    a.lo.minimize(a.p[j]);
                    a.hi.maximize(a.p[j]);
                }
                around_.push_back(a);
            }
        // Input -> output: the carried points. Each goes to the first of the faces around the
        // collapse at the smallest distance. The search starts at `first`, the face that carries
        // the point now (the nearest one, mostly), and skips the faces whose bounding box or
        // plane lies farther than the best so far.
        moved_.clear();
        const double tol2 = s_.tol * s_.tol;
        auto carry = [&](const Vec3& q, size_t first) {
            double best = HUGE_VAL;
            size_t bi = 0;
            const size_t n = around_.size();
            for (size_t j = 0; j < n; ++j) {
                const size_t i = first + j < n ? first + j : first + j - n;
                const Around& a = around_[i];
                double box2 = 0;
                for (int k = 0; k < 3; ++k) {
                    const double e = q[k] < a.lo[k] ? a.lo[k] - q[k] : (q[k] > a.hi[k] ? q[k] - a.hi[k] : 0.0);
                    box2 += e * e;
                }
                if (box2 > best) continue;
                const double plane = (q - a.p[0]) | a.n;
                if (plane * plane > best) continue;
                const double d2 = sq_dist_point_triangle(q, a.p[0], a.p[1], a.p[2]);
                if (d2 < best || (d2 == best && i < bi)) {
                    best = d2;
                    bi = i;
                }
            }
            if (best > tol2) return false;
            moved_.push_back({q, around_[bi].f});
            return true;
        };
        if (!carry(pts_[v0.idx()], 0)) return false;
        size_t own = 0;  // around_ starts with the faces around v0 but fl and fr, in this order
        for (const FH f : om_.vf_range(v0)) {
            const size_t first = f == fl || f == fr ? 0 : own++;
            for (const Vec3& q : s_.points[f.idx()])
                if (!carry(q, first)) return false;
        }
        // Output -> input: samples of the faces that move.
        for (const Around& a : around_)
            if (a.moved && !near_input(a.p[0], a.p[1], a.p[2], a.t)) return false;
        return true;
    }

    /// True when triangle abc, whose corners lie on the input, passes the output -> input test:
    /// it is split in 4 recursively until each piece is proven within tol of the input or has
    /// edges <= kSpacing * tol. A point of a piece lies within R (the piece's cover radius) of one
    /// of its corners, and the distance to the input is 1-Lipschitz, so a piece whose corners lie
    /// within d of the input is within d + R; a smallest piece needs d <= tol at its corners.
    bool near_input(const Vec3& a, const Vec3& b, const Vec3& c, const uint32_t (&t)[3]) {
        const double g = kSpacing * s_.tol;
        const double longest2 = std::max({(a - b).sqrnorm(), (b - c).sqrnorm(), (c - a).sqrnorm()});
        int levels = 0;
        for (double l2 = longest2; l2 > g * g; l2 *= 0.25) ++levels;
        return near_input(a, b, c, 0, 0, 0, t[0], t[1], t[2], levels);
    }

    /// Largest distance from a point of triangle abc to its nearest corner: the circumradius of an
    /// acute triangle, half the longest edge otherwise.
    static double cover_radius(const Vec3& a, const Vec3& b, const Vec3& c) {
        double e[3] = {(b - c).sqrnorm(), (c - a).sqrnorm(), (a - b).sqrnorm()};
        std::sort(e, e + 3);
        if (e[2] >= e[0] + e[1]) return 0.5 * std::sqrt(e[2]);
        const double area2 = ((b - a) % (c - a)).norm();  // twice the area
        return std::sqrt(e[0] * e[1] * e[2]) / (2.0 * area2);
    }

    /// `ta`, `tb`, `tc`: an input triangle within tol of a, b, c (UINT32_MAX: unknown). The
    /// distance to one triangle is convex, so a piece whose three corners lie within tol of the
    /// same input triangle lies within tol of it everywhere.
    bool near_input(const Vec3& a, const Vec3& b, const Vec3& c, double da, double db, double dc, uint32_t ta,
                    uint32_t tb, uint32_t tc, int levels) {
        if (levels == 0 || std::max({da, db, dc}) + cover_radius(a, b, c) <= s_.tol) return true;
        if (s_.surface->covers(ta, b, c, s_.tol) || (tb != ta && s_.surface->covers(tb, c, a, s_.tol)) ||
            (tc != ta && tc != tb && s_.surface->covers(tc, a, b, s_.tol)))
            return true;
        const Vec3 ab = (a + b) * 0.5, bc = (b + c) * 0.5, ca = (c + a) * 0.5;
        double dab, dbc, dca;
        // Each midpoint's search starts from a corner's triangle, so the test of a face depends on
        // the face alone (not on the faces tested before it).
        uint32_t tab = ta, tbc = tb, tca = tc;
        if (!s_.surface->within(ab, s_.tol, tab, dab)) return false;
        if (!s_.surface->within(bc, s_.tol, tbc, dbc)) return false;
        if (!s_.surface->within(ca, s_.tol, tca, dca)) return false;
        --levels;
        return near_input(ab, bc, ca, dab, dbc, dca, tab, tbc, tca, levels) &&
               near_input(a, ab, ca, da, dab, dca, ta, tab, tca, levels) &&
               near_input(ab, b, bc, dab, db, dbc, tab, tb, tbc, levels) &&
               near_input(ca, bc, c, dca, dbc, dc, tca, tbc, tc, levels);
    }

    /// orient3d in doubles: > 0 when d lies above the plane of abc (counter-clockwise seen from
    /// above).
    static double orient(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
        return ((b - a) % (c - a)) | (d - a);
    }

    /// True when segment pq crosses or touches triangle abc; false when they are coplanar (that
    /// case is left to simplify_verified's exact check).
    static bool segment_meets_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
        const double o1 = orient(a, b, c, p), o2 = orient(a, b, c, q);
        if ((o1 > 0 && o2 > 0) || (o1 < 0 && o2 < 0) || (o1 == 0 && o2 == 0)) return false;
        const double s1 = orient(p, q, a, b), s2 = orient(p, q, b, c), s3 = orient(p, q, c, a);
        return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
    }

    struct LocalFace {
        int v[3];
        Vec3 p[3], lo, hi;
    };

    /// True when two faces that share at most one vertex intersect other than at it (edge-sharing
    /// pairs are left to the normal test).
    static bool faces_intersect(const LocalFace& a, const LocalFace& b) {
        for (int k = 0; k < 3; ++k)
            if (a.lo[k] > b.hi[k] || b.lo[k] > a.hi[k]) return false;
        int shared = 0, ia = 0, ib = 0;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                if (a.v[i] == b.v[j]) {
                    ++shared;
                    ia = i;
                    ib = j;
                }
        if (shared >= 2) return false;
        if (shared == 1)  // the edge opposite the shared vertex in one meets the other
            return segment_meets_triangle(a.p[(ia + 1) % 3], a.p[(ia + 2) % 3], b.p[0], b.p[1], b.p[2]) ||
                   segment_meets_triangle(b.p[(ib + 1) % 3], b.p[(ib + 2) % 3], a.p[0], a.p[1], a.p[2]);
        for (int k = 0; k < 3; ++k)
            if (segment_meets_triangle(a.p[k], a.p[(k + 1) % 3], b.p[0], b.p[1], b.p[2]) ||
                segment_meets_triangle(b.p[k], b.p[(k + 1) % 3], a.p[0], a.p[1], a.p[2]))
                return true;
        return false;
    }

    LocalFace local_face(FH f, VH v0, const Vec3& p1, VH v1) const {
        LocalFace l;
        int k = 0;
        for (const VH u : om_.fv_range(f)) {
            l.v[k] = u == v0 ? v1.idx() : u.idx();
            l.p[k++] = u == v0 ? p1 : pts_[u.idx()];
        }
        l.lo = l.p[0];
        l.hi = l.p[0];
        for (int j = 1; j < 3; ++j) {
            l.lo.minimize(l.p[j]);
            l.hi.maximize(l.p[j]);
        }
        return l;
    }

    /// Local self-intersection test of collapsing h: the faces that move (v0 -> v1) must not cross
    /// each other or the faces around v0, v1 and their neighbours (the intersecting pairs that
    /// simplify_verified found on CThead shared a vertex or were one edge apart; with this test it
    /// finds none there and needs no repair round). Floating-point orientations, coplanar pairs
    /// skipped: simplify_verified's exact check stays the guarantee.
    bool embedded_after(HH h) {
        const auto [v0, v1, fl, fr] = ends(h);
        const Vec3 p1 = pts_[v1.idx()];
        moving_.clear();
        for (const FH f : om_.vf_range(v0))
            if (f != fl && f != fr) moving_.push_back(local_face(f, v0, p1, v1));
        for (size_t i = 0; i < moving_.size(); ++i)
            for (size_t j = i + 1; j < moving_.size(); ++j)
                if (faces_intersect(moving_[i], moving_[j])) return false;
        if (moving_.empty()) return true;
        // The faces that stay around v0, v1 and their neighbours (one halfedge walk each), tested
        // when their bounding box meets that of the moving faces.
        Vec3 lo = moving_[0].lo, hi = moving_[0].hi;
        for (const LocalFace& m : moving_) {
            lo.minimize(m.lo);
            hi.maximize(m.hi);
        }
        if (vstamp_.size() < om_.n_vertices()) vstamp_.resize(om_.n_vertices(), 0);
        if (fstamp_.size() < om_.n_faces()) fstamp_.resize(om_.n_faces(), 0);
        ++stamp_;
        ring_.clear();
        for (const VH v : {v0, v1}) {
            vstamp_[v.idx()] = stamp_;
            ring_.push_back(v);
        }
        for (size_t i = 0; i < 2; ++i)
            for (const VH w : om_.vv_range(ring_[i]))
                if (vstamp_[w.idx()] != stamp_) {
                    vstamp_[w.idx()] = stamp_;
                    ring_.push_back(w);
                }
        for (const FH f : om_.vf_range(v0)) fstamp_[f.idx()] = stamp_;
        LocalFace b;
        for (const VH w : ring_)
            for (const HH g : om_.voh_range(w)) {
                const FH f = om_.face_handle(g);
                if (!f.is_valid() || fstamp_[f.idx()] == stamp_) continue;
                fstamp_[f.idx()] = stamp_;
                const HH n = om_.next_halfedge_handle(g);
                b.v[0] = w.idx();
                b.v[1] = om_.to_vertex_handle(g).idx();
                b.v[2] = om_.to_vertex_handle(n).idx();
                bool apart = false;
                for (int k = 0; k < 3; ++k) b.p[k] = pts_[b.v[k]];
                b.lo = b.p[0];
                b.hi = b.p[0];
                for (int k = 1; k < 3; ++k) {
                    b.lo.minimize(b.p[k]);
                    b.hi.maximize(b.p[k]);
                }
                for (int k = 0; k < 3; ++k) apart = apart || b.lo[k] > hi[k] || lo[k] > b.hi[k];
                if (apart) continue;
                for (const LocalFace& m : moving_)
                    if (faces_intersect(m, b)) return false;
            }
        return true;
    }

    void collapse(HH h) {
        const VH v0 = om_.from_vertex_handle(h), v1 = om_.to_vertex_handle(h);
        s_.quadrics[v1.idx()] += s_.quadrics[v0.idx()];
        removed_ += (om_.is_boundary(h) || om_.is_boundary(om_.opposite_halfedge_handle(h))) ? 1 : 2;
        if (s_.tol > 0)
            for (const FH f : om_.vf_range(v0)) s_.points[f.idx()].clear();
        support_.clear();
        for (const VH w : om_.vv_range(v0))
            if (w != v1) support_.push_back(w);
        om_.collapse(h);
        for (const FH f : om_.vf_range(v1)) s_.normals[f.idx()] = s_.face_normal(f);
        if (s_.tol > 0)
            for (const auto& m : moved_) s_.points[m.f.idx()].push_back(m.q);
        // Costs change for the edges at v1, legality for the edges around v0's former neighbours
        // (refused ones get another chance); nothing changes elsewhere.
        for (const HH g : om_.voh_range(v1)) {
            evaluate(g);
            evaluate(om_.opposite_halfedge_handle(g));
        }
        for (const VH w : support_)
            for (const HH g : om_.voh_range(w)) evaluate(g);
    }

    /// Sample spacing of the new faces, in units of the tolerance.
    static constexpr double kSpacing = 0.5;

    struct Around {
        FH f;
        Vec3 p[3], n, lo, hi;
        uint32_t t[3];  ///< an input triangle at each corner (see s_.on_triangle)
        bool moved = false;
    };
    struct Moved {
        Vec3 q;
        FH f;
    };

    DecimationState& s_;
    OMesh& om_;
    const Vec3* pts_;  ///< om_'s points (collapses move none)
    HalfedgeHeap heap_;
    size_t removed_ = 0;  ///< faces removed by this worker's current run
    const std::vector<uint8_t>* border_ = nullptr;  ///< region mode: the border vertices
    std::vector<Around> around_;
    std::vector<Moved> moved_;
    std::vector<VH> support_;
    std::vector<LocalFace> moving_;
    std::vector<VH> ring_;
    std::vector<uint32_t> vstamp_, fstamp_;
    uint32_t stamp_ = 0;
    std::vector<uint32_t> link_stamp_;  ///< OMesh::is_collapse_ok's marks
    uint32_t link_current_ = 0;
};

/// One parallel pass: each region (`owner`, `regions` of them) is decimated on its own, in
/// parallel, except near its borders (see Decimator::run_region), in rounds: each round takes the
/// collapses cheaper than a threshold, the cost below which the cheapest collapses of as many
/// vertices lie as the target needs (costs rise as the decimation goes on, so a round falls
/// short of the target); a region takes at most its share of them (its vertices among those),
/// so the regions never overshoot the target together. The rounds follow the order of a global
/// decimation by cost, closely: each region's faces end up where they are needed.
void decimate_regions(DecimationState& state, const std::vector<uint16_t>& owner, size_t regions, size_t target) {
    const OMesh& om = state.om;
    const size_t nv = owner.size();
    std::vector<std::vector<uint32_t>> verts(regions);
    for (uint32_t v = 0; v < nv; ++v)
        if (!om.status(OMesh::VertexHandle(int(v))).deleted()) verts[owner[v]].push_back(v);
    // Border vertices: those with a neighbour in another region; frozen ones: those and their
    // neighbours, which no region collapses (a region's collapse never gives a vertex a border
    // neighbour, so the sets stay as they are).
    std::vector<uint8_t> border(nv, 0);
    for (const auto e : om.edges()) {
        if (om.estatus(e).deleted()) continue;
        const auto h = om.halfedge_handle(e, 0);
        const size_t a = size_t(om.from_vertex_handle(h).idx()), b = size_t(om.to_vertex_handle(h).idx());
        if (owner[a] != owner[b]) border[a] = border[b] = 1;
    }
    std::vector<uint8_t> frozen = border;
    for (const auto e : om.edges()) {
        if (om.estatus(e).deleted()) continue;
        const auto h = om.halfedge_handle(e, 0);
        const size_t a = size_t(om.from_vertex_handle(h).idx()), b = size_t(om.to_vertex_handle(h).idx());
        if (border[a] || border[b]) frozen[a] = frozen[b] = 1;
    }
    std::vector<double> cost(nv);
    for (int round = 0; round < kRounds && state.faces > target + 1; ++round) {
        const size_t need = (state.faces - target) / 2;  // collapses
        {
            Decimator probe(state);
#pragma omp parallel for schedule(static)
            for (long v = 0; v < long(nv); ++v) {
                const OMesh::VertexHandle vh{int(v)};
                cost[size_t(v)] = om.status(vh).deleted() ? HUGE_VAL : probe.min_cost(vh);
            }
        }
        std::vector<double> sorted = cost;
        std::nth_element(sorted.begin(), sorted.begin() + long(need), sorted.end());
        const double threshold = sorted[need];
        std::vector<size_t> below(regions + 1, 0);  // per region, and (last) frozen
        for (size_t v = 0; v < nv; ++v)
            if (cost[v] <= threshold) ++below[frozen[v] ? regions : owner[v]];
        size_t all = 0;
        for (const size_t n : below) all += n;
        std::vector<size_t> removed(regions, 0);
#pragma omp parallel
        {
            Decimator worker(state);
#pragma omp for schedule(dynamic, 1)
            for (long k = 0; k < long(regions); ++k) {
                const size_t share = size_t(double(need) * double(below[size_t(k)]) / double(std::max<size_t>(all, 1)));
                removed[size_t(k)] = worker.run_region(verts[size_t(k)], owner, border, uint16_t(k), 2 * share, threshold);
            }
        }
        size_t total = 0;
        for (const size_t n : removed) total += n;
        state.faces -= total;
        if (total == 0) break;
    }
}

/// The parallel passes: the slabs (pairs of half slabs, see slab_regions), then the slabs
/// shifted by half a slab, whose interiors hold the first slabs' seams; the serial pass then has
/// only the second slabs' seams left (in parts already decimated). The regions depend on the
/// mesh alone, so the result is the same for any number of threads.
void decimate_in_parallel(DecimationState& state, const Prepared& prep, size_t target) {
    if (prep.regions < 2) return;
    std::vector<uint16_t> owner(prep.half.size());
    for (size_t v = 0; v < owner.size(); ++v) owner[v] = uint16_t(prep.half[v] / 2);
    decimate_regions(state, owner, prep.regions, target);
    for (size_t v = 0; v < owner.size(); ++v) owner[v] = uint16_t((prep.half[v] + 1) / 2);
    decimate_regions(state, owner, prep.regions + 1, target);
}

}  // namespace

SimplifyResult simplify(const TriangleMesh& mesh, const SimplifyParams& params) {
    if (!(params.max_normal_deviation_deg > 0.0 && params.max_normal_deviation_deg <= 180.0))
        throw std::invalid_argument("simplify: max_normal_deviation_deg must be in (0, 180], got " +
                                    std::to_string(params.max_normal_deviation_deg));
    if (!(params.max_aspect_ratio == 0.0 || params.max_aspect_ratio >= 1.0))
        throw std::invalid_argument("simplify: max_aspect_ratio must be 0 (off) or >= 1, got " +
                                    std::to_string(params.max_aspect_ratio));
    if (!(params.max_error_mm >= 0.0) || !std::isfinite(params.max_error_mm))
        throw std::invalid_argument("simplify: max_error_mm must be >= 0 (0 = off), got " +
                                    std::to_string(params.max_error_mm));
    SimplifyResult r;
    r.faces_before = mesh.faces.size();
    if (params.target_faces > 0) {
        r.target_faces = params.target_faces;
    } else {
        if (!(params.ratio > 0.0 && params.ratio <= 1.0))
            throw std::invalid_argument("simplify: ratio must be in (0, 1], got " + std::to_string(params.ratio));
        r.target_faces = static_cast<size_t>(std::llround(params.ratio * static_cast<double>(r.faces_before)));
        if (r.target_faces == 0) r.target_faces = 1;
    }

    if (!params.locked_vertices.empty() && params.locked_vertices.size() != mesh.vertices.size())
        throw std::invalid_argument("simplify: locked_vertices holds " +
                                    std::to_string(params.locked_vertices.size()) +
                                    " flags, the mesh has " + std::to_string(mesh.vertices.size()) +
                                    " vertices");
    Prepared prep = to_openmesh(mesh, params.locked_vertices);
    OMesh& om = prep.om;
    om.request_vertex_status();
    om.request_edge_status();
    om.request_halfedge_status();
    om.request_face_status();
    {
        DecimationState state(om, prep.input_face, mesh, params);
        if (state.faces > r.target_faces) decimate_in_parallel(state, prep, r.target_faces);
        // The whole mesh (the regions' seams and whatever is left); the distance bound is relaxed
        // when it stops the decimation short of the target.
        Decimator dec(state);
        for (int round = 0; state.faces > r.target_faces; ++round) {
            const size_t refused = dec.run(r.target_faces);
            if (state.faces <= r.target_faces || refused == 0 || round == kMaxRelaxations) break;
            state.tol *= kRelaxFactor;
        }
        r.max_error_used_mm = state.tol;
    }
    om.garbage_collection();
    r.mesh = from_openmesh(om);
    r.faces_after = r.mesh.faces.size();
    r.volume_before_mm3 = signed_volume_mm3(mesh);
    r.volume_after_mm3 = signed_volume_mm3(r.mesh);
    r.volume_change_pct = r.volume_before_mm3 != 0.0
                              ? 100.0 * (r.volume_after_mm3 - r.volume_before_mm3) / std::fabs(r.volume_before_mm3)
                              : 0.0;
    return r;
}

TriangleMesh cluster_vertices(const TriangleMesh& mesh, double cell_mm) {
    if (!(cell_mm > 0) || !std::isfinite(cell_mm))
        throw std::invalid_argument("cluster_vertices: cell " + std::to_string(cell_mm) + " mm, expected a finite value > 0");
    TriangleMesh out;
    if (mesh.vertices.empty()) return out;
    for (const Face& f : mesh.faces)
        for (uint32_t v : f)
            if (v >= mesh.vertices.size())
                throw InvalidMesh("cluster_vertices: face index " + std::to_string(v) + " >= " +
                                  std::to_string(mesh.vertices.size()) + " vertices");
    Point lo = mesh.vertices[0];
    for (const Point& p : mesh.vertices)
        for (size_t a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]);
    // Cell key of each vertex; cells numbered in order of their first vertex.
    std::unordered_map<uint64_t, uint32_t> cell_of;
    cell_of.reserve(mesh.vertices.size() / 4);
    std::vector<uint32_t> to(mesh.vertices.size());
    std::vector<std::array<double, 4>> sum;  // x, y, z, count
    for (size_t v = 0; v < mesh.vertices.size(); ++v) {
        uint64_t key = 0;
        for (size_t a = 0; a < 3; ++a)
            key = key << 21 | (uint64_t(std::floor((mesh.vertices[v][a] - lo[a]) / cell_mm)) & ((1u << 21) - 1));
        const auto [it, added] = cell_of.try_emplace(key, uint32_t(sum.size()));
        if (added) sum.push_back({0, 0, 0, 0});
        auto& s = sum[it->second];
        for (size_t a = 0; a < 3; ++a) s[a] += mesh.vertices[v][a];
        s[3] += 1;
        to[v] = it->second;
    }
    out.vertices.resize(sum.size());
    for (size_t c = 0; c < sum.size(); ++c)
        out.vertices[c] = {sum[c][0] / sum[c][3], sum[c][1] / sum[c][3], sum[c][2] / sum[c][3]};
    std::vector<std::array<uint32_t, 3>> seen;  // each kept face, rotated to start at its smallest index
    for (const Face& f : mesh.faces) {
        const Face g{to[f[0]], to[f[1]], to[f[2]]};
        if (g[0] == g[1] || g[1] == g[2] || g[0] == g[2]) continue;
        const size_t m = g[0] < g[1] ? (g[0] < g[2] ? 0 : 2) : (g[1] < g[2] ? 1 : 2);
        seen.push_back({g[m], g[(m + 1) % 3], g[(m + 2) % 3]});
    }
    std::vector<size_t> order(seen.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return seen[a] < seen[b]; });
    std::vector<uint8_t> keep(seen.size(), 1);
    for (size_t k = 1; k < order.size(); ++k)
        if (seen[order[k]] == seen[order[k - 1]]) keep[order[k]] = 0;
    for (size_t k = 0; k < seen.size(); ++k)
        if (keep[k]) out.faces.push_back({seen[k][0], seen[k][1], seen[k][2]});
    return out;
}

double cluster_cell_for_faces(const TriangleMesh& mesh, size_t target_faces) {
    if (mesh.faces.empty() || target_faces == 0) return 0;
    double area = 0;
    for (const Face& f : mesh.faces) {
        const Point c = face_cross(mesh, f);
        area += 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    }
    return std::sqrt(2.0 * area / double(target_faces));
}

}  // namespace meshpost
