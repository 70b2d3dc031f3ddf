#pragma once
// Patches: the faces across each face's edges, and the edge-connected patches of a set of faces.
#include <array>
#include <cstdint>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

/// Marks "no face across this edge" in face_neighbours' result (a boundary edge).
inline constexpr uint32_t kNoFace = UINT32_MAX;

/// Each vertex's faces, in face order: those of vertex v are faces[start[v] .. start[v + 1]).
struct VertexFaces {
    std::vector<uint32_t> start;  ///< vertices + 1 entries
    std::vector<uint32_t> faces;  ///< a face once per corner
};

/// The faces around each vertex (a counting sort on all threads; face order for any thread count).
/// Throws InvalidMesh when a face references a vertex beyond the mesh (`fn` names the caller).
VertexFaces vertex_faces(const TriangleMesh& mesh, const char* fn = "vertex_faces");

/// Per face, the face across each of its edges (edge a: from corner a to corner a+1), or kNoFace
/// on the mesh's boundary. For an edge of more than two faces (not a 2-manifold), the other face
/// of lowest index. Linear in the faces (the faces around each vertex; no sort); deterministic.
/// Throws InvalidMesh when a face references a vertex beyond the mesh.
std::vector<std::array<uint32_t, 3>> face_neighbours(const TriangleMesh& mesh);

/// The edge-connected patches of the faces with member[f] != 0, through the neighbours `nb`
/// (face_neighbours): numbered in order of their lowest face, each patch's faces in breadth-first
/// order from it. Throws InvalidMesh when member has another size than nb.
std::vector<std::vector<uint32_t>> face_patches(const std::vector<std::array<uint32_t, 3>>& nb,
                                                const std::vector<uint8_t>& member);

/// Per face, 1 when one of its vertices is in `vertices` (in any order, repeats allowed), else 0;
/// a face with a vertex beyond the mesh counts as touching (on all threads). Throws InvalidMesh
/// when a listed vertex lies beyond the mesh.
std::vector<uint8_t> faces_touching(const TriangleMesh& mesh, const std::vector<uint32_t>& vertices);

}  // namespace meshpost
