// The Python module `endocast._endocast` (python/endocast/__init__.py wraps it): extract() over
// endocast::extract (endocast.h), and the volume reader, the phantom and the mesh tools.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstring>
#include <string>
#include <utility>

#include "convert.h"
#include "endocast/endocast.h"
#include "endocast/phantom.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/io.h"
#include "meshpost/measure.h"
#include "method_options.h"
#include "commands.h"
#include "report.h"

namespace py = pybind11;

namespace endocast::python {
namespace {

// Stops a run at the next stage when Python has a signal pending (Ctrl-C): the binding then raises
// KeyboardInterrupt.
struct Interrupted : std::exception {};

// The library's progress to a Python callable progress(event, text), event "stage" or "info".
struct PyProgress : Progress {
    py::object callback;
    void stage(const std::string& name) override { send("stage", name); }
    void info(const std::string& line) override { send("info", line); }
    void send(const char* event, const std::string& text) {
        py::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() != 0) {
            PyErr_Clear();
            throw Interrupted();
        }
        if (!callback.is_none()) callback(event, text);
    }
};

// The method's options from Python's keywords (the CLI's names, in mm), checked as the CLI checks them.
Options options_from(const py::dict& kw) {
    cli::MethodOptions m;
    cli::InputOptions in;
    Options o;
    for (const auto& item : kw) {
        const std::string k = py::str(item.first);
        const py::handle v = item.second;
        if (v.is_none()) continue;
        if (!set_method_option(m, k, v) && !set_input_option(in, k, v) && !set_run_option(o, k, v))
            throw InvalidParameter("extract: unknown option '" + k + "'");
    }
    o.method = cli::method_params(m);
    o.read = cli::read_options(in);
    o.self_intersections = meshpost::count_self_intersections;
    return o;
}

py::dict run_extract(const Source& source, const py::dict& kw, const py::object& progress) {
    const Options o = options_from(kw);
    PyProgress p;
    p.callback = progress;
    Result r;
    try {
        py::gil_scoped_release release;
        r = extract(source, o, &p);
    } catch (const Interrupted&) {
        PyErr_SetNone(PyExc_KeyboardInterrupt);
        throw py::error_already_set();
    }
    py::dict out;
    out["ecv_ml"] = r.ecv_ml();
    out["mesh"] = mesh_to_python(std::move(r.method.mesh));
    out["mask"] = r.method.mask.empty() ? py::object(py::none()) : volume_to_python(std::move(r.method.mask));
    out["report"] = py::module_::import("json").attr("loads")(cli::extract_report(r, o).dump());
    py::list warnings;
    for (const Warning& w : r.method.warnings) {
        py::dict d;
        d["code"] = w.code;
        d["message"] = w.message;
        d["values"] = w.values;
        warnings.append(d);
    }
    out["warnings"] = warnings;
    return out;
}

py::dict extract_path(const std::vector<std::string>& paths, const py::dict& kw, const py::object& progress) {
    Source s;
    s.paths = paths;
    return run_extract(s, kw, progress);
}

py::dict extract_array(const py::array& array, const py::dict& geometry, const py::dict& kw,
                       const py::object& progress) {
    const Geometry g = geometry_from(array, geometry);
    Source s;
    s.name = "array";
    Volume<int16_t> v16;
    Volume<float> v;
    if (fits_int16(array)) {
        v16 = volume_from<int16_t>(array, g);
        s.volume16 = &v16;
    } else {
        v = volume_from<float>(array, g);
        s.volume = &v;
    }
    return run_extract(s, kw, progress);
}

py::dict read_paths(const std::vector<std::string>& paths, const py::dict& kw) {
    const Options o = options_from(kw);
    ReadResult r;
    {
        py::gil_scoped_release release;
        r = read_volume(paths, o.read);
    }
    py::dict out = geometry_to_python(r.volume.geometry());
    out["array"] = volume_to_python(std::move(r.volume));
    out["format"] = r.info.format;
    out["warnings"] = r.info.warnings;
    return out;
}

py::dict phantom(const std::string& preset, double spacing, uint64_t seed, bool noise) {
    PhantomParams p;
    p.preset = parse_phantom_preset(preset);
    if (spacing != 0) {
        if (!(spacing > 0) || !std::isfinite(spacing)) throw InvalidParameter("phantom: spacing must be > 0 mm");
        p.spacing = {spacing, spacing, spacing};
    }
    p.seed = seed;
    p.noise = noise;
    PhantomResult r;
    {
        py::gil_scoped_release release;
        r = generate_phantom(p);
    }
    py::dict out = geometry_to_python(r.geometry);
    out["array"] = volume_to_python(std::move(r.ct));
    out["true_ecv_ml"] = r.true_ecv_ml;
    out["suggested_iso"] = r.suggested_iso;
    return out;
}

}  // namespace
}  // namespace endocast::python

PYBIND11_MODULE(_endocast, m) {
    using namespace endocast::python;
    m.doc() = "endocast: the braincase cavity of a skull CT as a closed surface (see the package endocast)";
    register_errors(m);
    m.def("extract_path", &extract_path, py::arg("paths"), py::arg("options"), py::arg("progress"));
    m.def("extract_array", &extract_array, py::arg("array"), py::arg("geometry"), py::arg("options"),
          py::arg("progress"));
    m.def("read_volume", &read_paths, py::arg("paths"), py::arg("options"));
    m.def("phantom", &phantom, py::arg("preset"), py::arg("spacing"), py::arg("seed"), py::arg("noise"));
    add_mesh_functions(m);
    m.attr("__version__") = endocast::cli::kVersion;
}
