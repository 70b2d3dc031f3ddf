// numpy <-> library conversions (convert.h).
#include "convert.h"

#include <cmath>
#include <cstring>
#include <memory>

#include <pybind11/stl.h>

namespace endocast::python {

namespace {

Vec3 three(const py::handle& v, const char* what) {
    const auto s = py::cast<std::vector<double>>(v);
    if (s.size() != 3) throw InvalidParameter(std::string(what) + ": expected 3 numbers (x, y, z)");
    return {s[0], s[1], s[2]};
}

}  // namespace

Geometry geometry_from(const py::array& array, const py::dict& geometry) {
    if (array.ndim() != 3)
        throw InvalidParameter("array: expected a 3-D array in (z, y, x) order, got " + std::to_string(array.ndim()) +
                               "-D");
    Geometry g;
    g.dims = {int64_t(array.shape(2)), int64_t(array.shape(1)), int64_t(array.shape(0))};
    if (g.dims[0] < 2 || g.dims[1] < 2 || g.dims[2] < 2)
        throw InvalidParameter("array: expected at least 2 voxels along each axis");
    if (!geometry.contains("spacing") || geometry["spacing"].is_none())
        throw InvalidParameter("spacing: give the voxel size (sx, sy, sz) in mm");
    g.spacing = three(geometry["spacing"], "spacing");
    for (double s : g.spacing)
        if (!(s > 0) || !std::isfinite(s)) throw InvalidParameter("spacing: each voxel size must be > 0 mm");
    if (geometry.contains("origin") && !geometry["origin"].is_none()) g.origin = three(geometry["origin"], "origin");
    if (geometry.contains("direction") && !geometry["direction"].is_none()) {
        py::array_t<double, py::array::c_style | py::array::forcecast> d(geometry["direction"]);
        if (d.size() != 9) throw InvalidParameter("direction: expected 9 numbers (a 3 x 3 matrix, row-major)");
        std::memcpy(g.direction.data(), d.data(), 9 * sizeof(double));
    }
    for (double v : g.origin)
        if (!std::isfinite(v)) throw InvalidParameter("origin: expected finite numbers (mm)");
    return g;
}

bool fits_int16(const py::array& array) {
    const char k = array.dtype().kind();
    const auto size = array.dtype().itemsize();
    return (k == 'i' && size <= 2) || (k == 'u' && size == 1);
}

template <class T>
Volume<T> volume_from(const py::array& array, const Geometry& g) {
    const char k = array.dtype().kind();
    if (k != 'i' && k != 'u' && k != 'f')
        throw py::type_error("array: expected integer or floating-point voxels, got dtype " +
                             std::string(py::str(array.dtype())));
    const auto c = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(array);
    if (!c) throw py::type_error("array: cannot convert to " + std::string(sizeof(T) == 2 ? "int16" : "float32"));
    Volume<T> v(g);
    std::memcpy(v.data(), c.data(), v.size() * sizeof(T));
    return v;
}
template Volume<float> volume_from<float>(const py::array&, const Geometry&);
template Volume<int16_t> volume_from<int16_t>(const py::array&, const Geometry&);

template <class T>
py::array volume_to_python(Volume<T>&& v) {
    const Dims d = v.geometry().dims;
    auto* owner = new Volume<T>(std::move(v));
    py::capsule base(owner, [](void* p) { delete static_cast<Volume<T>*>(p); });
    const py::ssize_t s = sizeof(T);
    return py::array_t<T>({py::ssize_t(d[2]), py::ssize_t(d[1]), py::ssize_t(d[0])},
                          {s * d[0] * d[1], s * d[0], s}, owner->data(), base);
}
template py::array volume_to_python<float>(Volume<float>&&);
template py::array volume_to_python<int16_t>(Volume<int16_t>&&);
template py::array volume_to_python<uint8_t>(Volume<uint8_t>&&);

py::dict geometry_to_python(const Geometry& g) {
    py::dict out;
    out["spacing"] = py::make_tuple(g.spacing[0], g.spacing[1], g.spacing[2]);
    out["origin"] = py::make_tuple(g.origin[0], g.origin[1], g.origin[2]);
    py::array_t<double> d({3, 3});
    std::memcpy(d.mutable_data(), g.direction.data(), 9 * sizeof(double));
    out["direction"] = d;
    return out;
}

py::dict mesh_to_python(meshpost::TriangleMesh&& mesh) {
    auto* owner = new meshpost::TriangleMesh(std::move(mesh));
    py::capsule base(owner, [](void* p) { delete static_cast<meshpost::TriangleMesh*>(p); });
    py::dict out;
    out["vertices"] = py::array_t<double>({py::ssize_t(owner->vertices.size()), py::ssize_t(3)},
                                          owner->vertices.empty() ? nullptr : owner->vertices[0].data(), base);
    out["faces"] = py::array_t<uint32_t>({py::ssize_t(owner->faces.size()), py::ssize_t(3)},
                                         owner->faces.empty() ? nullptr : owner->faces[0].data(), base);
    return out;
}

meshpost::TriangleMesh mesh_from(const py::array& vertices, const py::array& faces) {
    const auto v = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(vertices);
    const auto f = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(faces);
    if (!v || v.ndim() != 2 || v.shape(1) != 3) throw InvalidParameter("mesh: vertices must be an (N, 3) array (mm)");
    if (!f || f.ndim() != 2 || f.shape(1) != 3) throw InvalidParameter("mesh: faces must be an (M, 3) array of indices");
    meshpost::TriangleMesh m;
    m.vertices.resize(size_t(v.shape(0)));
    if (!m.vertices.empty()) std::memcpy(m.vertices[0].data(), v.data(), m.vertices.size() * 3 * sizeof(double));
    m.faces.resize(size_t(f.shape(0)));
    const int64_t* fi = f.data();
    for (size_t i = 0; i < m.faces.size() * 3; ++i) {
        if (fi[i] < 0 || fi[i] >= int64_t(m.vertices.size()))
            throw InvalidParameter("mesh: face " + std::to_string(i / 3) + " names vertex " + std::to_string(fi[i]) +
                                   ", expected 0 to " + std::to_string(int64_t(m.vertices.size()) - 1));
        m.faces[i / 3][i % 3] = uint32_t(fi[i]);
    }
    return m;
}

}  // namespace endocast::python
