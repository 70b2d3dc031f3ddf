// The report of a run of the method, built in one place (report.h).
#include "report.h"

#include <omp.h>

#include <algorithm>
#include <cmath>

#include "commands.h"
#include "endocast/volume.h"

namespace endocast::cli {
namespace {

nlohmann::json vec(const Vec3& v) { return {v[0], v[1], v[2]}; }

nlohmann::json refinement_json(const Result& r, const Options& o) {
    if (!r.refinement) return nullptr;
    const Refinement& f = *r.refinement;
    return {{"factor", f.factor},
            {"coarse_grid", grid_json(f.coarse_grid)},
            {"coarse_ecv_ml", f.coarse_ecv_ml},
            {"box", {f.box.lo[0], f.box.lo[1], f.box.lo[2], f.box.hi[0], f.box.hi[1], f.box.hi[2]}},
            {"slab_planes", o.refine_slab},
            {"slabs", f.slabs},
            {"band_voxels", f.band_voxels},
            {"band_endocast_voxels", f.band_endocast_voxels},
            {"changed_voxels", f.changed_voxels},
            {"clipped_voxels", f.clipped_voxels},
            {"pieces_removed", f.pieces_removed},
            {"estimated_memory_mb", double(r.plan.estimate_bytes) / double(1 << 20)}};
}

}  // namespace

nlohmann::json dicom_series_json(const DicomSeriesInfo& s, bool chosen) {
    return {{"series_uid", s.series_uid},
            {"description", s.description},
            {"modality", s.modality},
            {"sop_class_uid", s.sop_class_uid},
            {"sop_class", s.sop_class},
            {"image_type", s.image_type},
            {"kernel", s.kernel},
            {"series_number", s.series_number ? nlohmann::json(*s.series_number) : nlohmann::json(nullptr)},
            {"slices", s.files.size()},
            {"rows", s.rows},
            {"columns", s.columns},
            {"pixel_spacing_mm", {s.pixel_spacing_mm[0], s.pixel_spacing_mm[1]}},
            {"slice_thickness_mm", s.slice_thickness_mm},
            {"slice_step_mm", s.slice_step_mm},
            {"folders", s.folders},
            {"is_volume", s.is_volume},
            {"reason", s.reason},
            {"chosen", chosen}};
}

nlohmann::json method_parameters_json(const ExtractParams& p, const ExtractionResult& r) {
    nlohmann::json params;
    params["isovalue"] = r.params.isovalue;
    params["isovalue_automatic"] = r.params.isovalue_automatic;
    params["isovalue_rule"] = r.params.isovalue_rule;
    params["isovalue_margin"] = std::isfinite(r.params.isovalue_margin) ? nlohmann::json(r.params.isovalue_margin)
                                                                        : nlohmann::json(nullptr);
    params["void_radius_voxels"] = r.params.void_radius_voxels;
    params["void_radius_mm"] = r.params.void_radius_mm;
    params["thin_bone_prominence"] = r.params.thin_bone_prominence;
    params["seed_mode"] = to_string(r.params.seed_mode);
    params["seed_scale"] = r.params.seed_scale;
    params["border_seed_scale"] = r.border_seed_scale;
    if (r.params.seed_mode == SeedMode::Distance) params["distance_threshold_mm"] = p.seeds.distance_threshold_mm;
    nlohmann::json pts = nlohmann::json::array();
    for (const auto& s : r.endocast_seeds_world) pts.push_back(vec(s));
    params["seed_points_mm"] = pts;
    params["seed_radii_mm"] = r.endocast_seed_radii_mm;
    nlohmann::json cuts = nlohmann::json::array();
    for (const auto& c : p.cut_planes) cuts.push_back({{"point_mm", vec(c.point)}, {"normal", vec(c.normal)}});
    params["cut_planes"] = cuts;
    params["watershed_connectivity"] = 6;
    params["watershed_resumed"] = r.watershed_resumed;
    params["surface"] = to_string(r.params.surface);
    // The box of the work grid's voxels the stages after binarize ran on (null: all of it).
    params["work_box"] = r.work_box ? nlohmann::json{{"lo", {r.work_box->lo[0], r.work_box->lo[1], r.work_box->lo[2]}},
                                                     {"hi", {r.work_box->hi[0], r.work_box->hi[1], r.work_box->hi[2]}}}
                                    : nlohmann::json(nullptr);
    return params;
}

nlohmann::json input_json(const std::vector<std::string>& paths, const InputInfo& info, const Geometry& g) {
    nlohmann::json j = {{"path", paths.front()},
                        {"paths", paths},
                        {"format", info.format},
                        {"voxel_type", info.voxel_type},
                        {"files_read", info.files_read},
                        {"dims", {g.dims[0], g.dims[1], g.dims[2]}},
                        {"spacing", vec(g.spacing)},
                        {"origin", vec(g.origin)},
                        {"direction", g.direction},
                        {"read_path", info.read_path}};
    if (!info.series_uid.empty()) j["series_uid"] = info.series_uid;
    if (!info.spacing_source.empty()) j["spacing_source"] = info.spacing_source;
    if (!info.series_found.empty()) {
        nlohmann::json found = nlohmann::json::array();
        for (const auto& s : info.series_found) found.push_back(dicom_series_json(s, s.series_uid == info.series_uid));
        j["series_found"] = found;
    }
    j["gantry_tilt_deg"] = info.gantry_tilt_deg;
    j["resampled"] = info.resampled;
    if (info.resampled) {
        j["resample_reason"] = info.resample_reason;
        j["slice_runs"] = info.slice_runs;
    }
    return j;
}

nlohmann::json grid_json(const Geometry& g) {
    return {{"dims", {g.dims[0], g.dims[1], g.dims[2]}}, {"spacing", vec(g.spacing)}, {"origin", vec(g.origin)}};
}

nlohmann::json result_json(const ExtractionResult& r, const ExtractParams& p, const meshpost::TopologyReport& topo,
                           size_t self_intersections) {
    nlohmann::json j;
    j["bone_contact"] = r.bone_contact;
    j["bone_contact_offset_mm"] = r.bone_contact_offset_mm;
    nlohmann::json lengths, rules;
    for (const DerivedLength& l : derived_lengths(p, r)) {
        lengths[l.name] = l.mm;
        rules[l.name] = l.rule;
    }
    j["lengths_mm"] = lengths;
    j["length_rules"] = rules;
    j["leak_share"] = r.leak_share;
    j["ecv_ml"] = r.ecv_ml;
    j["mask_volume_ml"] = r.mask_volume_ml;
    j["surface_area_mm2"] = r.surface_area_mm2;
    j["vertices"] = r.mesh.vertices.size();
    j["faces"] = r.mesh.faces.size();
    j["closed_manifold"] = meshpost::is_closed_manifold(topo);
    j["self_intersections"] = self_intersections;
    j["genus"] = topo.genus;
    j["components"] = topo.components;
    j["degenerate_faces"] = topo.degenerate_faces;
    j["max_distance_mm"] = r.max_distance_mm;
    j["enclosure"] = r.enclosure;
    j["thin_bone_voxels"] = r.thin_bone_voxels;
    j["thin_bone_tips_returned"] = r.thin_bone_tips_returned;
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
                       {"cut", op.cut}, {"wide", op.wide}});
    j["openings"] = {{"closed", p.close_openings}, {"ball_radius_mm", r.openings.radius_mm},
                     {"wide_ball_radius_mm", r.openings.wide_radius_mm},
                     {"core_voxels", r.openings.core_voxels}, {"corner_voxels", r.openings.corner_voxels},
                     {"small_openings_voxels", r.openings.small_openings_voxels},
                     {"list", ops}};
    j["creases"] = {{"restored", p.creases.enabled && p.close_openings}, {"pieces", r.creases.pieces},
                    {"voxels", r.creases.voxels}, {"pieces_kept_closed", r.creases.pieces_kept_closed},
                    {"pieces_too_deep", r.creases.pieces_too_deep}, {"deep_pockets", r.creases.deep_pockets},
                    {"sheet_voxels", r.creases.sheet_voxels}, {"plugs_split", r.creases.plugs_split},
                    {"plug_voxels", r.creases.plug_voxels}};
    j["dips"] = {{"flushed", r.dips.flushed}, {"patches", r.dips.patches},
                 {"vertices_moved", r.dips.vertices_moved}, {"max_move_mm", r.dips.max_depth_mm},
                 {"volume_removed_ml", r.dips.volume_removed_mm3 / 1000.0}, {"crossing", r.dips.crossing}, {"sunk", r.dips.sunk},
                 {"faired", r.dips.faired}};
    j["handles"] = {{"euler_before", r.handles.euler_before}, {"euler_after", r.handles.euler_after},
                    {"voxels_closed", r.handles.voxels_closed}, {"voxels_matched", r.handles.voxels_matched}};
    nlohmann::json messages = nlohmann::json::array(), details = nlohmann::json::array();
    for (const Warning& w : r.warnings) {
        messages.push_back(w.message);
        details.push_back({{"code", w.code}, {"message", w.message}, {"values", w.values}});
    }
    j["warnings"] = messages;
    j["warning_details"] = details;
    j["void_filled_voxels"] = r.void_filled_voxels;
    j["bone_fragments_removed_voxels"] = r.bone_fragments_removed_voxels;
    j["other_value"] = r.other_value;
    if (r.params.surface == SurfaceMode::HalfMax) j["half_max"] = half_max_json(r.half_max);
    return j;
}

nlohmann::json extract_report(const Result& r, const Options& o) {
    const ExtractionResult& m = r.method;
    const bool coarse_to_fine = r.plan.path == ExtractPath::CoarseToFine;
    nlohmann::json j;
    j["tool"] = "endocast extract";
    j["version"] = kVersion;
    j["input"] = input_json(r.paths, r.input, r.input_grid);
    nlohmann::json params = method_parameters_json(o.method, m);
    params["crop"] = o.crop ? nlohmann::json{o.crop->lo[0], o.crop->lo[1], o.crop->lo[2],
                                             o.crop->hi[0], o.crop->hi[1], o.crop->hi[2]}
                            : nlohmann::json(nullptr);
    params["downsample"] = o.downsample;
    params["work_grid"] = grid_json(r.mesh_grid);
    params["path"] = to_string(r.plan.path);
    params["refine"] = coarse_to_fine ? r.plan.factor : 0;
    params["threads"] = omp_get_max_threads();
    params["ct_storage"] = r.ct_storage;
    j["parameters"] = params;
    j.update(params);  // every parameter also at the top level (outside checks read them there)
    j.update(result_json(m, o.method, r.topology, size_t(std::max<int64_t>(r.self_intersections, 0))));
    if (r.self_intersections < 0) j["self_intersections"] = nullptr;
    const double mb = double(1 << 20);
    j["path_plan"] = {{"taken", to_string(r.plan.path)}, {"reason", r.plan.reason},
                      {"whole_grid_estimate_mb", double(r.plan.whole_grid_bytes) / mb},
                      {"estimate_mb", double(r.plan.estimate_bytes) / mb},
                      {"memory_limit_mb", double(r.plan.limit.bytes) / mb},
                      {"memory_limit_source", r.plan.limit.source}};
    j["refinement"] = refinement_json(r, o);
    j["self_intersection_check"] = {{"faces", o.check_all_faces ? "all" : "moved after marching cubes"},
                                    {"faces_tested", r.faces_tested}};
    if (coarse_to_fine) j["mask_grid"] = grid_json(m.mask.geometry());
    const StageTimings& t = m.timings_s;
    j["timings_s"] = {{"read", r.read_s}, {"binarize", t.binarize}, {"void_fill", t.void_fill},
                      {"distance", t.distance}, {"seeds", t.seeds}, {"watershed", t.watershed},
                      {"openings", t.openings}, {"polygonize", t.polygonize}, {"dips", t.dips},
                      {"bone_contact", t.bone_contact}, {"refine", r.refine_s}, {"check", r.check_s}};
    j["peak_memory_mb"] = peak_memory_mb();
    j["huge_pages"] = huge_pages_advised();
    return j;
}

nlohmann::json half_max_json(const HalfMaxInfo& h) {
    return {{"cavity_level", h.cavity_level},       {"threshold_min", h.threshold_min},
            {"threshold_median", h.threshold_median}, {"threshold_max", h.threshold_max},
            {"band_voxels", h.band_voxels},         {"fallback_voxels", h.fallback_voxels},
            {"voxels_added", h.voxels_added},       {"voxels_removed", h.voxels_removed}};
}

}  // namespace endocast::cli
