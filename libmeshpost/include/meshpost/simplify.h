#pragma once
// Quadric-error simplification (Garland & Heckbert 1997) on OpenMesh's halfedge mesh: halfedge
// collapses ordered by the quadric error of the surviving vertex (ties: lower halfedge index),
// each one legal only when
//  - the link condition holds (the collapse keeps a manifold a manifold, so closedness,
//    components and genus are kept), as in OpenMesh's decimater,
//  - no remaining face normal turns by more than `max_normal_deviation_deg` (no fold-over, no
//    zero-area face),
//  - optionally, the two-sided distance bound `max_error_mm` holds (below),
//  - the faces that move cross neither each other nor the faces around the collapsed edge's
//    vertices and their neighbours (a local self-intersection test in floating point; coplanar
//    pairs are not tested), and
//  - optionally, the worst aspect ratio of the affected faces stays below `max_aspect_ratio` or
//    improves.
// Vertices are kept at their input positions (a subset of the input vertices survives).
//
// Distance bound (max_error_mm = t > 0), checked for the cheapest collapse only when it is taken
// from the queue (a refused collapse waits until a neighbouring collapse changes its faces):
//  - output -> input: each face that a collapse creates is split in 4 recursively until a piece
//    is proven within t of the input (its corners lie within d of the input and every point of
//    it within R of a corner, d + R <= t; the distance is 1-Lipschitz; or its corners all lie
//    within t of one input triangle, the distance to which is convex) or its edges are <= t/2;
//    the corners of the smallest pieces must lie within t of the input (a uniform grid of the
//    input triangles and a walk over their neighbours answer this). A point of such a piece is
//    within t/(2 sqrt 3) of a corner, so the true output -> input distance is < 1.29 t.
//  - input -> output: every input vertex removed so far and the centroid of every input face is
//    carried by its nearest simplified face (as OpenMesh's ModHausdorffT) and must stay within t
//    of the faces around the collapse. Between these points the input can stray further.
// When the bound leaves more faces than the target, it is relaxed (x1.25, at most 20 times) and
// decimation goes on; SimplifyResult::max_error_used_mm is the bound in force at the end.
// Parallel: a mesh of 40,000 vertices or more is cut into slabs across its longest side (up to 8,
// equal vertex counts), each decimated on its own, in parallel (OpenMP), taking only collapses
// whose removed vertex has its two rings of neighbours inside the slab; then the same with the
// slabs shifted by half a slab (their interiors hold the first slabs' seams); then a serial pass
// over the whole mesh (the last seams, and on to the target). Each parallel pass goes in 3
// rounds, each round up to a common cost threshold (the cost below which the cheapest collapses
// of as many vertices lie as the target needs; each slab takes at most its share), so the
// collapses follow the global order by cost closely and each slab keeps the faces it needs. The
// slabs depend on the mesh alone, and a slab's collapses read and write only its own part of the
// mesh, so the result is the same whatever the thread count.
//
// This target (meshpost) is permissive and its local test does not prove the result free of
// self-intersections; use simplify_verified() (cgal/simplify_verified.h, meshpost_cgal) for the guarded
// version that checks the result with CGAL's exact predicates and retries with stricter settings.
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
    /// Two-sided distance bound, mm (see above): samples of the simplified surface within this
    /// distance of the input, and the input's vertices and face centroids within it of the
    /// simplified surface; relaxed when the target cannot be reached otherwise. 0 (the default
    /// here; `endocast simplify` uses 0.35) disables it; otherwise > 0.
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
    /// The distance bound in force at the end, mm: max_error_mm, or more when it had to be relaxed
    /// to reach the target; 0 when off.
    double max_error_used_mm = 0;
};

/// Simplifies an edge- and vertex-manifold, consistently oriented triangle mesh (closed or with
/// boundaries). Isolated vertices are dropped. Throws InvalidMesh when the faces do not form an
/// oriented manifold (OpenMesh rejects the face), when a face index is out of range, or when a
/// coordinate is not finite; throws std::invalid_argument for a target of 0 faces, a ratio outside
/// (0, 1], a normal deviation outside (0, 180] or an aspect ratio in (0, 1).
SimplifyResult simplify(const TriangleMesh& mesh, const SimplifyParams& params);

/// Vertex clustering (Rossignac & Borrel 1993), for previews of meshes too large to simplify in
/// time (a microCT endocast of tens of millions of faces in the HTML report's 3D view): the vertices
/// in each cube of side `cell_mm` (a grid from the bounding box's minimum) merge into their mean,
/// faces that lose a corner and repeated faces are dropped. O(faces); the same result for any
/// thread count; it keeps neither the topology nor the volume exactly (a preview, not a result).
/// Throws std::invalid_argument for a cell that is not finite and > 0, InvalidMesh for a face
/// index out of range.
TriangleMesh cluster_vertices(const TriangleMesh& mesh, double cell_mm);

/// The cell of cluster_vertices that leaves about `target_faces` faces: sqrt(2 x area / target),
/// the spacing of a grid whose surface triangulation has that many faces (0 for an empty mesh).
double cluster_cell_for_faces(const TriangleMesh& mesh, size_t target_faces);

}  // namespace meshpost
