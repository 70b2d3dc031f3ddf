#pragma once
// Self-intersection test with CGAL (exact predicates). Implemented in the meshpost_cgal target (GPL).
#include <cstddef>
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

/// Counts pairs of faces that intersect other than at a shared vertex or edge. Works on any mesh:
/// a valid polygon mesh (manifold, consistently oriented, no repeated index) goes through
/// CGAL::Polygon_mesh_processing::self_intersections on a Surface_mesh; anything else through the
/// same face-pair test applied to the triangle soup, with adjacency taken from shared vertex
/// indices (so unwelded duplicate vertices do not count as shared). Two faces with the same three
/// vertices count as intersecting in the soup test. Degenerate (collinear) faces are skipped, as
/// CGAL does; analyze_topology reports them. Sequential (deterministic).
/// Throws InvalidMesh for an out-of-range face index or a non-finite coordinate.
SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh);
/// As above, keeping up to `max_examples` pairs (the lexicographically smallest).
SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh, size_t max_examples);

}  // namespace meshpost
