// The extract options from Python's keywords, and the error types (convert.h).
#include <cmath>
#include <string>

#include <pybind11/stl.h>

#include "convert.h"
#include "meshpost/mesh.h"

namespace endocast::python {

namespace {

double number(py::handle v, const std::string& key, double lo, double hi) {
    const double x = py::cast<double>(v);
    if (!(x >= lo && x <= hi))
        throw InvalidParameter(key + " " + std::to_string(x) + ": expected a value in [" + std::to_string(lo) + ", " +
                               std::to_string(hi) + "]");
    return x;
}

int integer(py::handle v, const std::string& key, int lo, int hi) {
    const long x = py::cast<long>(v);
    if (x < lo || x > hi)
        throw InvalidParameter(key + " " + std::to_string(x) + ": expected an integer in [" + std::to_string(lo) + ", " +
                               std::to_string(hi) + "]");
    return int(x);
}

std::vector<double> numbers(py::handle v, const std::string& key, size_t n) {
    const auto x = py::cast<std::vector<double>>(v);
    if (x.size() != n) throw InvalidParameter(key + ": expected " + std::to_string(n) + " numbers");
    for (double d : x)
        if (!std::isfinite(d)) throw InvalidParameter(key + ": expected finite numbers");
    return x;
}

// The enum value whose to_string is `s`, among `values`.
template <class E>
E parse(const std::string& key, const std::string& s, std::initializer_list<E> values) {
    std::string known;
    for (E e : values) {
        if (to_string(e) == s) return e;
        known += (known.empty() ? "" : ", ") + std::string(to_string(e));
    }
    throw InvalidParameter(key + " '" + s + "': expected one of " + known);
}

constexpr double kInf = 1e300;

}  // namespace

bool set_method_option(cli::MethodOptions& m, const std::string& k, py::handle v) {
    if (k == "iso") m.iso = number(v, k, -kInf, kInf);
    else if (k == "void_radius") m.void_radius = number(v, k, 0, kInf);
    else if (k == "void_radius_mm") m.void_radius_mm = number(v, k, 0, kInf);
    else if (k == "thin_bone") m.thin_bone = number(v, k, 0, 1);
    else if (k == "seed_mode")
        m.seed_mode = parse(k, py::cast<std::string>(v),
                            {SeedMode::Auto, SeedMode::AutoLargest, SeedMode::Distance, SeedMode::Point});
    else if (k == "seed_scale") m.seed_scale = number(v, k, 0, 1);
    else if (k == "border_seed_scale") m.border_seed_scale = number(v, k, 0, 1);
    else if (k == "distance_threshold") m.distance_threshold = number(v, k, 0, kInf);
    else if (k == "seed_point") m.seed_point = numbers(v, k, 3);
    else if (k == "cut_planes")
        for (const auto& c : v) m.cut_planes.push_back(numbers(c, k, 6));
    else if (k == "keep_openings") m.keep_openings = py::cast<bool>(v);
    else if (k == "keep_creases_closed") m.keep_creases_closed = py::cast<bool>(v);
    else if (k == "keep_dips") m.keep_dips = py::cast<bool>(v);
    else if (k == "opening_radius_mm") m.opening_radius_mm = number(v, k, 0, kInf);
    else if (k == "surface") m.surface = parse(k, py::cast<std::string>(v), {SurfaceMode::Iso, SurfaceMode::HalfMax});
    else return false;
    return true;
}

bool set_input_option(cli::InputOptions& in, const std::string& k, py::handle v) {
    if (k == "series") in.series = py::cast<std::string>(v);
    else if (k == "series_description") in.series_description = py::cast<std::string>(v);
    else if (k == "slice_spacing") in.slice_spacing = number(v, k, 0, kInf);
    else if (k == "raw_size") {
        for (double d : numbers(v, k, 3)) in.raw_size.push_back(int64_t(d));
    } else if (k == "raw_type")
        in.raw_type = parse(k, py::cast<std::string>(v),
                            {RawType::Int8, RawType::UInt8, RawType::Int16, RawType::UInt16, RawType::Int32,
                             RawType::UInt32, RawType::Float32, RawType::Float64});
    else if (k == "raw_big_endian") in.raw_endian = py::cast<bool>(v) ? Endian::Big : Endian::Little;
    else if (k == "raw_header") in.raw_header = uint64_t(number(v, k, 0, 9e18));
    else if (k == "spacing") {
        in.spacing = numbers(v, k, 3);
        for (double s : in.spacing)
            if (!(s > 0)) throw InvalidParameter("spacing: each voxel size must be > 0 mm");
    } else if (k == "origin") in.origin = numbers(v, k, 3);
    else return false;
    return true;
}

bool set_run_option(Options& o, const std::string& k, py::handle v) {
    if (k == "crop") {
        const std::vector<double> c = numbers(v, k, 6);
        o.crop = CropBox{{int64_t(c[0]), int64_t(c[1]), int64_t(c[2])}, {int64_t(c[3]), int64_t(c[4]), int64_t(c[5])}};
    } else if (k == "downsample") o.downsample = integer(v, k, 1, 64);
    else if (k == "refine") o.refine = integer(v, k, 0, 64);
    else if (k == "refine_slab") o.refine_slab = integer(v, k, 1, 4096);
    else if (k == "max_memory_mb") o.max_memory_mb = number(v, k, 1e-9, kInf);
    else if (k == "check_all_faces") o.check_all_faces = py::cast<bool>(v);
    else return false;
    return true;
}

void register_errors(py::module_& m) {
    (void)m;
    py::register_exception_translator([](std::exception_ptr p) {
        if (!p) return;
        auto raise = [](const char* type, const char* what) {
            const py::object cls = py::module_::import("endocast.errors").attr(type);
            PyErr_SetObject(cls.ptr(), py::str(what).ptr());
        };
        try {
            std::rethrow_exception(p);
        } catch (const IoError& e) {
            raise("InputError", e.what());
        } catch (const InvalidParameter& e) {
            raise("ParameterError", e.what());
        } catch (const NoResult& e) {
            raise("NoResultError", e.what());
        } catch (const OutOfMemory& e) {
            raise("OutOfMemoryError", e.what());
        } catch (const meshpost::MeshIoError& e) {
            raise("InputError", e.what());
        } catch (const meshpost::InvalidMesh& e) {
            raise("ParameterError", e.what());
        }
    });
}

}  // namespace endocast::python
