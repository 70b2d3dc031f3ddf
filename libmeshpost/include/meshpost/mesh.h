#pragma once
// TriangleMesh: an indexed triangle mesh in world millimetres.
// Faces are counter-clockwise seen from outside (normals point outward) for closed meshes.
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace meshpost {

using Point = std::array<double, 3>;
using Face = std::array<uint32_t, 3>;

struct TriangleMesh {
    std::vector<Point> vertices;  ///< world coordinates, mm
    std::vector<Face> faces;      ///< vertex indices, CCW seen from outside

    size_t vertex_count() const { return vertices.size(); }
    size_t face_count() const { return faces.size(); }
};

/// The first face (lowest index) that references a vertex index >= the vertex count, or
/// faces.size() when every index is valid; checked on all threads.
size_t first_face_with_bad_index(const TriangleMesh& m);

/// Base of all meshpost errors.
class MeshError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};
/// A mesh file could not be read or written, or its content is malformed.
class MeshIoError : public MeshError {
public:
    using MeshError::MeshError;
};
/// The mesh violates a precondition of an algorithm (e.g. not closed).
class InvalidMesh : public MeshError {
public:
    using MeshError::MeshError;
};

}  // namespace meshpost
