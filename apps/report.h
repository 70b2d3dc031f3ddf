#pragma once
// The report of a run of the method, built in one place: extract writes it as report.json (batch
// reads each specimen's, the HTML page shows it) and robustness writes its input and parameters
// blocks. Keys are a contract (docs/report.schema.json); add, don't rename.
#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "endocast/dicom_series.h"
#include "endocast/endocast.h"
#include "meshpost/topology.h"

namespace endocast::cli {

/// The report of extract() (docs/report.schema.json) but what the caller adds: `outputs`, and
/// `timings_s.write` / `.total` (`.qc`, `.html` with the pictures).
nlohmann::json extract_report(const Result& r, const Options& o);

/// The report's `parameters` (what the method used, as resolved by it): isovalue and its rule,
/// void radius in voxels and mm, thin-bone prominence, seeds, cut planes, the watershed's
/// connectivity and the surface (r.params, resolve()); the distance threshold and cut planes of `p`.
nlohmann::json method_parameters_json(const ExtractParams& p, const ExtractionResult& r);

/// The report's `input`: the path(s), format, voxel type, files read, the input's geometry
/// (before --crop/--downsample), the DICOM series found and chosen, gantry tilt and resampling.
nlohmann::json input_json(const std::vector<std::string>& paths, const InputInfo& info, const Geometry& input_grid);

/// A DICOM series as `series --json` and the report's input.series_found give it (no file list):
/// series_uid, description, modality, sop_class_uid, sop_class, image_type, kernel, series_number
/// (null when absent), slices, rows, columns, pixel_spacing_mm [between rows, between columns],
/// slice_thickness_mm, slice_step_mm, folders, is_volume, reason, chosen.
nlohmann::json dicom_series_json(const DicomSeriesInfo& s, bool chosen);

/// {dims, spacing, origin} of a grid (the report's work_grid).
nlohmann::json grid_json(const Geometry& g);

/// The results of an extraction: ECV, mask volume, area, bone contact, the mesh's checks (closed
/// 2-manifold, genus, components, degenerate faces, self-intersections), the chosen cavity
/// (max_distance_mm, enclosure, candidates), what each closing step did (openings, creases, dips,
/// handles), warnings, void fill and, for the half-maximum surface, half_max.
nlohmann::json result_json(const ExtractionResult& r, const ExtractParams& p, const meshpost::TopologyReport& topo,
                           size_t self_intersections);

/// The report's `half_max` object: cavity_level, threshold_min/_median/_max, band_voxels,
/// fallback_voxels, voxels_added, voxels_removed.
nlohmann::json half_max_json(const HalfMaxInfo& h);

}  // namespace endocast::cli
