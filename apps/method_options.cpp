// The options shared by the subcommands that run the method: declared, converted and reported
// once (method_options.h).
#include "method_options.h"

#include <algorithm>
#include <utility>

#include "commands.h"
#include "endocast/errors.h"
#include "endocast/tiff.h"

namespace endocast::cli {
namespace {

// `names` -> enum values, from the library's to_string (one spelling of each name).
template <typename E, typename Name>
std::vector<std::pair<std::string, E>> enum_names(std::initializer_list<E> values, Name name) {
    std::vector<std::pair<std::string, E>> m;
    for (E e : values) m.emplace_back(std::string(name(e)), e);
    return m;
}

// An option parsing one of `names` into an enum: CheckedTransformer maps the name to the value; a
// check on the raw text before it accepts the names only (CheckedTransformer alone also takes the
// enum's integer). --help shows {a,b,c}, as the Slicer description reads it.
template <typename E>
CLI::Option* add_enum(CLI::App& app, const std::string& flag, E& target,
                      const std::vector<std::pair<std::string, E>>& names, const std::string& help) {
    std::vector<std::string> keys;
    std::string current;
    for (const auto& n : names) {
        keys.push_back(n.first);
        if (n.second == target) current = n.first;
    }
    return app.add_option(flag, target, help)
        ->transform(CLI::CheckedTransformer(names).description(""))
        ->transform(CLI::IsMember(keys))  // runs first (transforms are applied last-added first)
        ->default_str(current);
}

}  // namespace

const char* const kSurfaceHelp =
    "iso: the isosurface at T (the paper's method); half-max: the half-maximum-height surface "
    "(Spoor et al. 1993, the standard edge criterion for CT in physical anthropology): near the "
    "cavity's boundary each voxel gets the threshold half-way between the cavity content (median CT "
    "of the cavity's core) and the local bone peak (largest CT within a few voxels), the voxels "
    "there are re-classified by it and the surface follows it, so it moves far less with --iso "
    "(T still segments the skull and is used where no bone edge is near)";

const char* const kSeriesHelp =
    "DICOM: the SeriesInstanceUID of the series to read, when the folder (or DICOMDIR) holds several "
    "(`endocast series DIR` lists them). Default: the CT volume with the thinnest slices, then the most "
    "slices, then the smallest UID; the others are named in a warning";
const char* const kSeriesDescriptionHelp =
    "DICOM: read the series whose SeriesDescription contains TEXT (case-insensitive; one equal to TEXT wins "
    "over ones containing it; with --series both must match). Matching no series or several volumes is an "
    "error that lists them";

void add_method_options(CLI::App& app, MethodOptions& o, bool with_iso) {
    if (with_iso)
        app.add_option("--iso", o.iso, "Bone isovalue T in the scan's units (HU for DICOM). Default: automatic from the histogram, reported with its rule and margin: Otsu between soft tissue and bone (a living head); Otsu between air with soft tissue and bone when soft tissue lies close to air (small-animal microCT); Otsu between air and the rest (a dry skull, which may need --iso)");
    app.add_option("--void-radius", o.void_radius, "Ball radius for filling voids in bone, in voxels of the smallest spacing")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    app.add_option("--void-radius-mm", o.void_radius_mm, "Ball radius for filling voids in mm (overrides --void-radius)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--thin-bone", o.thin_bone,
                   "Recover thin bone (orbital roofs, cribriform plate) blurred below the isovalue: a "
                   "voxel below T is bone when it is a ridge of the CT along an axis rising at least "
                   "this fraction of the way from its sides up to T; 0 = off (the paper's binarization). "
                   "Stops leaks through thin plates (the orbital roofs); may also close the thin "
                   "walls of a sinus, whose air is then left out of a tissue-filled braincase "
                   "(docs/accuracy.md). A ridge with the cavity on both sides and around it (the "
                   "blur past the tip of a bony lip, such as the sella's rim) goes back to the cavity")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    add_enum(app, "--seed-mode", o.seed_mode,
             enum_names({SeedMode::Auto, SeedMode::AutoLargest, SeedMode::Distance, SeedMode::Point},
                        [](SeedMode m) { return to_string(m); }),
             "auto: border = other; candidate cavities at the deepest distance maxima, "
             "the one best enclosed by bone (score enclosure^4 x volume, reported) = endocast; "
             "auto-largest: the paper's rule (deepest empty voxel = endocast); "
             "distance: components of the distance field above --distance-threshold; "
             "point: a ball around --seed-point");
    app.add_option("--seed-scale", o.seed_scale, "s in (0,1): seed balls have radius s * distance to bone")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    app.add_option("--border-seed-scale", o.border_seed_scale,
                   "Scale of the 'other' seed balls at the volume border. Default: --seed-scale, and "
                   "with --seed-mode auto, 0 when the chosen cavity then faces the border over more "
                   "than 10% of its boundary, or more than 1% of it faces the border balls, or when "
                   "the border cuts a section of the cavity ringed by bone (a scan cropped through the "
                   "braincase; warned and reported). 0 seeds the border voxels alone, so the border seeds do not eat "
                   "into a cavity cut by the border")
        ->check(CLI::Range(0.0, 1.0));
    app.add_option("--distance-threshold", o.distance_threshold, "mm, for --seed-mode distance (the paper's alternative for small braincases)");
    app.add_option("--seed-point", o.seed_point, "X Y Z (or X,Y,Z, as 3D Slicer passes it) in world mm: a point inside the braincase (implies --seed-mode point)")
        ->expected(3)
        ->delimiter(',');
    app.add_option("--cut-plane", o.cut_planes,
                   "PX PY PZ NX NY NZ (world mm): close an opening by a plane; every empty voxel on "
                   "the side the normal points to is outside the endocast (repeatable)")
        ->expected(6)
        ->allow_extra_args(false);
    app.add_flag("--no-close-openings", o.keep_openings,
                 "Keep the boundary where the watershed floods meet (the paper's behaviour) "
                 "instead of closing each opening (foramen magnum, canals) by a plane fitted to its "
                 "rim on the inner skull surface");
    app.add_flag("--no-restore-creases", o.keep_creases_closed,
                 "Leave to bone the creases of the cavity that the void fill closes (the olfactory "
                 "groove, the sella, the angles of the skull base's floors): by default each piece "
                 "the void fill added that touches only the endocast (not a foramen: those a "
                 "ball of half, then a quarter of, the void-fill radius closes stay closed) and lies on "
                 "average at most twice that radius below its mouth is given back to it");
    app.add_flag("--no-flush-dips", o.keep_dips,
                 "Leave each closing surface where the void fill's ball dips into the hole it "
                 "plugged (up to 2.7 mm beyond the inner table for a 10 mm hole with 6 voxels of 1 mm) "
                 "instead of moving it onto the membrane spanning the hole's rim; and each closing "
                 "surface the watershed left sunk down a channel wider than that ball, facing other "
                 "empty space, where it is (not raised to the channel's mouth); and each closing surface "
                 "across a wide opening as the watershed left it (not moved onto the thin plate "
                 "continuing the inner table around it)");
    app.add_flag("--no-bone-box", o.whole_volume,
                 "Run every stage on the whole volume. By default the stages after binarize run on "
                 "the bone's bounding box grown by twice the void-fill radius and 2 voxels (the "
                 "report's work_box): the same cavity, faster and in less memory when air surrounds "
                 "the skull");
    app.add_option("--opening-radius-mm", o.opening_radius_mm,
                   "Ball radius (mm) that defines the core of the cavity when closing openings "
                   "(default: 0.3 x the cavity's depth)");
    add_enum(app, "--surface", o.surface,
             enum_names({SurfaceMode::Iso, SurfaceMode::HalfMax}, [](SurfaceMode m) { return to_string(m); }),
             kSurfaceHelp);
}

void add_grid_options(CLI::App& app, GridOptions& o) {
    app.add_option("--crop", o.crop,
                    "X0 Y0 Z0 X1 Y1 Z1: keep only voxels X0 <= x < X1 (likewise y, z; indices of "
                    "the input, end exclusive) before extraction; the mesh stays in the scan's world "
                    "coordinates")
        ->expected(6);
    app.add_option("--downsample", o.downsample,
                    "Integer factor F: average F x F x F blocks of voxels (after --crop) before "
                    "extraction; spacing x F, about 1/F^3 of the memory and time")
        ->check(CLI::Range(1, 64))
        ->capture_default_str();
    app.add_option("--refine", o.refine,
                    "Integer factor F >= 2: the coarse-to-fine path for scans too large for memory (microCT): "
                    "the method runs on the scan block-averaged by F (choosing the cavity, closing its "
                    "openings), then the band around its boundary is decided again from the scan's own voxels "
                    "and meshed on the scan's grid, a slab of planes at a time (inputs read in slabs only: TIFF, "
                    "raw, NRRD raw/gzip, uncompressed MetaImage). 0: automatic, taken (with the smallest F whose grid holds <= 134 M "
                    "voxels) only when the whole grid does not fit in memory; --mask and the QC picture are then on the coarse grid")
        ->check(CLI::Range(0, 64))
        ->capture_default_str();
    app.add_option("--refine-slab", o.refine_slab, "Planes of the scan per slab on the coarse-to-fine path")
        ->check(CLI::Range(int64_t(1), int64_t(4096)))
        ->capture_default_str();
    app.add_option("--max-memory", o.max_memory_mb,
                    "MB: stop before reading (exit 6) when the estimated peak memory exceeds this "
                    "(default: the available memory, MemAvailable or the cgroup limit)")
        ->check(CLI::PositiveNumber);
}

void apply_grid_options(const GridOptions& g, Options& o) {
    if (!g.crop.empty()) o.crop = CropBox{{g.crop[0], g.crop[1], g.crop[2]}, {g.crop[3], g.crop[4], g.crop[5]}};
    o.downsample = g.downsample;
    o.refine = g.refine;
    o.refine_slab = g.refine_slab;
    o.max_memory_mb = g.max_memory_mb;
}

void add_input_options(CLI::App& app, InputOptions& o) {
    app.add_option("--series", o.series, kSeriesHelp);
    app.add_option("--series-description", o.series_description, kSeriesDescriptionHelp);
    app.add_option("--slice-spacing", o.slice_spacing,
                   "DICOM: slice spacing in mm of the regular grid that a series with gantry tilt or uneven slice "
                   "spacing is resampled onto (default 0: the smallest step of a run of evenly spaced slices); "
                   "> 0 resamples any DICOM series")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--raw-size", o.raw_size, "Raw input: X Y Z voxels of the whole volume")->expected(3);
    add_enum(app, "--raw-type", o.raw_type,
             enum_names({RawType::Int8, RawType::UInt8, RawType::Int16, RawType::UInt16, RawType::Int32,
                         RawType::UInt32, RawType::Float32, RawType::Float64},
                        [](RawType t) { return to_string(t); }),
             "Raw input voxel type");
    add_enum(app, "--raw-endian", o.raw_endian,
             std::vector<std::pair<std::string, Endian>>{{"little", Endian::Little}, {"big", Endian::Big}},
             "Raw input byte order");
    app.add_option("--raw-header", o.raw_header, "Raw input: bytes to skip at the start of each file")
        ->capture_default_str();
    app.add_option("--spacing", o.spacing,
                   "Raw and TIFF input: voxel size SX SY SZ in mm (raw default 1 1 1; TIFF default the files' "
                   "resolution tags, required when they have none)")
        ->expected(3);
    app.add_option("--origin", o.origin,
                   "Raw and TIFF input: world position of voxel (0,0,0) in mm (default 0 0 0, or ImageJ's origin)")
        ->expected(3);
}

ExtractParams method_params(const MethodOptions& o) {
    ExtractParams p;
    p.binarize.isovalue = o.iso;
    p.void_fill.radius_voxels = o.void_radius;
    p.void_fill.radius_mm = o.void_radius_mm;
    p.binarize.thin_bone_prominence = o.thin_bone;
    p.seeds.mode = o.seed_mode;
    p.seeds.scale = o.seed_scale;
    p.seeds.border_scale = o.border_seed_scale;
    p.seeds.distance_threshold_mm = o.distance_threshold;
    if (!o.seed_point.empty()) {
        if (o.seed_mode == SeedMode::Auto) p.seeds.mode = SeedMode::Point;
        p.seeds.points_world.push_back({o.seed_point[0], o.seed_point[1], o.seed_point[2]});
    }
    if (p.seeds.mode == SeedMode::Point && p.seeds.points_world.empty())
        throw InvalidParameter("--seed-mode point needs --seed-point X Y Z (world mm)");
    if (p.seeds.mode == SeedMode::Distance && !(o.distance_threshold > 0))
        throw InvalidParameter("--seed-mode distance needs --distance-threshold MM (> 0)");
    for (const auto& c : o.cut_planes) p.cut_planes.push_back({{c[0], c[1], c[2]}, {c[3], c[4], c[5]}});
    p.close_openings = !o.keep_openings;
    p.creases.enabled = !o.keep_creases_closed;
    p.dips.enabled = !o.keep_dips;
    p.bone_box = !o.whole_volume;
    p.openings.radius_mm = o.opening_radius_mm;
    p.surface = o.surface;
    return p;
}

ReadOptions read_options(const InputOptions& o) {
    ReadOptions ro;
    ro.series_uid = o.series;
    ro.series_description = o.series_description;
    ro.slice_spacing_mm = o.slice_spacing;
    if (!o.raw_size.empty()) {
        RawOptions raw;
        raw.size = {o.raw_size[0], o.raw_size[1], o.raw_size[2]};
        raw.type = o.raw_type;
        raw.endian = o.raw_endian;
        raw.header_bytes = o.raw_header;
        if (!o.spacing.empty()) raw.spacing = {o.spacing[0], o.spacing[1], o.spacing[2]};
        if (!o.origin.empty()) raw.origin = {o.origin[0], o.origin[1], o.origin[2]};
        ro.raw = raw;
    } else if (!o.spacing.empty() || !o.origin.empty()) {
        if (!is_tiff_input(o.inputs))
            throw InvalidParameter("--spacing/--origin apply to raw input (with --raw-size) and TIFF input only; "
                                   "other formats carry their own geometry");
        if (!o.spacing.empty()) ro.spacing = Vec3{o.spacing[0], o.spacing[1], o.spacing[2]};
        if (!o.origin.empty()) ro.origin = Vec3{o.origin[0], o.origin[1], o.origin[2]};
    }
    return ro;
}

}  // namespace endocast::cli
