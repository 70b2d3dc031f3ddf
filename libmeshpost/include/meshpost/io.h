#pragma once
// Mesh files: STL (binary written; binary and ASCII read), PLY (binary little-endian written;
// ASCII and binary read), OBJ, OFF. Format chosen by the file extension (case-insensitive).
#include <string>

#include "meshpost/mesh.h"

namespace meshpost {

/// Writes `mesh` to `path`, format by extension (.stl binary, .ply binary, .obj, .off).
/// Written to a temporary file beside `path` and renamed on success: a failure leaves no partial
/// file and does not destroy an existing one. Throws MeshIoError (unknown extension, cannot write).
void write_mesh(const TriangleMesh& mesh, const std::string& path);

/// Reads a triangle mesh; polygons with more than 3 vertices are fan-triangulated; STL vertices are
/// welded by exact position. Throws MeshIoError naming the file and the defect (truncated data,
/// out-of-range index, non-finite coordinate, empty file, unknown extension).
TriangleMesh read_mesh(const std::string& path);

}  // namespace meshpost
