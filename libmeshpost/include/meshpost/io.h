#pragma once
// Mesh files: STL (binary written; binary and ASCII read), PLY (binary little-endian written;
// ASCII and binary read), OBJ, OFF. Format chosen by the file extension (case-insensitive).
//
// Precision: OBJ and OFF store coordinates as shortest round-trip decimal text (std::to_chars), so a
// write/read round trip is exact. Binary STL and PLY store float32: coordinates come back rounded to
// the nearest float (about 7 significant digits).
//
// Reading details:
// - STL: a file is binary when its size is exactly 84 + 50 * (declared triangle count), even if it
//   starts with "solid"; otherwise it must be ASCII ("solid" first, text only). Vertices are welded
//   by exact position (-0 equals +0), so a closed mesh written as STL reads back closed. Facet
//   normals are ignored.
// - PLY: ascii, binary_little_endian, binary_big_endian; any element and property is accepted and
//   skipped by its declared type (char..double, int8..float64); x, y, z of "vertex" may be of any
//   scalar type; "face" needs a list "vertex_indices" (or "vertex_index") with integer count and
//   index types. Element counts are checked against the file size before anything is allocated.
// - OBJ: "v" and "f" lines; "f 1/2/3 ..." and negative (relative) indices; index 0 and indices to
//   vertices not yet defined are errors; other statements (vn, vt, g, usemtl, ...) are ignored.
// - OFF: "OFF" (also COFF, NOFF, CNOFF) header, '#' comments, counts on the header line or the next;
//   extra values on vertex and face lines (colours) are ignored.
// - Polygons with more than 3 vertices are fan-triangulated (v0, vk, vk+1).
#include <string>
#include <string_view>

#include "meshpost/mesh.h"

namespace meshpost {

/// Writes `mesh` to `path`, format by extension (.stl binary, .ply binary, .obj, .off).
/// STL, PLY and OBJ declare `SPACE=LPS` in their header (the 80-byte STL header, a PLY `comment`,
/// an OBJ `#` line), the convention 3D Slicer reads; coordinates are written as given.
/// Written to a temporary file `path + ".tmp-XXXXXX"` beside `path` and renamed on success: a
/// failure leaves no partial file and does not destroy an existing one. Throws MeshIoError (unknown
/// extension, cannot write, face index out of range, non-finite coordinate, coordinate beyond the
/// float32 range for STL/PLY, counts beyond what the format can store).
void write_mesh(const TriangleMesh& mesh, const std::string& path);

/// Reads a triangle mesh; polygons with more than 3 vertices are fan-triangulated; STL vertices are
/// welded by exact position. Throws MeshIoError naming the file and the defect (missing or empty
/// file, unknown extension, truncated data, malformed number, out-of-range or zero index, face with
/// fewer than 3 vertices, non-finite coordinate, unsupported PLY format or type, counts that
/// overflow or exceed the file size). Never returns a face index >= vertices.size().
TriangleMesh read_mesh(const std::string& path);

/// Parses mesh file content already in memory, exactly as read_mesh parses a file's bytes (read_mesh
/// reads the file and calls this). `extension` picks the format: ".stl", ".ply", ".obj", ".off" (the
/// dot is optional, case-insensitive). Error messages name "<memory>.ext" instead of a file. Throws
/// MeshIoError like read_mesh (unknown extension, empty input, every content defect). Used by the
/// fuzz targets (tests/fuzz/) so that no file I/O is needed.
TriangleMesh read_mesh_from_memory(const std::string& bytes, const std::string& extension);

/// Writes `bytes` to `path` the way write_mesh writes a mesh: through a uniquely named temporary
/// file beside it (`path + ".tmp-XXXXXX"`), synced, then renamed onto it; on a failure the
/// temporary file is removed and an existing `path` is left as it was. The one atomic file writer
/// of the project (reports, CSV, PNG, HTML; volumes go through a temporary directory instead, since
/// ITK writes a header and a data file). Throws MeshIoError naming `path` and the failing step.
void write_file_atomic(const std::string& path, std::string_view bytes);

}  // namespace meshpost
