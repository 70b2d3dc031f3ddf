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
#include "endocast/io.h"
#include "endocast/memory.h"
#include "endocast/pipeline.h"
#include "meshpost/io.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"

namespace endocast::cli {
namespace {

struct ExtractOptions {
    std::vector<std::string> inputs;
    std::string output, mask, report, series, series_description;
    QcOptions pictures;     // --qc, --html, --qc-panel-px (extract_outputs.h)
    std::optional<double> iso;
    double void_radius = 6.0;
    std::optional<double> void_radius_mm;
    double thin_bone = 0.5;
    std::string seed_mode = "auto";
    double seed_scale = 0.9;
    double border_seed_scale = -1;
    double distance_threshold = 0;
    double slice_spacing = 0;
    std::vector<double> seed_point;
    std::vector<std::vector<double>> cut_planes;
    bool keep_openings = false;
    bool keep_creases_closed = false;
    bool keep_dips = false;
    double opening_radius_mm = 0;
    std::string surface = "iso";
    // raw input
    std::vector<int64_t> raw_size;
    std::string raw_type = "uint16", raw_endian = "little";
    uint64_t raw_header = 0;
    std::vector<double> spacing, origin;
    // shrinking and the memory guard
    std::vector<int64_t> crop;
    int downsample = 1;
    std::optional<double> max_memory_mb;
};

nlohmann::json vec(const Vec3& v) { return {v[0], v[1], v[2]}; }

std::string lower_ext(const std::string& p) {
    const auto dot = p.find_last_of('.');
    std::string e = dot == std::string::npos ? "" : p.substr(dot);
    for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    return e;
}

void check_output_extensions(const ExtractOptions& o) {
    if (!o.output.empty()) {
        const std::string e = lower_ext(o.output);
        if (e != ".stl" && e != ".ply" && e != ".obj" && e != ".off")
            throw InvalidParameter("-o " + o.output + ": unknown mesh extension '" + e +
                                   "', expected .stl, .ply, .obj or .off");
    }
    if (!o.mask.empty()) {
        const std::string& m = o.mask;
        const bool ok = lower_ext(m) == ".nrrd" || lower_ext(m) == ".nii" || lower_ext(m) == ".mha" ||
                        (m.size() > 7 && m.compare(m.size() - 7, 7, ".nii.gz") == 0);
        if (!ok)
            throw InvalidParameter("--mask " + m + ": expected a .nrrd, .nii.gz, .nii or .mha file");
    }
}

void run_extract(const ExtractOptions& o, const GlobalOptions& g) {
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    check_output_extensions(o);
    check_qc_options(o.pictures);
    Progress progress(choose_progress_style(g.quiet, g.log_json),
                      extract_stage_count(!o.keep_openings, o.pictures));
    auto log = [&](const std::string& s) { progress.info(s); };

    // ---- read
    ReadOptions ro;
    ro.series_uid = o.series;
    ro.series_description = o.series_description;
    ro.slice_spacing_mm = o.slice_spacing;
    if (!o.raw_size.empty()) {
        RawOptions raw;
        raw.size = {o.raw_size[0], o.raw_size[1], o.raw_size[2]};
        raw.type = parse_raw_type(o.raw_type);
        raw.endian = o.raw_endian == "big" ? Endian::Big : Endian::Little;
        raw.header_bytes = o.raw_header;
        if (!o.spacing.empty()) raw.spacing = {o.spacing[0], o.spacing[1], o.spacing[2]};
        if (!o.origin.empty()) raw.origin = {o.origin[0], o.origin[1], o.origin[2]};
        ro.raw = raw;
    } else if (!o.spacing.empty() || !o.origin.empty()) {
        throw InvalidParameter("--spacing/--origin apply to raw input only (with --raw-size); "
                               "other formats carry their own geometry");
    }
    ShrinkParams shrink_params;
    if (!o.crop.empty())
        shrink_params.crop = CropBox{{o.crop[0], o.crop[1], o.crop[2]}, {o.crop[3], o.crop[4], o.crop[5]}};
    shrink_params.downsample = o.downsample;
    ro.check_header = [&](const VolumeHeader& h) {
        check_extract_memory(h, shrink_params, o.max_memory_mb, o.inputs.front());
    };
    progress.stage("read");
    log("reading " + o.inputs.front() + (o.inputs.size() > 1 ? " (+" + std::to_string(o.inputs.size() - 1) + " files)" : ""));
    ReadResult in = read_volume(o.inputs, ro);
    const Geometry input_geo = in.volume.geometry();
    in.volume = shrink(std::move(in.volume), shrink_params);
    const auto t_read = std::chrono::steady_clock::now();
    const Geometry& geo = in.volume.geometry();
    {
        std::ostringstream s;
        s << "  " << in.info.format << " " << in.info.voxel_type << ", " << geo.dims[0] << " x "
          << geo.dims[1] << " x " << geo.dims[2] << " voxels of " << geo.spacing[0] << " x "
          << geo.spacing[1] << " x " << geo.spacing[2] << " mm";
        log(s.str());
        for (const auto& series : in.info.series_found)
            if (series.series_uid == in.info.series_uid) log("  DICOM series " + describe_dicom_series(series));
    }

    // ---- method
    ExtractParams p;
    p.binarize.isovalue = o.iso;
    p.void_fill.radius_voxels = o.void_radius;
    p.void_fill.radius_mm = o.void_radius_mm;
    p.binarize.thin_bone_prominence = o.thin_bone;
    p.seeds.mode = parse_seed_mode(o.seed_mode);
    p.seeds.scale = o.seed_scale;
    p.seeds.border_scale = o.border_seed_scale;
    p.seeds.distance_threshold_mm = o.distance_threshold;
    if (!o.seed_point.empty()) {
        if (o.seed_mode == "auto") p.seeds.mode = SeedMode::Point;
        p.seeds.points_world.push_back({o.seed_point[0], o.seed_point[1], o.seed_point[2]});
    }
    if (p.seeds.mode == SeedMode::Point && p.seeds.points_world.empty())
        throw InvalidParameter("--seed-mode point needs --seed-point X Y Z (world mm)");
    if (p.seeds.mode == SeedMode::Distance && !(o.distance_threshold > 0))
        throw InvalidParameter("--seed-mode distance needs --distance-threshold MM (> 0)");
    for (const auto& c : o.cut_planes)
        p.cut_planes.push_back({{c[0], c[1], c[2]}, {c[3], c[4], c[5]}});
    p.close_openings = !o.keep_openings;
    p.creases.enabled = !o.keep_creases_closed;
    p.dips.enabled = !o.keep_dips;
    p.openings.radius_mm = o.opening_radius_mm;
    p.surface = parse_surface_mode(o.surface);
    p.progress = [&](const std::string& stage) { progress.stage(stage); };
    ExtractionResult r;
    try {
        r = extract_endocast(in.volume, p);
    } catch (const NoResult& e) {  // name the input: the method's messages cannot
        throw NoResult(o.inputs.front() + ": " + e.what());
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
    j["input"] = {{"path", o.inputs.front()},
                  {"paths", o.inputs},
                  {"format", in.info.format},
                  {"voxel_type", in.info.voxel_type},
                  {"files_read", in.info.files_read},
                  {"dims", {input_geo.dims[0], input_geo.dims[1], input_geo.dims[2]}},
                  {"spacing", vec(input_geo.spacing)},
                  {"origin", vec(input_geo.origin)},
                  {"direction", input_geo.direction}};
    if (!in.info.series_uid.empty()) j["input"]["series_uid"] = in.info.series_uid;
    if (!in.info.series_found.empty()) {
        nlohmann::json found = nlohmann::json::array();
        for (const auto& s : in.info.series_found)
            found.push_back(dicom_series_json(s, s.series_uid == in.info.series_uid));
        j["input"]["series_found"] = found;
    }
    j["input"]["gantry_tilt_deg"] = in.info.gantry_tilt_deg;
    j["input"]["resampled"] = in.info.resampled;
    if (in.info.resampled) {
        j["input"]["resample_reason"] = in.info.resample_reason;
        j["input"]["slice_runs"] = in.info.slice_runs;
    }
    nlohmann::json params;
    params["isovalue"] = r.isovalue;
    params["isovalue_automatic"] = r.isovalue_automatic;
    params["isovalue_rule"] = r.isovalue_rule;
    params["void_radius_voxels"] = o.void_radius_mm ? *o.void_radius_mm / std::min({geo.spacing[0], geo.spacing[1], geo.spacing[2]}) : o.void_radius;
    params["void_radius_mm"] = r.void_radius_mm;
    params["thin_bone_prominence"] = o.thin_bone;
    params["seed_mode"] = to_string(r.seed_mode);
    params["seed_scale"] = r.seed_scale;
    params["border_seed_scale"] = r.border_seed_scale;
    if (r.seed_mode == SeedMode::Distance) params["distance_threshold_mm"] = o.distance_threshold;
    nlohmann::json pts = nlohmann::json::array();
    for (const auto& s : r.endocast_seeds_world) pts.push_back(vec(s));
    params["seed_points_mm"] = pts;
    params["seed_radii_mm"] = r.endocast_seed_radii_mm;
    nlohmann::json cuts = nlohmann::json::array();
    for (const auto& c : o.cut_planes) cuts.push_back({{"point_mm", {c[0], c[1], c[2]}}, {"normal", {c[3], c[4], c[5]}}});
    params["cut_planes"] = cuts;
    params["crop"] = shrink_params.crop ? nlohmann::json(o.crop) : nlohmann::json(nullptr);
    params["downsample"] = o.downsample;
    params["work_grid"] = {{"dims", {geo.dims[0], geo.dims[1], geo.dims[2]}}, {"spacing", vec(geo.spacing)}, {"origin", vec(geo.origin)}};
    params["watershed_connectivity"] = 6;
    params["surface"] = to_string(r.surface);
    params["threads"] = omp_get_max_threads();
    j["parameters"] = params;
    for (auto it = params.begin(); it != params.end(); ++it) j[it.key()] = it.value();
    j["bone_contact"] = r.bone_contact;
    j["ecv_ml"] = r.ecv_ml;
    j["mask_volume_ml"] = r.mask_volume_ml;
    j["surface_area_mm2"] = r.surface_area_mm2;
    j["vertices"] = r.mesh.vertices.size();
    j["faces"] = r.mesh.faces.size();
    j["closed_manifold"] = clean;
    j["self_intersections"] = si.intersecting_pairs;
    j["genus"] = topo.genus;
    j["components"] = topo.components;
    j["degenerate_faces"] = topo.degenerate_faces;
    j["max_distance_mm"] = r.max_distance_mm;
    j["enclosure"] = r.enclosure;
    j["thin_bone_voxels"] = r.thin_bone_voxels;
    j["air_excluded_voxels"] = r.air_excluded_voxels;
    j["border_contact_mm2"] = r.border_contact_mm2;
    j["cut_voxels"] = r.cut_voxels;
    nlohmann::json cands = nlohmann::json::array();
    for (const auto& c : r.candidates)
        cands.push_back({{"centre_mm", vec(c.centre_world)}, {"depth_mm", c.depth_mm},
                         {"volume_ml", c.volume_ml}, {"enclosure", c.enclosure}, {"score", c.score},
                         {"merged_into", c.merged_into}, {"chosen", c.chosen}});
    j["cavity_candidates"] = cands;
    nlohmann::json ops = nlohmann::json::array();
    for (const auto& op : r.openings.openings)
        ops.push_back({{"centre_mm", vec(op.centre_world)}, {"normal", vec(op.normal)},
                       {"radius_mm", op.radius_mm}, {"area_mm2", op.area_mm2}, {"voxels_removed", op.voxels_removed},
                       {"collar_voxels", op.collar_voxels}, {"plane_fitted", op.plane_fitted},
                       {"cut", op.cut}});
    j["openings"] = {{"closed", p.close_openings}, {"ball_radius_mm", r.openings.radius_mm},
                     {"core_voxels", r.openings.core_voxels}, {"corner_voxels", r.openings.corner_voxels},
                     {"small_openings_voxels", r.openings.small_openings_voxels},
                     {"list", ops}};
    j["creases"] = {{"restored", p.creases.enabled && p.close_openings}, {"pieces", r.creases.pieces},
                    {"voxels", r.creases.voxels}, {"pieces_kept_closed", r.creases.pieces_kept_closed},
                    {"pieces_too_deep", r.creases.pieces_too_deep}, {"deep_pockets", r.creases.deep_pockets}};
    j["dips"] = {{"flushed", r.dips.flushed}, {"patches", r.dips.patches},
                 {"vertices_moved", r.dips.vertices_moved}, {"max_move_mm", r.dips.max_depth_mm},
                 {"volume_removed_ml", r.dips.volume_removed_mm3 / 1000.0}};
    j["handles"] = {{"euler_before", r.handles.euler_before}, {"euler_after", r.handles.euler_after},
                    {"voxels_closed", r.handles.voxels_closed}, {"voxels_matched", r.handles.voxels_matched}};
    j["warnings"] = r.warnings;
    j["void_filled_voxels"] = r.void_filled_voxels;
    j["bone_fragments_removed_voxels"] = r.bone_fragments_removed_voxels;
    j["other_value"] = r.other_value;
    if (r.surface == SurfaceMode::HalfMax) j["half_max"] = half_max_json(r.half_max);
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

    if (!g.quiet) {
        std::ostringstream s;
        s << std::fixed << std::setprecision(1);
        s << "isovalue " << r.isovalue << (r.isovalue_automatic ? " (automatic, " + r.isovalue_rule + ")" : "")
          << ", void radius " << r.void_radius_mm << " mm, seeds " << to_string(r.seed_mode)
          << " (scale " << r.seed_scale << ")\n";
        s << "ECV " << std::setprecision(2) << r.ecv_ml << " mL (mask " << r.mask_volume_ml
          << " mL), area " << std::setprecision(0) << r.surface_area_mm2 << " mm^2, "
          << r.mesh.vertices.size() << " vertices, " << r.mesh.faces.size() << " faces\n";
        s << "bone contact " << std::setprecision(3) << r.bone_contact << " (share of the surface on bone"
          << std::setprecision(2);
        if (r.bone_contact < p.min_bone_contact) s << "; below " << p.min_bone_contact << ": check the openings";
        s << ")\n";
        s << "closed 2-manifold: " << (clean ? "yes" : "NO") << ", genus " << topo.genus
          << ", self-intersections " << si.intersecting_pairs << ", time " << std::setprecision(2)
          << total << " s, peak memory " << std::setprecision(0) << peak_memory_mb() << " MB\n";
        if (!o.output.empty()) s << "wrote " << o.output << "\n";
        if (!o.mask.empty()) s << "wrote " << o.mask << "\n";
        if (!o.report.empty()) s << "wrote " << o.report << "\n";
        if (!o.pictures.qc.empty()) s << "wrote " << o.pictures.qc << "\n";
        if (!o.pictures.html.empty()) s << "wrote " << o.pictures.html << "/index.html\n";
        std::cout << s.str();
    }
}

}  // namespace

void setup_extract(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<ExtractOptions>();
    auto* sub = app.add_subcommand(
        "extract",
        "Extract the endocast (braincase cavity) of a skull CT as a closed, oriented 2-manifold "
        "triangle mesh in the scan's world coordinates (mm, ITK/LPS space, so it overlays the CT "
        "in 3D Slicer and ITK-SNAP).");
    sub->add_option("INPUT", o->inputs,
                    "A .nrrd/.nhdr/.nii/.nii.gz/.mha/.mhd file, a directory holding DICOM series (searched "
                    "recursively; see --series) or its DICOMDIR file, "
                    "or headerless raw file(s) / a slice pattern (with --raw-size)")
        ->required();
    sub->add_option("-o,--output", o->output, "Mesh to write: .stl (binary), .ply, .obj or .off");
    sub->add_option("--mask", o->mask, "Endocast label volume (1 = endocast) in the input's geometry (the grid after --crop/--downsample): .nrrd or .nii.gz");
    sub->add_option("--report", o->report, "JSON report: input, parameters used, ECV, area, mesh checks, timings, memory");
    add_qc_options(*sub, o->pictures);
    sub->add_option("--iso", o->iso, "Bone isovalue T in the scan's units (HU for DICOM). Default: automatic (Otsu between soft tissue and bone, reported)");
    sub->add_option("--void-radius", o->void_radius, "Ball radius for filling voids in bone, in voxels of the smallest spacing")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    sub->add_option("--void-radius-mm", o->void_radius_mm, "Ball radius for filling voids in mm (overrides --void-radius)")
        ->check(CLI::NonNegativeNumber);
    sub->add_option("--thin-bone", o->thin_bone,
                    "Recover thin bone (orbital roofs, cribriform plate) blurred below the isovalue: a "
                    "voxel below T is bone when it is a ridge of the CT along an axis rising at least "
                    "this fraction of the way from its sides up to T; 0 = off (the paper's binarization). "
                    "Stops leaks through thin plates (the orbital roofs); may also close the thin "
                    "walls of a sinus, whose air is then left out of a tissue-filled braincase "
                    "(docs/accuracy.md)")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    sub->add_option("--seed-mode", o->seed_mode,
                    "auto: border = other; candidate cavities at the deepest distance maxima, "
                    "the one best enclosed by bone (score enclosure^4 x volume, reported) = endocast; "
                    "auto-largest: the paper's rule (deepest empty voxel = endocast); "
                    "distance: components of the distance field above --distance-threshold; "
                    "point: a ball around --seed-point")
        ->check(CLI::IsMember({"auto", "auto-largest", "distance", "point"}))
        ->capture_default_str();
    sub->add_option("--seed-scale", o->seed_scale, "s in (0,1): seed balls have radius s * distance to bone")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    sub->add_option("--border-seed-scale", o->border_seed_scale,
                    "Scale of the 'other' seed balls at the volume border. Default: --seed-scale, and "
                    "with --seed-mode auto, 0 when the chosen cavity then faces the border over more "
                    "than 10% of its boundary, or more than 1% of it faces the border balls (a scan "
                    "cropped through the braincase; warned and reported). 0 seeds the border voxels alone, so the border seeds do not eat "
                    "into a cavity cut by the border")
        ->check(CLI::Range(0.0, 1.0));
    sub->add_option("--distance-threshold", o->distance_threshold, "mm, for --seed-mode distance (the paper's alternative for small braincases)");
    sub->add_option("--seed-point", o->seed_point, "X Y Z (or X,Y,Z, as 3D Slicer passes it) in world mm: a point inside the braincase (implies --seed-mode point)")
        ->expected(3)
        ->delimiter(',');
    sub->add_option("--cut-plane", o->cut_planes,
                    "PX PY PZ NX NY NZ (world mm): close an opening by a plane; every empty voxel on "
                    "the side the normal points to is outside the endocast (repeatable)")
        ->expected(6)
        ->allow_extra_args(false);
    sub->add_flag("--no-close-openings", o->keep_openings,
                  "Keep the boundary where the watershed floods meet (the paper's behaviour) "
                  "instead of closing each opening (foramen magnum, canals) by a plane fitted to its "
                  "rim on the inner skull surface");
    sub->add_flag("--no-restore-creases", o->keep_creases_closed,
                  "Leave to bone the creases of the cavity that the void fill closes (the olfactory "
                  "groove, the sella, the angles of the skull base's floors): by default each piece "
                  "the void fill added that touches only the endocast (not a foramen: those a "
                  "ball of half, then a quarter of, the void-fill radius closes stay closed) and lies on "
                  "average at most twice that radius below its mouth is given back to it");
    sub->add_flag("--no-flush-dips", o->keep_dips,
                  "Leave each closing surface where the void fill's ball dips into the hole it "
                  "plugged (up to 2.7 mm beyond the inner table for a 10 mm hole with 6 voxels of 1 mm) "
                  "instead of moving it onto the membrane spanning the hole's rim");
    sub->add_option("--opening-radius-mm", o->opening_radius_mm,
                    "Ball radius (mm) that defines the core of the cavity when closing openings "
                    "(default: 0.3 x the cavity's depth)");
    sub->add_option("--surface", o->surface, kSurfaceHelp)
        ->check(CLI::IsMember({"iso", "half-max"}))
        ->capture_default_str();
    sub->add_option("--series", o->series, kSeriesHelp);
    sub->add_option("--series-description", o->series_description, kSeriesDescriptionHelp);
    sub->add_option("--slice-spacing", o->slice_spacing,
                    "DICOM: slice spacing in mm of the regular grid that a series with gantry tilt or uneven slice "
                    "spacing is resampled onto (default 0: the smallest step of a run of evenly spaced slices); "
                    "> 0 resamples any DICOM series")
        ->check(CLI::NonNegativeNumber);
    sub->add_option("--raw-size", o->raw_size, "Raw input: X Y Z voxels of the whole volume")->expected(3);
    sub->add_option("--raw-type", o->raw_type, "Raw input voxel type")
        ->check(CLI::IsMember({"int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"}))
        ->capture_default_str();
    sub->add_option("--raw-endian", o->raw_endian, "Raw input byte order")
        ->check(CLI::IsMember({"little", "big"}))
        ->capture_default_str();
    sub->add_option("--raw-header", o->raw_header, "Raw input: bytes to skip at the start of each file")
        ->capture_default_str();
    sub->add_option("--spacing", o->spacing, "Raw input: voxel size SX SY SZ in mm (default 1 1 1)")->expected(3);
    sub->add_option("--origin", o->origin, "Raw input: world position of voxel (0,0,0) in mm (default 0 0 0)")->expected(3);
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
