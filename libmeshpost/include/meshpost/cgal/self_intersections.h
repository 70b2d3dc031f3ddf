#pragma once
// Self-intersection test with CGAL's exact predicates. Implemented in the meshpost_cgal target (GPL).
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

struct SelfIntersectionReport {
    size_t intersecting_pairs = 0;                       ///< face pairs that intersect
    /// Up to 20 pairs (face indices, first < second): the lexicographically smallest ones, sorted,
    /// so the result is deterministic.
    std::vector<std::pair<size_t, size_t>> examples;
};

/// How candidate face pairs are found; the face-pair test (exact predicates) is the same.
enum class SelfIntersectionMethod {
    /// Uniform grid over the faces' bounding boxes (cell edge: about the mean face extent), each
    /// pair of faces whose closed boxes overlap tested once, in the cell holding the low corner of
    /// the boxes' overlap; cells in parallel (OpenMP). Falls back to CgalReference when the faces
    /// would fill more than 16 cells each on average (very uneven face sizes).
    Grid,
    /// CGAL::Polygon_mesh_processing::self_intersections on a Surface_mesh for a valid polygon
    /// mesh (manifold, consistently oriented, no repeated index; slabs of x in parallel), else
    /// CGAL's box_intersection_d on the triangle soup. Slower; kept as the reference.
    CgalReference,
};

struct SelfIntersectionOptions {
    size_t max_examples = 20;  ///< pairs kept in `examples` (the lexicographically smallest)
    SelfIntersectionMethod method = SelfIntersectionMethod::Grid;
    /// When set (one flag per face): only the pairs with at least one flagged face are tested and
    /// counted; the caller vouches for the pairs of unflagged faces. The extraction sets it to the
    /// faces that moved after marching cubes (flush_dips): the marching-cubes surface of a
    /// Freudenthal subdivision is embedded by construction (marching_cubes.h). The grid then visits
    /// only the cells the flagged faces meet. Throws InvalidMesh for another size than the faces.
    const std::vector<uint8_t>* subject = nullptr;
};

/// Counts pairs of faces that intersect other than at a shared vertex or edge. Works on any mesh.
/// Adjacency is taken from shared vertex indices (so unwelded duplicate vertices do not count as
/// shared): faces sharing an edge intersect when they are coplanar and overlap (their third
/// vertices on the same side of the edge), faces sharing one vertex when the edge opposite it in
/// either face meets the other face, other faces when they meet at all - the test of
/// CGAL::Polygon_mesh_processing::self_intersections, which uses the halfedge structure. Two faces
/// with the same three vertices count as intersecting. Degenerate (collinear) faces are skipped, as
/// CGAL does; analyze_topology reports them. The report does not depend on the method or on the
/// thread count. Throws InvalidMesh for an out-of-range face index or a non-finite coordinate.
SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh,
                                               const SelfIntersectionOptions& options);
/// As above with the default options (20 examples, grid).
SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh);
/// As above, keeping up to `max_examples` pairs (the lexicographically smallest).
SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh, size_t max_examples);
/// The number of intersecting pairs with a flagged face (`subject`, one flag per face; null: every
/// pair), by the grid method (endocast::Options::self_intersections takes it).
size_t count_self_intersections(const TriangleMesh& mesh, const std::vector<uint8_t>* subject);

}  // namespace meshpost
