#pragma once
// Conversions between numpy and the library (python/src/module.cpp), and the module's parts:
// options from keywords, the error types, the mesh functions.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "endocast/endocast.h"
#include "method_options.h"

namespace endocast::python {

namespace py = pybind11;

/// The grid of a (z, y, x) array: dims from its shape, spacing (sx, sy, sz) mm > 0 (required),
/// origin (mm, default 0) and direction (9 numbers row-major or 3x3, default identity) from
/// `geometry`. Throws InvalidParameter for a shape that is not 3-D or a bad spacing, py::type_error
/// for a dtype that is not a real number.
Geometry geometry_from(const py::array& array, const py::dict& geometry);

/// Whether the array's dtype holds only values an int16 holds (int8, uint8, int16).
bool fits_int16(const py::array& array);

/// The array's voxels in a volume on `g` (one copy, converted to T).
template <class T>
Volume<T> volume_from(const py::array& array, const Geometry& g);

/// A volume as a (z, y, x) numpy array that owns its voxels (no copy).
template <class T>
py::array volume_to_python(Volume<T>&& v);

/// {"spacing", "origin", "direction"} of a grid (x, y, z order; direction row-major 3x3).
py::dict geometry_to_python(const Geometry& g);

/// {"vertices": (N, 3) float64 mm, "faces": (M, 3) uint32}, owning the mesh's arrays.
py::dict mesh_to_python(meshpost::TriangleMesh&& mesh);

/// A mesh from (N, 3) vertices and (M, 3) faces (copied). InvalidParameter for other shapes or a
/// face naming a vertex that does not exist.
meshpost::TriangleMesh mesh_from(const py::array& vertices, const py::array& faces);

/// Sets the option `key` (the CLI's long name with '_' for '-') from `value`: true when it is one
/// of that group's. Throws InvalidParameter for a value out of range.
bool set_method_option(cli::MethodOptions& m, const std::string& key, py::handle value);
bool set_input_option(cli::InputOptions& in, const std::string& key, py::handle value);
bool set_run_option(Options& o, const std::string& key, py::handle value);

/// Translates the library's exceptions into endocast.errors' types (python/endocast/errors.py).
void register_errors(py::module_& m);

/// read_mesh, write_mesh, inspect, compare, simplify.
void add_mesh_functions(py::module_& m);

}  // namespace endocast::python
