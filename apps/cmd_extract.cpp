// `endocast extract`: the whole method, from a CT scan to an endocast mesh, mask and report.
#include <omp.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <optional>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "extract_outputs.h"
#include "method_options.h"
#include "report.h"
#include "endocast/io.h"
#include "endocast/memory.h"
#include "endocast/pipeline.h"
#include "endocast/slice_source.h"
#include "meshpost/io.h"
#include "meshpost/text.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"

namespace endocast::cli {
namespace {

using meshpost::text::lower_extension;

struct ExtractOptions {
    InputOptions input;     // INPUT, --series, --slice-spacing, raw input (method_options.h)
    MethodOptions method;   // --iso ... --surface (method_options.h)
    std::string output, mask, report;
    QcOptions pictures;     // --qc, --html, --qc-panel-px (extract_outputs.h)
    // shrinking and the memory guard
    std::vector<int64_t> crop;
    int downsample = 1;
    std::optional<double> max_memory_mb;
};

void check_output_extensions(const ExtractOptions& o) {
    if (!o.output.empty()) {
        const std::string e = lower_extension(o.output);
        if (e != ".stl" && e != ".ply" && e != ".obj" && e != ".off")
            throw InvalidParameter("-o " + o.output + ": unknown mesh extension '" + e +
                                   "', expected .stl, .ply, .obj or .off");
    }
    if (!o.mask.empty()) {
        const std::string& m = o.mask;
        const std::string e = lower_extension(m);
        const bool ok = e == ".nrrd" || e == ".nii" || e == ".mha" || meshpost::text::ends_with(m, ".nii.gz");
        if (!ok)
            throw InvalidParameter("--mask " + m + ": expected a .nrrd, .nii.gz, .nii or .mha file");
    }
}

// What `extract` prints when it is not quiet: the parameters used, the ECV, bone contact, the
// mesh's checks, time and memory, and the files written.
std::string summary_text(const ExtractOptions& o, const ExtractionResult& r, double min_bone_contact,
                         const meshpost::TopologyReport& topo, size_t self_intersections, double total) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(1);
    s << "isovalue " << r.params.isovalue << (r.params.isovalue_automatic ? " (automatic, " + r.params.isovalue_rule + ")" : "")
      << ", void radius " << r.params.void_radius_mm << " mm, seeds " << to_string(r.params.seed_mode)
      << " (scale " << r.params.seed_scale << ")\n";
    s << "ECV " << std::setprecision(2) << r.ecv_ml << " mL (mask " << r.mask_volume_ml
      << " mL), area " << std::setprecision(0) << r.surface_area_mm2 << " mm^2, "
      << r.mesh.vertices.size() << " vertices, " << r.mesh.faces.size() << " faces\n";
    s << "bone contact " << std::setprecision(3) << r.bone_contact << " (share of the surface on bone"
      << std::setprecision(2);
    if (r.bone_contact < min_bone_contact) s << "; below " << min_bone_contact << ": check the openings";
    s << ")\n";
    s << "closed 2-manifold: " << (meshpost::is_closed_manifold(topo) ? "yes" : "NO") << ", genus " << topo.genus
      << ", self-intersections " << self_intersections << ", time " << std::setprecision(2)
      << total << " s, peak memory " << std::setprecision(0) << peak_memory_mb() << " MB\n";
    if (!o.output.empty()) s << "wrote " << o.output << "\n";
    if (!o.mask.empty()) s << "wrote " << o.mask << "\n";
    if (!o.report.empty()) s << "wrote " << o.report << "\n";
    if (!o.pictures.qc.empty()) s << "wrote " << o.pictures.qc << "\n";
    if (!o.pictures.html.empty()) s << "wrote " << o.pictures.html << "/index.html\n";
    return s.str();
}

void run_extract(const ExtractOptions& o, const GlobalOptions& g) {
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    check_output_extensions(o);
    check_qc_options(o.pictures);
    Progress progress(choose_progress_style(g.quiet, g.log_json),
                      extract_stage_count(!o.method.keep_openings, o.pictures));
    auto log = [&](const std::string& s) { progress.info(s); };

    // ---- read
    const std::vector<std::string>& inputs = o.input.inputs;
    ReadOptions ro = read_options(o.input);
    ExtractParams p = method_params(o.method);
    ShrinkParams shrink_params;
    if (!o.crop.empty())
        shrink_params.crop = CropBox{{o.crop[0], o.crop[1], o.crop[2]}, {o.crop[3], o.crop[4], o.crop[5]}};
    shrink_params.downsample = o.downsample;
    ro.check_header = [&](const VolumeHeader& h) {
        check_extract_memory(h, shrink_params, o.max_memory_mb, inputs.front());
    };
    auto last_report = t0;
    ro.slab_progress = [&](int64_t done, int64_t total) {  // at most every 5 s, with an ETA
        const auto now = std::chrono::steady_clock::now();
        if (seconds(last_report, now) < 5 || done >= total) return;
        last_report = now;
        const double t = seconds(t0, now);
        std::ostringstream m;
        m << std::fixed << std::setprecision(0) << "  read " << done << " of " << total << " slices, " << t
          << " s, about " << t * double(total - done) / double(done) << " s left";
        log(m.str());
    };
    progress.stage("read");
    log("reading " + inputs.front() + (inputs.size() > 1 ? " (+" + std::to_string(inputs.size() - 1) + " files)" : ""));
    ReadResult in = read_shrunk(inputs, ro, shrink_params);
    const Geometry input_geo = in.input_grid;
    const auto t_read = std::chrono::steady_clock::now();
    const Geometry& geo = in.volume.geometry();
    {
        std::ostringstream s;
        s << "  " << in.info.format << " " << in.info.voxel_type << ", " << geo.dims[0] << " x "
          << geo.dims[1] << " x " << geo.dims[2] << " voxels of " << geo.spacing[0] << " x "
          << geo.spacing[1] << " x " << geo.spacing[2] << " mm";
        if (!in.info.spacing_source.empty()) s << " (voxel size: " << in.info.spacing_source << ")";
        log(s.str());
        if (shrink_params.crop || shrink_params.downsample != 1)
            log(in.info.read_path == "slabs"
                    ? "  read in slabs of " + std::to_string(shrink_slab_slices(input_geo.dims, shrink_params)) +
                          " slices, each cropped/downsampled as it was read (the whole volume was never in memory)"
                    : "  read whole, then cropped/downsampled (this input cannot be read in slabs)");
        for (const auto& series : in.info.series_found)
            if (series.series_uid == in.info.series_uid) log("  DICOM series " + describe_dicom_series(series));
    }

    // ---- method
    p.progress = [&](const std::string& stage) { progress.stage(stage); };
    ExtractionResult r;
    try {
        r = extract_endocast(in.volume, p);
    } catch (const NoResult& e) {  // name the input: the method's messages cannot
        throw NoResult(inputs.front() + ": " + e.what());
    }
    r.warnings.insert(r.warnings.begin(), in.info.warnings.begin(), in.info.warnings.end());

    // ---- check
    progress.stage("check");
    const auto t_check0 = std::chrono::steady_clock::now();
    const meshpost::TopologyReport topo = meshpost::analyze_topology(r.mesh);
    const meshpost::SelfIntersectionReport si = meshpost::find_self_intersections(r.mesh);
    const bool clean = meshpost::is_closed_manifold(topo);
    const auto t_check1 = std::chrono::steady_clock::now();

    // ---- write (each output atomically)
    progress.stage("write");
    if (!o.output.empty()) meshpost::write_mesh(r.mesh, o.output);
    if (!o.mask.empty()) write_volume(r.mask, o.mask);
    const auto t_write = std::chrono::steady_clock::now();

    nlohmann::json j;
    j["tool"] = "endocast extract";
    j["version"] = kVersion;
    j["input"] = input_json(inputs, in.info, input_geo);
    nlohmann::json params = method_parameters_json(o.method, r);
    params["crop"] = shrink_params.crop ? nlohmann::json(o.crop) : nlohmann::json(nullptr);
    params["downsample"] = o.downsample;
    params["work_grid"] = grid_json(geo);
    params["threads"] = omp_get_max_threads();
    j["parameters"] = params;
    j.update(params);  // every parameter also at the top level (outside checks read them there)
    j.update(result_json(r, p, topo, si.intersecting_pairs));
    j["outputs"] = {{"mesh", o.output}, {"mask", o.mask}, {"qc", o.pictures.qc}, {"html", o.pictures.html}};
    const double total = seconds(t0, std::chrono::steady_clock::now());
    j["timings_s"] = {{"read", seconds(t0, t_read)},
                      {"binarize", r.timings_s.binarize},
                      {"void_fill", r.timings_s.void_fill},
                      {"distance", r.timings_s.distance},
                      {"seeds", r.timings_s.seeds},
                      {"watershed", r.timings_s.watershed},
                      {"openings", r.timings_s.openings},
                      {"polygonize", r.timings_s.polygonize},
                      {"dips", r.timings_s.dips},
                      {"bone_contact", r.timings_s.bone_contact},
                      {"check", seconds(t_check0, t_check1)},
                      {"write", seconds(t_check1, t_write)},
                      {"total", total}};
    j["peak_memory_mb"] = peak_memory_mb();
    write_qc_outputs(o.pictures, in.volume, r, j, progress);  // adds timings_s.qc / .html
    if (!o.report.empty()) meshpost::write_file_atomic(o.report, j.dump(2) + "\n");
    for (const auto& w : r.warnings) progress.warning(w);
    progress.done({{"ecv_ml", r.ecv_ml}, {"bone_contact", r.bone_contact}, {"faces", r.mesh.faces.size()},
                   {"closed_manifold", clean}});

    if (!g.quiet) std::cout << summary_text(o, r, p.min_bone_contact, topo, si.intersecting_pairs, total);
}

}  // namespace

void setup_extract(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<ExtractOptions>();
    auto* sub = app.add_subcommand(
        "extract",
        "Extract the endocast (braincase cavity) of a skull CT as a closed, oriented 2-manifold "
        "triangle mesh in the scan's world coordinates (mm, ITK/LPS space, so it overlays the CT "
        "in 3D Slicer and ITK-SNAP).");
    sub->add_option("INPUT", o->input.inputs,
                    "A .nrrd/.nhdr/.nii/.nii.gz/.mha/.mhd file, a directory holding DICOM series (searched "
                    "recursively; see --series) or its DICOMDIR file, a TIFF stack (a folder of .tif/.tiff slices, "
                    "a multi-page .tif, or a slice pattern such as 'scan/slice%04d.tif'; see --spacing), "
                    "or headerless raw file(s) / a slice pattern (with --raw-size)")
        ->required();
    sub->add_option("-o,--output", o->output, "Mesh to write: .stl (binary), .ply, .obj or .off");
    sub->add_option("--mask", o->mask, "Endocast label volume (1 = endocast) in the input's geometry (the grid after --crop/--downsample): .nrrd or .nii.gz");
    sub->add_option("--report", o->report, "JSON report: input, parameters used, ECV, area, mesh checks, timings, memory");
    add_qc_options(*sub, o->pictures);
    add_method_options(*sub, o->method);
    add_input_options(*sub, o->input);
    sub->add_option("--crop", o->crop,
                    "X0 Y0 Z0 X1 Y1 Z1: keep only voxels X0 <= x < X1 (likewise y, z; indices of "
                    "the input, end exclusive) before extraction; the mesh stays in the scan's world "
                    "coordinates")
        ->expected(6);
    sub->add_option("--downsample", o->downsample,
                    "Integer factor F: average F x F x F blocks of voxels (after --crop) before "
                    "extraction; spacing x F, about 1/F^3 of the memory and time")
        ->check(CLI::Range(1, 64))
        ->capture_default_str();
    sub->add_option("--max-memory", o->max_memory_mb,
                    "MB: stop before reading (exit 6) when the estimated peak memory exceeds this "
                    "(default: the available memory, MemAvailable or the cgroup limit)")
        ->check(CLI::PositiveNumber);
    sub->callback([o, &g] { run_extract(*o, g); });
}

}  // namespace endocast::cli
