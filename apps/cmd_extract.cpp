// `endocast extract`: the whole method, from a CT scan to an endocast mesh, mask and report.
#include <omp.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <optional>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <system_error>
#include <thread>
#include <functional>
#include <memory>
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
#include "endocast/refine.h"
#include "endocast/slice_source.h"
#include "endocast/volume.h"
#include "meshpost/io.h"
#include "meshpost/measure.h"
#include "meshpost/patches.h"
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
    int refine = 0;                 // 0: automatic (coarse-to-fine only when the whole grid does not fit)
    int64_t refine_slab = 64;       // fine planes per slab on the coarse-to-fine path
    bool check_all_faces = false;   // self-intersections among every pair of faces, not only the moved ones
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

// The coarse-to-fine path warns when the cavity's depth spans fewer of its coarse grid's voxels than
// this: the method's accuracy is measured down to ~20 voxels (a mouse at 0.14 mm; a human at 1 mm
// spans ~50; docs/accuracy.md).
constexpr double kCoarseDepthWarnVoxels = 15.0;

// A progress callback for a long loop: a line at most every 5 s, "  <verb> <done> of <total>
// <units>, <t> s, about <eta> s left", timed from the callback's creation.
std::function<void(int64_t, int64_t)> eta_lines(const std::string& verb, const std::string& units,
                                                const std::function<void(const std::string&)>& log) {
    const auto start = std::chrono::steady_clock::now();
    auto last = std::make_shared<std::chrono::steady_clock::time_point>(start);
    return [=](int64_t done, int64_t total) {
        const auto now = std::chrono::steady_clock::now();
        if (std::chrono::duration<double>(now - *last).count() < 5 || done >= total || done <= 0) return;
        *last = now;
        const double t = std::chrono::duration<double>(now - start).count();
        std::ostringstream m;
        m << std::fixed << std::setprecision(0) << "  " << verb << " " << done << " of " << total << " " << units
          << ", " << t << " s, about " << t * double(total - done) / double(done) << " s left";
        log(m.str());
    };
}

void run_extract(const ExtractOptions& o, const GlobalOptions& g) {
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    check_output_extensions(o);
    check_qc_options(o.pictures);

    // ---- read
    const std::vector<std::string>& inputs = o.input.inputs;
    ReadOptions ro = read_options(o.input);
    ExtractParams p = method_params(o.method);
    ShrinkParams shrink_params;
    if (!o.crop.empty())
        shrink_params.crop = CropBox{{o.crop[0], o.crop[1], o.crop[2]}, {o.crop[3], o.crop[4], o.crop[5]}};
    shrink_params.downsample = o.downsample;
    // The path: an input read in slabs is planned from its header before anything is read (the
    // coarse-to-fine path reads it twice: shrunk, then plane by plane); any other input is checked
    // when its header is read (whole grid only).
    std::unique_ptr<SliceSource> source = open_slice_source(inputs, ro);
    ExtractPlan plan;
    if (source) {
        plan = plan_extract(source->header(), shrink_params, o.refine, o.refine_slab, o.max_memory_mb, inputs.front());
    } else if (o.refine != 0) {
        throw InvalidParameter(inputs.front() + ": --refine needs an input read in slabs (a TIFF stack, raw data, a "
                               "NRRD with raw or gzip data, or an uncompressed MetaImage); convert it to one of these");
    } else {
        plan.reason = "the method runs on the work grid (this input is read whole: the coarse-to-fine path needs "
                      "a TIFF stack, raw data or a NRRD with raw or gzip data)";
    }
    const bool coarse_to_fine = plan.path == ExtractPath::CoarseToFine;
    if (coarse_to_fine) {
        if (p.surface != SurfaceMode::Iso)
            throw InvalidParameter("--surface " + std::string(to_string(p.surface)) +
                                   " is not available on the coarse-to-fine path (--refine, or a grid too large for "
                                   "memory): use --surface iso, or --downsample");
        shrink_params.downsample = plan.factor;
        p.keep_labels = true;
    }
    Progress progress(choose_progress_style(g.quiet, g.log_json),
                      extract_stage_count(!o.method.keep_openings, o.pictures) + (coarse_to_fine ? 1 : 0));
    auto log = [&](const std::string& s) { progress.info(s); };
    ro.check_header = [&](const VolumeHeader& h) {  // an input read in slabs was checked by plan_extract
        if (!source) check_extract_memory(h, shrink_params, o.max_memory_mb, inputs.front());
    };
    ro.slab_progress = eta_lines("read", "slices", log);
    progress.stage("read");
    log("path: " + plan.reason);
    log("reading " + inputs.front() + (inputs.size() > 1 ? " (+" + std::to_string(inputs.size() - 1) + " files)" : ""));
    // A NRRD of 8- or 16-bit integers read whole comes as int16 straight away (never as float); the
    // method's CT is int16 then (below).
    ro.int16 = !coarse_to_fine && !shrink_params.crop && shrink_params.downsample == 1 && p.surface == SurfaceMode::Iso;
    ReadResult in = read_shrunk(inputs, ro, shrink_params);
    const Geometry input_geo = in.input_grid;
    // The grid the mesh is on: the work grid, or on the coarse-to-fine path the input (cropped).
    const Geometry mesh_grid = coarse_to_fine ? shrunk_geometry(input_geo, {shrink_params.crop, 1}) : in.volume.geometry();
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
    // On the work grid, an integer-valued CT (int16 or uint16 data up to 32767: most scans) is kept
    // as int16: the same result (every stage compares the samples as floats) in half the memory
    // (volume.h). Not with --surface half-max (its field is built from a float CT) nor on the
    // coarse-to-fine path (a block-averaged grid).
    Volume<int16_t> ct16;
    if (!coarse_to_fine && p.surface == SurfaceMode::Iso) {
        ct16 = in.volume16.empty() ? exact_int16(in.volume) : std::move(in.volume16);
        if (!ct16.empty()) {
            in.volume = Volume<float>();
            in.volume.geometry() = ct16.geometry();  // the geometry stays readable; the samples are in ct16
        }
    }
    const std::string ct_storage = ct16.empty() ? "float32" : "int16";
    p.progress = [&](const std::string& stage) { progress.stage(stage); };
    // The CT and the mask after the method: for the pictures, and on the coarse-to-fine path. When
    // nothing needs the CT, the method takes it over and keeps only the bone's box of it.
    const bool pictures = !o.pictures.qc.empty() || !o.pictures.html.empty();
    const bool keep_ct = pictures || coarse_to_fine;
    p.keep_mask = keep_ct || !o.mask.empty();
    ExtractionResult r;
    try {
        if (keep_ct) r = ct16.empty() ? extract_endocast(in.volume, p) : extract_endocast(ct16, p);
        else r = ct16.empty() ? extract_endocast(std::move(in.volume), p) : extract_endocast(std::move(ct16), p);
    } catch (const NoResult& e) {  // name the input: the method's messages cannot
        throw NoResult(inputs.front() + ": " + e.what());
    }
    r.warnings.insert(r.warnings.begin(), in.info.warnings.begin(), in.info.warnings.end());

    // ---- coarse-to-fine: the band re-decided and meshed on the input's grid, plane by plane
    nlohmann::json refine_json = nullptr;
    double refine_s = 0;
    if (coarse_to_fine) {
        progress.stage("refine");
        const auto t_refine0 = std::chrono::steady_clock::now();
        const int F = plan.factor;
        const uint64_t need = estimate_refine_memory_bytes(source->header(), shrink_params.crop, F, o.refine_slab,
                                                           uint64_t(r.mesh.faces.size()) * uint64_t(F * F));
        if (plan.limit.bytes != 0 && need > plan.limit.bytes)
            throw OutOfMemory(inputs.front() + ": the coarse-to-fine path's mesh of about " +
                              std::to_string(r.mesh.faces.size() * size_t(F * F)) + " faces needs about " +
                              std::to_string(need >> 20) + " MB of memory (estimate), more than the " +
                              std::to_string(plan.limit.bytes >> 20) + " MB allowed by " + plan.limit.source +
                              "; use a larger --refine factor, or --downsample");
        const Volume<uint8_t> classes =
            refine_classes(r.mask, r.labels, in.volume, r.params.isovalue, r.mesh, r.face_on_bone_ct);
        const Volume<uint8_t>& coarse_labels = r.labels;
        const PackedMask skull = PackedMask::where(coarse_labels.geometry(), [&](size_t i) { return coarse_labels[i] == kBone; });
        r.labels = Volume<uint8_t>();
        RefineParams rp;
        rp.isovalue = r.params.isovalue;
        rp.other_value = r.other_value;
        rp.slab_planes = o.refine_slab;
        rp.clip_mesh = &r.mesh;
        rp.progress = eta_lines("refined", "planes", log);
        const CropBox box = shrink_params.crop.value_or(CropBox{{0, 0, 0}, input_geo.dims});
        const Dims& d = input_geo.dims;
        std::vector<float> plane(size_t(d[0] * d[1]));
        const PlaneReader read = [&](int64_t z, float* dst) {
            source->read(box.lo[2] + z, 1, plane.data());
            const int64_t nx = mesh_grid.dims[0];
            for (int64_t y = 0; y < mesh_grid.dims[1]; ++y)
                std::copy_n(plane.data() + size_t((box.lo[1] + y) * d[0] + box.lo[0]), nx, dst + size_t(y * nx));
        };
        RefineResult fine = refine_full_resolution(mesh_grid, read, classes, F, rp);
        const Geometry coarse_grid = in.volume.geometry();
        refine_json = {{"factor", F},
                       {"coarse_grid", grid_json(coarse_grid)},
                       {"coarse_ecv_ml", r.ecv_ml},
                       {"box", {fine.box.lo[0], fine.box.lo[1], fine.box.lo[2], fine.box.hi[0], fine.box.hi[1], fine.box.hi[2]}},
                       {"slab_planes", o.refine_slab},
                       {"slabs", fine.slabs},
                       {"band_voxels", fine.band_voxels},
                       {"band_endocast_voxels", fine.band_endocast_voxels},
                       {"changed_voxels", fine.changed_voxels},
                       {"clipped_voxels", fine.clipped_voxels},
                       {"pieces_removed", fine.pieces_removed},
                       {"estimated_memory_mb", double(plan.estimate_bytes) / double(1 << 20)}};
        if (r.max_distance_mm < kCoarseDepthWarnVoxels * coarse_grid.largest_spacing()) {
            std::ostringstream m;
            m << "the coarse-to-fine path ran the method on " << coarse_grid.spacing[0] << " x " << coarse_grid.spacing[1]
              << " x " << coarse_grid.spacing[2] << " mm voxels (the scan's x " << F << "), where the cavity's depth ("
              << r.max_distance_mm << " mm) spans fewer than " << kCoarseDepthWarnVoxels
              << " voxels: the cavity's closures and cuts are decided there "
                 "(look at the QC picture; without --refine the whole grid is used when it fits in memory)";
            r.warnings.push_back(m.str());
        }
        r.mesh = std::move(fine.mesh);
        r.topology.reset();  // the coarse mesh's
        r.mask_volume_ml = fine.region_volume_ml;
        r.ecv_ml = meshpost::signed_volume_mm3(r.mesh) / 1000.0;
        r.surface_area_mm2 = meshpost::surface_area_mm2(r.mesh);
        // Bone contact of the fine mesh, sampled as the coarse one was (the coarse CT, its probe,
        // its skull).
        BoneContactParams bcp = p.bone_contact;
        bcp.offset_mm = r.bone_contact_offset_mm;
        const BoneContact contact = bone_contact(r.mesh, in.volume, r.params.isovalue, bcp, skull);
        r.bone_contact = contact.share;
        r.face_on_bone = contact.face_on_bone;
        r.face_on_bone_ct.clear();
        r.face_leaks.clear();  // leak_share stays the coarse surface's
        r.warnings.erase(std::remove_if(r.warnings.begin(), r.warnings.end(),
                                        [](const std::string& w) { return w.rfind("bone contact ", 0) == 0; }),
                         r.warnings.end());
        if (r.bone_contact < p.min_bone_contact)
            r.warnings.push_back("bone contact " + std::to_string(r.bone_contact) +
                                 " of the refined mesh, expected >= " + std::to_string(p.min_bone_contact) +
                                 " (look at the QC picture)");
        refine_s = seconds(t_refine0, std::chrono::steady_clock::now());
    }

    // ---- check
    progress.stage("check");
    const auto t_check0 = std::chrono::steady_clock::now();
    // The mesh is written on a thread of its own (mostly the file system's time: the bytes, the
    // sync, the rename) while it is checked on all threads: its topology (the extraction's, analysed
    // beside the dips, unless there was none or the coarse-to-fine path replaced the mesh), then its
    // self-intersections. With one thread, one after the other. A failed check (an error, not
    // defects found: those are reported, and the mesh kept) removes the file written beside it, so
    // that an error leaves no output, as when the mesh was written after the check.
    std::exception_ptr check_failed, write_failed;
    double mesh_write_s = 0;
    const auto write = [&] {
        try {
            const auto t0 = std::chrono::steady_clock::now();
            meshpost::write_mesh(r.mesh, o.output);
            mesh_write_s = seconds(t0, std::chrono::steady_clock::now());
        } catch (...) {
            write_failed = std::current_exception();
        }
    };
    std::thread writer;
    if (!o.output.empty()) {
        if (omp_get_max_threads() > 1) writer = std::thread(write);
        else write();
    }
    meshpost::TopologyReport topo;
    meshpost::SelfIntersectionReport si;
    size_t faces_tested = r.mesh.faces.size();
    try {
        topo = r.topology ? *r.topology : meshpost::analyze_topology(r.mesh);
        // Self-intersections: the marching-cubes surface is embedded by construction
        // (marching_cubes.h), so only the faces flush_dips moved are tested, against every face near
        // them (the coarse-to-fine path's mesh is marching cubes alone); --check-all-faces tests
        // every pair.
        meshpost::SelfIntersectionOptions si_options;
        std::vector<uint8_t> moved_faces;
        if (!o.check_all_faces) {
            moved_faces = coarse_to_fine ? std::vector<uint8_t>(r.mesh.faces.size(), 0)
                                         : meshpost::faces_touching(r.mesh, r.dips.moved_vertices);
            si_options.subject = &moved_faces;
            faces_tested = size_t(std::count(moved_faces.begin(), moved_faces.end(), uint8_t(1)));
        }
        si = meshpost::find_self_intersections(r.mesh, si_options);
    } catch (...) {
        check_failed = std::current_exception();
    }
    if (writer.joinable()) writer.join();
    // From here on an error (a failed check, the mask, the pictures, the report) removes the mesh
    // written beside the check: an error leaves no mesh behind. Not where the write itself failed
    // (the target then holds what it held before). A failed check's error is the one reported.
    struct RemoveOnError {
        const std::string& path;
        const bool armed;
        const int errors = std::uncaught_exceptions();
        ~RemoveOnError() {
            if (armed && std::uncaught_exceptions() > errors) {
                std::error_code ignored;
                std::filesystem::remove(path, ignored);
            }
        }
    } remove_mesh_on_error{o.output, !write_failed && !o.output.empty()};
    if (check_failed) std::rethrow_exception(check_failed);
    if (write_failed) std::rethrow_exception(write_failed);
    const bool clean = meshpost::is_closed_manifold(topo);
    const auto t_check1 = std::chrono::steady_clock::now();

    // ---- write (each output atomically; the mesh was written during the check)
    progress.stage("write");
    if (!o.mask.empty()) write_volume(r.mask, o.mask);
    const auto t_write = std::chrono::steady_clock::now();

    nlohmann::json j;
    j["tool"] = "endocast extract";
    j["version"] = kVersion;
    j["input"] = input_json(inputs, in.info, input_geo);
    nlohmann::json params = method_parameters_json(o.method, r);
    params["crop"] = shrink_params.crop ? nlohmann::json(o.crop) : nlohmann::json(nullptr);
    params["downsample"] = o.downsample;
    params["work_grid"] = grid_json(mesh_grid);
    params["path"] = to_string(plan.path);
    params["refine"] = coarse_to_fine ? plan.factor : 0;
    params["threads"] = omp_get_max_threads();
    params["ct_storage"] = ct_storage;
    j["parameters"] = params;
    j.update(params);  // every parameter also at the top level (outside checks read them there)
    j.update(result_json(r, p, topo, si.intersecting_pairs));
    j["path_plan"] = {{"taken", to_string(plan.path)}, {"reason", plan.reason},
                 {"whole_grid_estimate_mb", double(plan.whole_grid_bytes) / double(1 << 20)},
                 {"estimate_mb", double(plan.estimate_bytes) / double(1 << 20)},
                 {"memory_limit_mb", double(plan.limit.bytes) / double(1 << 20)},
                 {"memory_limit_source", plan.limit.source}};
    j["refinement"] = refine_json;
    j["self_intersection_check"] = {{"faces", o.check_all_faces ? "all" : "moved after marching cubes"},
                                    {"faces_tested", faces_tested}};
    if (coarse_to_fine) j["mask_grid"] = grid_json(r.mask.geometry());  // --mask: the coarse grid
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
                      {"refine", refine_s},
                      {"check", seconds(t_check0, t_check1)},
                      {"write", mesh_write_s + seconds(t_check1, t_write)},
                      {"total", total}};
    j["peak_memory_mb"] = peak_memory_mb();
    j["huge_pages"] = endocast::huge_pages_advised();
    if (pictures) {  // adds timings_s.qc / .html
        if (ct16.empty()) write_qc_outputs(o.pictures, in.volume, r, j, progress);
        else write_qc_outputs(o.pictures, ct16, r, j, progress);
    }
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
    sub->add_option("--refine", o->refine,
                    "Integer factor F >= 2: the coarse-to-fine path for scans too large for memory (microCT): "
                    "the method runs on the scan block-averaged by F (choosing the cavity, closing its "
                    "openings), then the band around its boundary is decided again from the scan's own voxels "
                    "and meshed on the scan's grid, a slab of planes at a time (inputs read in slabs only: TIFF, "
                    "raw, NRRD raw/gzip, uncompressed MetaImage). 0: automatic, taken (with the smallest F whose grid holds <= 134 M "
                    "voxels) only when the whole grid does not fit in memory; --mask and the QC picture are then on the coarse grid")
        ->check(CLI::Range(0, 64))
        ->capture_default_str();
    sub->add_option("--refine-slab", o->refine_slab, "Planes of the scan per slab on the coarse-to-fine path")
        ->check(CLI::Range(int64_t(1), int64_t(4096)))
        ->capture_default_str();
    sub->add_flag("--check-all-faces", o->check_all_faces,
                  "Test every pair of faces for self-intersections (default: the faces moved after marching "
                  "cubes, by the flush of dips, against the faces near them; marching cubes on the Freudenthal "
                  "subdivision cannot self-intersect)");
    sub->add_option("--max-memory", o->max_memory_mb,
                    "MB: stop before reading (exit 6) when the estimated peak memory exceeds this "
                    "(default: the available memory, MemAvailable or the cgroup limit)")
        ->check(CLI::PositiveNumber);
    sub->callback([o, &g] { run_extract(*o, g); });
}

}  // namespace endocast::cli
