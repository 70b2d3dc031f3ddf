// The mesh functions of the Python module (convert.h): read, write, inspect, compare, simplify.
#include <pybind11/stl.h>

#include <utility>

#include "convert.h"
#include "meshpost/cgal/deviation.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/cgal/simplify_verified.h"
#include "meshpost/io.h"
#include "meshpost/measure.h"
#include "meshpost/register.h"
#include "meshpost/topology.h"

namespace endocast::python {

namespace {

py::dict stats(const meshpost::DistanceStats& s) {
    py::dict d;
    d["mean"] = s.mean;
    d["rms"] = s.rms;
    d["median"] = s.median;
    d["p95"] = s.p95;
    d["max"] = s.max;
    d["samples"] = s.samples;
    return d;
}

py::dict inspect(const py::array& vertices, const py::array& faces) {
    const meshpost::TriangleMesh mesh = mesh_from(vertices, faces);
    py::gil_scoped_release release;
    const meshpost::TopologyReport t = meshpost::analyze_topology(mesh);
    const meshpost::SelfIntersectionReport si = meshpost::find_self_intersections(mesh);
    const double volume = meshpost::signed_volume_mm3(mesh);
    const double area = meshpost::surface_area_mm2(mesh);
    py::gil_scoped_acquire gil;
    py::dict d;
    d["vertices"] = mesh.vertices.size();
    d["faces"] = mesh.faces.size();
    d["closed_manifold"] = meshpost::is_closed_manifold(t);
    d["genus"] = t.genus;
    d["components"] = t.components;
    d["boundary_edges"] = t.boundary_edges;
    d["nonmanifold_edges"] = t.nonmanifold_edges;
    d["nonmanifold_vertices"] = t.nonmanifold_vertices;
    d["inconsistent_edges"] = t.inconsistent_edges;
    d["degenerate_faces"] = t.degenerate_faces;
    d["self_intersections"] = si.intersecting_pairs;
    d["volume_ml"] = volume / 1000.0;
    d["area_mm2"] = area;
    return d;
}

py::dict compare(const py::array& va, const py::array& fa, const py::array& vb, const py::array& fb, bool align) {
    meshpost::TriangleMesh a = mesh_from(va, fa);
    const meshpost::TriangleMesh b = mesh_from(vb, fb);
    if (a.faces.empty() || b.faces.empty()) throw InvalidParameter("compare: a mesh has no faces");
    py::dict d;
    meshpost::RegisterResult reg;
    meshpost::DeviationResult dev;
    {
        py::gil_scoped_release release;
        if (align) {
            reg = meshpost::register_rigid(a, b);
            a = meshpost::transformed(a, reg.transform);
        }
        dev = meshpost::surface_deviation(a, b);
    }
    if (align) {
        d["rotation_deg"] = reg.transform.angle_deg();
        d["translation"] = reg.transform.translation;
        d["rmse"] = reg.rmse_mm;
    }
    d["a_to_b"] = stats(dev.a_to_b);
    d["b_to_a"] = stats(dev.b_to_a);
    d["hausdorff"] = dev.hausdorff_mm;
    d["sampling_error_bound_mm"] = dev.sampling_error_bound_mm;
    return d;
}

py::dict simplify(const py::array& vertices, const py::array& faces, size_t target_faces, double ratio,
                  double max_error_mm) {
    const meshpost::TriangleMesh mesh = mesh_from(vertices, faces);
    if ((target_faces == 0) == (ratio == 0)) throw InvalidParameter("simplify: give exactly one of faces and ratio");
    if (ratio != 0 && !(ratio > 0 && ratio <= 1)) throw InvalidParameter("simplify: ratio must be in (0, 1]");
    if (!(max_error_mm >= 0)) throw InvalidParameter("simplify: max_error_mm must be >= 0");
    const meshpost::TopologyReport before = meshpost::analyze_topology(mesh);
    if (!before.oriented || before.degenerate_faces > 0 || before.faces == 0)
        throw InvalidParameter("simplify needs a consistently oriented 2-manifold without degenerate faces");
    meshpost::SimplifyParams p;
    p.target_faces = target_faces;
    p.ratio = ratio;
    p.max_error_mm = max_error_mm;
    meshpost::VerifiedSimplifyResult v;
    meshpost::HausdorffResult h;
    {
        py::gil_scoped_release release;
        v = meshpost::simplify_verified(mesh, p);
        if (v.clean) h = meshpost::hausdorff_distance(v.simplified.mesh, mesh);
    }
    if (!v.clean)
        throw NoResult("simplify: could not reach " + std::to_string(v.simplified.target_faces) +
                       " faces without breaking the mesh (" + v.failure + ")");
    py::dict d = mesh_to_python(std::move(v.simplified.mesh));
    d["volume_change_pct"] = v.simplified.volume_change_pct;
    d["hausdorff_mm"] = h.hausdorff_mm;
    return d;
}

}  // namespace

void add_mesh_functions(py::module_& m) {
    m.def("read_mesh", [](const std::string& path) {
        meshpost::TriangleMesh mesh = meshpost::read_mesh(path);
        return mesh_to_python(std::move(mesh));
    }, py::arg("path"));
    m.def("write_mesh", [](const py::array& vertices, const py::array& faces, const std::string& path) {
        const meshpost::TriangleMesh mesh = mesh_from(vertices, faces);
        py::gil_scoped_release release;
        meshpost::write_mesh(mesh, path);
    }, py::arg("vertices"), py::arg("faces"), py::arg("path"));
    m.def("inspect", &inspect, py::arg("vertices"), py::arg("faces"));
    m.def("compare", &compare, py::arg("va"), py::arg("fa"), py::arg("vb"), py::arg("fb"), py::arg("align"));
    m.def("simplify", &simplify, py::arg("vertices"), py::arg("faces"), py::arg("target_faces"), py::arg("ratio"),
          py::arg("max_error_mm"));
}

}  // namespace endocast::python
