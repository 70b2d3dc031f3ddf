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

/// Positions of the free vertices that solve the discrete thin-plate (uniform bi-Laplace)
/// equation, L(L x) = 0 at each free vertex, the others fixed: the patch continues the slope of
/// the fixed surface around it (C1 across its rim, where the membrane is only C0), so a hole in a
/// curved wall is closed by a surface that keeps the wall's curvature. Every neighbour of a free
/// vertex must have all its faces in the mesh (give it a ring of fixed faces around the patch).
/// Deterministic. Throws InvalidMesh as membrane_positions does.
std::vector<Point> thin_plate_positions(const TriangleMesh& mesh, const std::vector<uint8_t>& free_vertex);

}  // namespace meshpost
