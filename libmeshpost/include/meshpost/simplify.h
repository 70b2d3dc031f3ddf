#pragma once
// Quadric-error simplification (Garland & Heckbert 1997) with OpenMesh's decimater: halfedge
// collapses ordered by the quadric error of the surviving vertex, each one legal only when
//  - OpenMesh's link condition holds (the collapse keeps a manifold a manifold, so closedness,
//    components and genus are kept),
//  - no remaining face normal turns by more than `max_normal_deviation_deg` (no fold-over, no
//    zero-area face), and
//  - optionally, every removed input vertex stays within `max_error_mm` of the simplified surface,
//  - optionally, the worst aspect ratio of the affected faces stays below `max_aspect_ratio` or
//    improves.
// Vertices are kept at their input positions (a subset of the input vertices survives).
// Deterministic: the same input and parameters give the same output, whatever the thread count.
//
// This target (meshpost) is permissive and cannot test for self-intersections; use
// simplify_verified() (simplify_verified.h, meshpost_cgal) for the guarded version that checks the
// result with CGAL and retries with stricter settings.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

struct SimplifyParams {
    /// Target number of faces; when 0, `ratio` is used. The result can have one face more or fewer
    /// (a collapse on a closed mesh removes two faces), or more when no legal collapse remains.
    size_t target_faces = 0;
    /// Target fraction of the input faces in (0, 1]; used when target_faces == 0.
    double ratio = 0.0;
    /// Largest rotation of a face normal allowed by one collapse, degrees in (0, 180].
    double max_normal_deviation_deg = 60.0;
    /// Aspect-ratio guard: the faces around a collapse must keep (longest edge / its height) below
    /// this value, unless the collapse makes the worst of them rounder. 0 disables the guard;
    /// otherwise >= 1.
    double max_aspect_ratio = 0.0;
    /// Distance guard, mm: a collapse is legal only when every input vertex removed so far stays
    /// within this distance of the simplified faces around it (OpenMesh ModHausdorffT). 0 disables
    /// the guard; otherwise > 0.
    double max_error_mm = 0.0;
    /// Input vertices that must not be collapsed away (non-zero = locked); empty = none. Faces
    /// around a locked vertex can still change when a neighbour collapses into it.
    std::vector<uint8_t> locked_vertices;
};

struct SimplifyResult {
    TriangleMesh mesh;
    size_t faces_before = 0, faces_after = 0;
    size_t target_faces = 0;                 ///< the face count asked for
    double volume_before_mm3 = 0, volume_after_mm3 = 0;
    double volume_change_pct = 0;            ///< 100 * (after - before) / |before|; 0 when before == 0
};

/// Simplifies an edge- and vertex-manifold, consistently oriented triangle mesh (closed or with
/// boundaries). Isolated vertices are dropped. Throws InvalidMesh when the faces do not form an
/// oriented manifold (OpenMesh rejects the face), when a face index is out of range, or when a
/// coordinate is not finite; throws std::invalid_argument for a target of 0 faces, a ratio outside
/// (0, 1], a normal deviation outside (0, 180] or an aspect ratio in (0, 1).
SimplifyResult simplify(const TriangleMesh& mesh, const SimplifyParams& params);

}  // namespace meshpost
