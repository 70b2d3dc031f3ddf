// `endocast phantom`: writes a synthetic skull CT and its ground truth.
#include <regex>
#include <algorithm>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "progress.h"
#include "meshpost/io.h"
#include "endocast/io.h"
#include "endocast/phantom.h"

namespace endocast::cli {
namespace {

struct PhantomOptions {
    std::string output;
    std::string preset = "human";
    uint64_t seed = 1;
    double tilt = 0;
    std::vector<int64_t> size;
    std::vector<double> spacing;
    std::vector<double> origin;
    std::vector<double> grid_centre;
    bool no_noise = false, no_blur = false, no_voids = false, no_crack = false,
         no_foramina = false, no_foramen_magnum = false, no_scalp = false;
    bool spine = false, sinus = false, orbits = false, body = false, skull_base = false;
    double optic_canal_radius = 0;
    double crop_base = 0;
    bool stream = false;
};

/// OUT.nrrd -> OUT.json (also strips .nii.gz).
std::string sidecar_path(const std::string& out) {
    std::string base = out;
    for (const char* ext : {".nii.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd", ".tiff", ".tif"}) {
        const std::string e(ext);
        if (base.size() > e.size() && base.compare(base.size() - e.size(), e.size(), e) == 0) {
            base.resize(base.size() - e.size());
            break;
        }
    }
    // A TIFF slice pattern ("stack/slice%04d"): the sidecar is named without the number
    // ("stack/slice.json"; "stack/phantom.json" when the name is only the number).
    const std::regex conversion("%[-+ 0]*[0-9]*[diu]");
    if (std::regex_search(base, conversion)) {
        base = std::regex_replace(base, conversion, "");
        if (base.empty() || base.back() == '/') base += "phantom";
    }
    return base + ".json";
}

void run_phantom(const PhantomOptions& o, const GlobalOptions& g) {
    // "human-full": the human study case (spine, frontal sinus, orbits on).
    const bool full = o.preset == "human-full";
    PhantomParams p = full ? human_full_phantom_params() : PhantomParams{};
    if (!full) p.preset = parse_phantom_preset(o.preset);
    p.seed = o.seed;
    p.tilt_deg = o.tilt;
    if (!o.size.empty()) p.size = {o.size[0], o.size[1], o.size[2]};
    if (!o.spacing.empty()) p.spacing = {o.spacing[0], o.spacing[1], o.spacing[2]};
    if (!o.origin.empty()) p.origin = {o.origin[0], o.origin[1], o.origin[2]};
    if (!o.grid_centre.empty()) p.grid_centre_mm = {o.grid_centre[0], o.grid_centre[1], o.grid_centre[2]};
    p.noise = !o.no_noise;
    p.blur = !o.no_blur;
    p.diploic_voids = !o.no_voids;
    p.crack = !o.no_crack;
    p.small_foramina = !o.no_foramina;
    p.foramen_magnum = !o.no_foramen_magnum;
    p.scalp = !o.no_scalp;
    p.spine = p.spine || o.spine;
    p.frontal_sinus = p.frontal_sinus || o.sinus;
    p.orbits = p.orbits || o.orbits;
    p.optic_canal_radius_mm = o.optic_canal_radius;
    p.body = o.body;
    p.crop_base_mm = o.crop_base;
    p.skull_base = o.skull_base;
    if (p.preset == PhantomPreset::Mouse) p.spine = true;  // always built (features.spine)
    // Rendered in slabs: a volume of up to kWholeVoxels is gathered and written whole (NRRD with
    // gzip, NIfTI, ...); a larger one (microCT) streams to the file slab by slab (raw NRRD, TIFF)
    // and is never held whole.
    constexpr int64_t kWholeVoxels = int64_t{1} << 29;  // 1 GiB as int16
    constexpr int64_t kSlabVoxels = int64_t{1} << 26;   // 128 MiB as int16
    Progress progress(choose_progress_style(g.quiet, g.log_json), 0);
    Volume<int16_t> ct;
    std::unique_ptr<SlabWriter> stream;
    const PhantomResult r = generate_phantom_slabs(
        p, kSlabVoxels, [&](const Geometry& whole, int64_t z0, const Volume<int16_t>& slab) {
            if (z0 == 0) {
                if (!o.stream && whole.voxel_count() <= uint64_t(kWholeVoxels)) {
                    ct = Volume<int16_t>(whole);
                } else {
                    stream = open_slab_writer(o.output, whole);
                    progress.info("phantom: " + std::to_string(whole.dims[0]) + " x " + std::to_string(whole.dims[1]) +
                                  " x " + std::to_string(whole.dims[2]) + " voxels, written to " + o.output +
                                  " slab by slab");
                }
            }
            if (!stream) {
                std::copy(slab.data(), slab.data() + slab.size(), ct.data() + size_t(z0) * size_t(whole.dims[0] * whole.dims[1]));
                return;
            }
            stream->write(slab);
            const int64_t done = z0 + slab.nz();
            const double t = progress.elapsed_s();
            std::ostringstream m;
            m << "phantom: " << done << " of " << whole.dims[2] << " slices, " << std::fixed << std::setprecision(0) << t
              << " s, about " << t * double(whole.dims[2] - done) / double(done) << " s left";
            progress.info(m.str());
        });
    const Geometry& geo = r.geometry;

    nlohmann::json j;
    j["preset"] = to_string(p.preset);
    j["preset_name"] = o.preset;
    j["seed"] = p.seed;
    j["tilt_deg"] = p.tilt_deg;
    j["dims"] = {geo.dims[0], geo.dims[1], geo.dims[2]};
    j["spacing_mm"] = {geo.spacing[0], geo.spacing[1], geo.spacing[2]};
    j["origin_mm"] = {geo.origin[0], geo.origin[1], geo.origin[2]};
    j["true_ecv_ml"] = r.true_ecv_ml;
    j["true_ecv_error_ml"] = r.true_ecv_error_ml;
    j["suggested_iso"] = r.suggested_iso;
    j["units"] = "HU";
    j["cavity_centre_mm"] = {r.cavity_centre_world[0], r.cavity_centre_world[1], r.cavity_centre_world[2]};
    j["cavity_semi_axes_mm"] = {r.cavity_semi_axes_mm[0], r.cavity_semi_axes_mm[1], r.cavity_semi_axes_mm[2]};
    j["foramen_magnum_mm"] = {r.foramen_magnum_world[0], r.foramen_magnum_world[1], r.foramen_magnum_world[2]};
    j["foramen_magnum_radius_mm"] = r.foramen_magnum_radius_mm;
    j["foramen_magnum_axis"] = {r.foramen_magnum_axis[0], r.foramen_magnum_axis[1], r.foramen_magnum_axis[2]};
    const auto& R = r.cavity_rotation;
    j["cavity_rotation"] = {{R[0], R[1], R[2]}, {R[3], R[4], R[5]}, {R[6], R[7], R[8]}};
    j["spinal_canal_radius_mm"] = r.spinal_canal_radius_mm;
    j["shell_thickness_mm"] = r.shell_thickness_mm;
    j["sigma_mm"] = r.sigma_mm;
    nlohmann::json openings = nlohmann::json::array();
    for (const PhantomOpening& op : r.openings)
        openings.push_back({{"name", op.name},
                            {"centre_mm", {op.centre_world[0], op.centre_world[1], op.centre_world[2]}},
                            {"axis", {op.axis_world[0], op.axis_world[1], op.axis_world[2]}},
                            {"radius_mm", op.radius_mm}});
    j["openings"] = openings;
    j["cropped"] = r.cropped;
    if (r.cropped) {
        j["crop_plane_z_mm"] = r.crop_plane_z_mm;
        j["true_ecv_slice_centres_ml"] = r.true_ecv_slice_centres_ml;
    }
    j["features"] = {{"noise", p.noise}, {"blur", p.blur}, {"diploic_voids", p.diploic_voids},
                     {"crack", p.crack}, {"small_foramina", p.small_foramina},
                     {"foramen_magnum", p.foramen_magnum}, {"scalp", p.scalp},
                     {"spine", p.spine}, {"frontal_sinus", p.frontal_sinus},
                     {"orbits", p.orbits},
                     {"optic_canal_radius_mm", r.optic_canal_radius_mm},
                     {"body", p.body}, {"crop_base_mm", p.crop_base_mm},
                     {"skull_base", p.skull_base}};
    if (r.landmarks) {
        const PhantomLandmarks& l = *r.landmarks;
        auto v = [](const Vec3& x) { return nlohmann::json::array({x[0], x[1], x[2]}); };
        j["landmarks"] = {{"basion_mm", v(l.basion)},
                          {"opisthion_mm", v(l.opisthion)},
                          {"foramen_magnum_plane", {{"point_mm", v(l.foramen_magnum_plane_point)},
                                                    {"normal", v(l.foramen_magnum_plane_normal)}}},
                          {"cribriform_plate_centre_mm", v(l.cribriform_plate_centre)},
                          {"symmetry_plane", {{"point_mm", v(l.symmetry_plane_point)},
                                              {"normal", v(l.symmetry_plane_normal)}}}};
    }
    j["description"] = r.description;

    if (stream) stream->finish();
    else write_volume(ct, o.output);
    const std::string side = sidecar_path(o.output);
    meshpost::write_file_atomic(side, j.dump(2) + "\n");
    if (!g.quiet) {
        std::cout << "phantom: " << r.description << "\n"
                  << "wrote " << o.output << " and " << side << "\n"
                  << "true ECV " << r.true_ecv_ml << " mL (+- " << r.true_ecv_error_ml
                  << "), suggested isovalue " << r.suggested_iso
                  << " HU\n";
    }
}

}  // namespace

void setup_phantom(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<PhantomOptions>();
    auto* sub = app.add_subcommand(
        "phantom",
        "Write a synthetic skull CT (HU, int16) with a known endocranial volume, and OUT.json with "
        "the true ECV (mL) and the suggested isovalue.");
    sub->add_option("OUT", o->output,
                    "Output volume (.nrrd, .nii.gz, .mha; .tif: one multi-page TIFF; a pattern such as "
                    "stack/slice%04d.tif: one TIFF per slice, numbered from 0, into an existing folder)")
        ->required();
    sub->add_option("--preset", o->preset,
                    "human (brain-filled, scalp), dry (air-filled cranium), macaque (small braincase, "
                    "0.5 mm voxels), human-full (human with --spine --sinus --orbits), mouse or rodent "
                    "(adult mouse cranium, ECV ~0.45 mL, 0.07 mm voxels: cribriform plate with 0.04-0.15 mm "
                    "pores, turbinates, bullae, oblique foramen magnum closed by its plane, spine; always "
                    "anatomical)")
        ->check(CLI::IsMember({"human", "dry", "macaque", "human-full", "mouse", "rodent"}))
        ->capture_default_str();
    sub->add_option("--seed", o->seed, "Seed of the noise and void placement")->capture_default_str();
    sub->add_option("--tilt", o->tilt, "Rotation of the head about the left-right axis (degrees)")
        ->check(CLI::Range(-90.0, 90.0))
        ->capture_default_str();
    sub->add_option("--size", o->size, "Grid size X Y Z in voxels (default: head plus 10 mm margin; mouse 1 mm)")
        ->expected(3);
    sub->add_option("--spacing", o->spacing, "Voxel size SX SY SZ in mm (default 1, macaque 0.5, mouse 0.07)")
        ->expected(3);
    sub->add_option("--origin", o->origin, "World position of voxel (0,0,0) in mm (default 0 0 0)")
        ->expected(3);
    sub->add_option("--grid-centre", o->grid_centre,
                    "With --size (--skull-base or mouse): the phantom-frame point X Y Z in mm (x left->right, "
                    "y posterior->anterior, z inferior->superior, from the cavity centre, before --tilt) put at "
                    "the grid's centre, e.g. a small window at a fine --spacing (default 0 0 0)")
        ->expected(3);
    sub->add_flag("--no-noise", o->no_noise, "No Gaussian noise");
    sub->add_flag("--no-blur", o->no_blur, "No partial-volume blur");
    sub->add_flag("--no-voids", o->no_voids, "No diploic voids in the bone");
    sub->add_flag("--no-crack", o->no_crack, "No crack in the vault");
    sub->add_flag("--no-foramina", o->no_foramina, "No small foramina");
    sub->add_flag("--no-foramen-magnum", o->no_foramen_magnum, "No foramen magnum");
    sub->add_flag("--no-scalp", o->no_scalp, "No soft tissue around the skull");
    sub->add_flag("--spine", o->spine,
                  "Cervical spine: content-filled canal from the foramen magnum to the lower border "
                  "inside vertebral rings");
    sub->add_flag("--sinus", o->sinus,
                  "Air-filled frontal sinus joined by a duct to the nasal cavity and the nostrils");
    sub->add_flag("--orbits", o->orbits,
                  "Two orbits (fat, eyeball) joined to the braincase by optic canals");
    sub->add_option("--optic-canal-radius", o->optic_canal_radius,
                    "Optic canal radius in mm (default: 7 human/dry, 3.5 macaque; open after the "
                    "6-voxel void closing)")
        ->check(CLI::NonNegativeNumber);
    sub->add_flag("--body", o->body,
                  "Large field of view: shoulders, chest, clavicles and a CT couch touching the head "
                  "(431x321x279 voxels at 1 mm)");
    sub->add_flag("--skull-base", o->skull_base,
                  "Anatomical skull base: anterior fossa over 0.5-1 mm orbital roofs, cribriform "
                  "plate (1 mm holes), middle fossae under the sphenoid wings, petrous ridges, sella, "
                  "clivus, posterior fossa, and the foramina at their real sizes (with the human, "
                  "dry or macaque preset; with --spine, --tilt, --crop-base, --no-scalp; not with "
                  "--orbits, --sinus, --body, --optic-canal-radius)");
    sub->add_option("--crop-base", o->crop_base,
                    "Cut the volume at the skull base: its lower face lies MM above the cavity's "
                    "lowest point (0 = off)")
        ->check(CLI::NonNegativeNumber);
    sub->add_flag("--stream", o->stream,
                  "Write the volume slab by slab (128 MiB of voxels at a time) and never hold it whole; "
                  "automatic above 2^29 voxels (1 GiB). Raw .nrrd or .tif output only");
    sub->callback([o, &g] { run_phantom(*o, g); });
}

}  // namespace endocast::cli
