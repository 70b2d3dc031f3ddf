// Quadric-error simplification with OpenMesh's DecimaterT (see simplify.h).
#include "meshpost/simplify.h"

// OpenMesh properties push_back default-constructed (uninitialised) VectorT values, which GCC 12
// reports as maybe-uninitialized when inlined; the values are always assigned before use.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModAspectRatioT.hh>
#include <OpenMesh/Tools/Decimater/ModHausdorffT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "meshpost/measure.h"

namespace meshpost {
namespace {

struct DoubleTraits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
using BaseMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

/// OpenMesh's mesh with its own collapse test: OpenMesh 9's TriConnectivity::is_collapse_ok looks
/// a property up by name on every call, which made it half of the decimation time. DecimaterT
/// calls `is_collapse_ok` on its mesh type, so this one (the link condition, with a vertex stamp
/// array instead of property lookups) replaces it.
class OMesh : public BaseMesh {
public:
    /// True when collapsing halfedge h (v0 -> v1, v0 removed) keeps the surface a manifold of the
    /// same topology: the common neighbours of v0 and v1 are exactly the opposite vertices vl, vr
    /// of the edge's faces (vertex link condition) and boundaries are not pinched. (The edge link
    /// condition, which only fails for a tetrahedron, is tested by DecimaterT itself.)
    bool is_collapse_ok(HalfedgeHandle h) {
        const HalfedgeHandle o = opposite_halfedge_handle(h);
        if (status(edge_handle(h)).deleted()) return false;
        const VertexHandle v0 = to_vertex_handle(o), v1 = to_vertex_handle(h);
        if (status(v0).deleted() || status(v1).deleted()) return false;
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
        if (stamp_.size() < n_vertices()) stamp_.resize(n_vertices(), 0);
        if (++current_ == 0) {  // wrapped around: clear
            std::fill(stamp_.begin(), stamp_.end(), 0);
            current_ = 1;
        }
        for (const VertexHandle v : vv_range(v0)) stamp_[v.idx()] = current_;
        for (const VertexHandle v : vv_range(v1))
            if (stamp_[v.idx()] == current_ && v != vl && v != vr) return false;
        return true;
    }

private:
    std::vector<uint32_t> stamp_;
    uint32_t current_ = 0;
};

/// `locked`: empty, or one flag per input vertex (non-zero: the vertex is locked).
OMesh to_openmesh(const TriangleMesh& in, const std::vector<uint8_t>& locked) {
    const size_t nv = in.vertices.size();
    std::vector<char> used(nv, 0);
    for (size_t f = 0; f < in.faces.size(); ++f)
        for (uint32_t v : in.faces[f]) {
            if (v >= nv)
                throw InvalidMesh("simplify: face " + std::to_string(f) + " references vertex " + std::to_string(v) +
                                  " but the mesh has " + std::to_string(nv) + " vertices");
            used[v] = 1;
        }
    OMesh om;
    std::vector<OMesh::VertexHandle> vh(nv);
    for (size_t v = 0; v < nv; ++v) {
        if (!used[v]) continue;
        const Point& p = in.vertices[v];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
            throw InvalidMesh("simplify: vertex " + std::to_string(v) + " has a non-finite coordinate");
        vh[v] = om.add_vertex(OMesh::Point(p[0], p[1], p[2]));
    }
    if (!locked.empty()) {
        om.request_vertex_status();
        for (size_t v = 0; v < nv; ++v)
            if (used[v] && locked[v]) om.status(vh[v]).set_locked(true);
    }
    for (size_t f = 0; f < in.faces.size(); ++f) {
        const Face& t = in.faces[f];
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
            throw InvalidMesh("simplify: face " + std::to_string(f) + " repeats a vertex (degenerate face)");
        const OMesh::FaceHandle fh = om.add_face(vh[t[0]], vh[t[1]], vh[t[2]]);
        if (!fh.is_valid())
            throw InvalidMesh("simplify: face " + std::to_string(f) +
                              " makes the mesh non-manifold or inconsistently oriented; simplify needs an "
                              "oriented 2-manifold (see `endocast inspect`)");
    }
    return om;
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
    OMesh om = to_openmesh(mesh, params.locked_vertices);
    om.request_face_normals();
    om.update_face_normals();
    // Status flags (deleted) must outlive the decimater, which releases its own request.
    om.request_vertex_status();
    om.request_edge_status();
    om.request_halfedge_status();
    om.request_face_status();
    {
        using Decimater = OpenMesh::Decimater::DecimaterT<OMesh>;
        Decimater dec(om);
        OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
        dec.add(quadric);
        dec.module(quadric).unset_max_err();
        OpenMesh::Decimater::ModNormalFlippingT<OMesh>::Handle flip;
        dec.add(flip);
        dec.module(flip).set_max_normal_deviation(params.max_normal_deviation_deg);
        OpenMesh::Decimater::ModAspectRatioT<OMesh>::Handle aspect;
        if (params.max_aspect_ratio > 0.0) {
            dec.add(aspect);
            dec.module(aspect).set_aspect_ratio(static_cast<float>(params.max_aspect_ratio));
            dec.module(aspect).set_binary(true);
        }
        OpenMesh::Decimater::ModHausdorffT<OMesh>::Handle hausdorff;
        if (params.max_error_mm > 0.0) {
            dec.add(hausdorff);
            dec.module(hausdorff).set_tolerance(params.max_error_mm);
        }
        if (!dec.initialize()) throw std::logic_error("simplify: OpenMesh decimater failed to initialize");
        if (r.target_faces < om.n_faces()) dec.decimate_to_faces(0, r.target_faces);
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

}  // namespace meshpost
