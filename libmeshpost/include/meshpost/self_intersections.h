#pragma once
// Self-intersection test with CGAL (exact predicates). Implemented in the meshpost_cgal target (GPL).
#include <cstddef>
#include <utility>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

struct SelfIntersectionReport {
    size_t intersecting_pairs = 0;                       ///< face pairs that intersect
    std::vector<std::pair<size_t, size_t>> examples;     ///< up to 20 pairs (face indices)
};

/// Counts pairs of faces that intersect other than at a shared vertex or edge (CGAL
/// Polygon_mesh_processing::self_intersections on the triangle soup). Works on any mesh.
SelfIntersectionReport find_self_intersections(const TriangleMesh& mesh);

}  // namespace meshpost
