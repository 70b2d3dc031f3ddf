#pragma once
// The options shared by the subcommands that run the method (extract, robustness; batch mirrors
// extract's): how the input is read (InputOptions) and the method's parameters (MethodOptions).
// Each group is declared once on a CLI11 app (enums parsed by CheckedTransformer into the
// library's enum types) and turned into the library's parameter structs once; report.h writes
// them into the report.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "endocast/endocast.h"

namespace endocast::cli {

/// How the input is read, beyond its path(s): the DICOM series, the regular grid a tilted or
/// unevenly spaced series is resampled onto, and headerless raw input.
struct InputOptions {
    std::vector<std::string> inputs;  ///< the positional INPUT(s), declared by each subcommand
    std::string series, series_description;
    double slice_spacing = 0;  ///< mm; 0 = the smallest step of a run of evenly spaced slices
    std::vector<int64_t> raw_size;  ///< X Y Z voxels; empty = not raw input
    RawType raw_type = RawType::UInt16;
    Endian raw_endian = Endian::Little;
    uint64_t raw_header = 0;            ///< bytes skipped at the start of each raw file
    std::vector<double> spacing, origin;  ///< raw input only (mm); empty = 1 1 1 / 0 0 0
};

/// The method's parameters as the user gives them (ExtractParams is what the library takes).
struct MethodOptions {
    std::optional<double> iso;  ///< bone isovalue T (scan units); empty = automatic
    double void_radius = VoidFillParams{}.radius_voxels;  ///< voxels of the smallest spacing (the library's default)
    std::optional<double> void_radius_mm;  ///< overrides void_radius
    double thin_bone = BinarizeParams{}.thin_bone_prominence;  ///< in [0, 1]; 0 = off
    SeedMode seed_mode = SeedParams{}.mode;
    double seed_scale = SeedParams{}.scale;
    double border_seed_scale = -1;   ///< < 0: the library's default (reported)
    double distance_threshold = 0;   ///< mm, for SeedMode::Distance
    std::vector<double> seed_point;  ///< X Y Z world mm, or empty
    std::vector<std::vector<double>> cut_planes;  ///< each PX PY PZ NX NY NZ (world mm)
    bool keep_openings = false;
    bool keep_creases_closed = false;
    bool keep_dips = false;
    bool whole_volume = false;     ///< --no-bone-box: every stage on the whole volume
    double opening_radius_mm = 0;  ///< 0 = 0.3 x the cavity's depth
    SurfaceMode surface = ExtractParams{}.surface;
};

/// The grid the method runs on and the memory guard: --crop, --downsample, --refine,
/// --refine-slab, --max-memory (extract, robustness).
struct GridOptions {
    std::vector<int64_t> crop;       ///< X0 Y0 Z0 X1 Y1 Z1 voxels, or empty
    int downsample = 1;
    std::optional<double> max_memory_mb;
    int refine = 0;                  ///< 0: automatic (coarse-to-fine only when the whole grid does not fit)
    int64_t refine_slab = 64;        ///< fine planes per slab on the coarse-to-fine path
};

/// Declares --crop, --downsample, --refine, --refine-slab and --max-memory.
void add_grid_options(CLI::App& app, GridOptions& o);

/// Sets the library's crop, downsample, refinement and memory limit from `g`.
void apply_grid_options(const GridOptions& g, Options& o);

/// Declares the method's options on `app`, in the order `--help` lists them; `with_iso` false
/// leaves out `--iso` (robustness declares its own central isovalue).
void add_method_options(CLI::App& app, MethodOptions& o, bool with_iso = true);

/// Declares `--series`, `--series-description`, `--slice-spacing` and the raw-input options.
void add_input_options(CLI::App& app, InputOptions& o);

/// The library's parameters for `o` (progress callback unset). Throws InvalidParameter for
/// combinations the options cannot express alone (--seed-mode point without --seed-point, ...).
ExtractParams method_params(const MethodOptions& o);

/// The reader's options for `o`. Throws InvalidParameter for --spacing/--origin without raw input.
ReadOptions read_options(const InputOptions& o);

}  // namespace endocast::cli
