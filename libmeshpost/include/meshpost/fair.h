#pragma once
// Fairing: moves a set of a mesh's vertices onto the membrane spanning the others.
#include <cstdint>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

/// Positions of the vertices for which `free_vertex` is nonzero that solve the discrete membrane
/// (uniform Laplace) equation: each free vertex at the mean of its edge neighbours, the other
/// vertices fixed; a patch of free vertices becomes the smoothest surface spanning its fixed
/// boundary (a disk across a hole's rim). Returns every vertex's position (the fixed ones as they
/// are). Deterministic. Throws InvalidMesh when free_vertex has another size than the vertices, a
/// face references a vertex beyond them, or a group of free vertices has no fixed neighbour.
std::vector<Point> membrane_positions(const TriangleMesh& mesh, const std::vector<uint8_t>& free_vertex);

}  // namespace meshpost
