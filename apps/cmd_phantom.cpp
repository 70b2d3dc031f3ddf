// `endocast phantom`: writes a synthetic skull CT and its ground truth.
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.h"
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
    bool no_noise = false, no_blur = false, no_voids = false, no_crack = false,
         no_foramina = false, no_foramen_magnum = false, no_scalp = false;
};

/// OUT.nrrd -> OUT.json (also strips .nii.gz).
std::string sidecar_path(const std::string& out) {
    std::string base = out;
    for (const char* ext : {".nii.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd"}) {
        const std::string e(ext);
        if (base.size() > e.size() && base.compare(base.size() - e.size(), e.size(), e) == 0) {
            base.resize(base.size() - e.size());
            break;
        }
    }
    return base + ".json";
}

void run_phantom(const PhantomOptions& o, const GlobalOptions& g) {
    PhantomParams p;
    p.preset = parse_phantom_preset(o.preset);
    p.seed = o.seed;
    p.tilt_deg = o.tilt;
    if (!o.size.empty()) p.size = {o.size[0], o.size[1], o.size[2]};
    if (!o.spacing.empty()) p.spacing = {o.spacing[0], o.spacing[1], o.spacing[2]};
    if (!o.origin.empty()) p.origin = {o.origin[0], o.origin[1], o.origin[2]};
    p.noise = !o.no_noise;
    p.blur = !o.no_blur;
    p.diploic_voids = !o.no_voids;
    p.crack = !o.no_crack;
    p.small_foramina = !o.no_foramina;
    p.foramen_magnum = !o.no_foramen_magnum;
    p.scalp = !o.no_scalp;
    const PhantomResult r = generate_phantom(p);
    const Geometry& geo = r.ct.geometry();

    nlohmann::json j;
    j["preset"] = to_string(p.preset);
    j["seed"] = p.seed;
    j["tilt_deg"] = p.tilt_deg;
    j["dims"] = {geo.dims[0], geo.dims[1], geo.dims[2]};
    j["spacing_mm"] = {geo.spacing[0], geo.spacing[1], geo.spacing[2]};
    j["origin_mm"] = {geo.origin[0], geo.origin[1], geo.origin[2]};
    j["true_ecv_ml"] = r.true_ecv_ml;
    j["suggested_iso"] = r.suggested_iso;
    j["units"] = "HU";
    j["cavity_centre_mm"] = {r.cavity_centre_world[0], r.cavity_centre_world[1], r.cavity_centre_world[2]};
    j["cavity_semi_axes_mm"] = {r.cavity_semi_axes_mm[0], r.cavity_semi_axes_mm[1], r.cavity_semi_axes_mm[2]};
    j["foramen_magnum_mm"] = {r.foramen_magnum_world[0], r.foramen_magnum_world[1], r.foramen_magnum_world[2]};
    j["foramen_magnum_radius_mm"] = r.foramen_magnum_radius_mm;
    j["features"] = {{"noise", p.noise}, {"blur", p.blur}, {"diploic_voids", p.diploic_voids},
                     {"crack", p.crack}, {"small_foramina", p.small_foramina},
                     {"foramen_magnum", p.foramen_magnum}, {"scalp", p.scalp}};
    j["description"] = r.description;

    write_volume(r.ct, o.output);
    const std::string side = sidecar_path(o.output);
    write_text_atomic(side, j.dump(2) + "\n");
    if (!g.quiet) {
        std::cout << "phantom: " << r.description << "\n"
                  << "wrote " << o.output << " and " << side << "\n"
                  << "true ECV " << r.true_ecv_ml << " mL, suggested isovalue " << r.suggested_iso
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
    sub->add_option("OUT", o->output, "Output volume (.nrrd, .nii.gz, .mha)")->required();
    sub->add_option("--preset", o->preset, "human (brain-filled, scalp), dry (air-filled cranium), macaque (small braincase, 0.5 mm voxels)")
        ->check(CLI::IsMember({"human", "dry", "macaque"}))
        ->capture_default_str();
    sub->add_option("--seed", o->seed, "Seed of the noise and void placement")->capture_default_str();
    sub->add_option("--tilt", o->tilt, "Rotation of the head about the left-right axis (degrees)")
        ->check(CLI::Range(-90.0, 90.0))
        ->capture_default_str();
    sub->add_option("--size", o->size, "Grid size X Y Z in voxels (default: head plus 10 mm margin)")
        ->expected(3);
    sub->add_option("--spacing", o->spacing, "Voxel size SX SY SZ in mm (default 1, macaque 0.5)")
        ->expected(3);
    sub->add_option("--origin", o->origin, "World position of voxel (0,0,0) in mm (default 0 0 0)")
        ->expected(3);
    sub->add_flag("--no-noise", o->no_noise, "No Gaussian noise");
    sub->add_flag("--no-blur", o->no_blur, "No partial-volume blur");
    sub->add_flag("--no-voids", o->no_voids, "No diploic voids in the bone");
    sub->add_flag("--no-crack", o->no_crack, "No crack in the vault");
    sub->add_flag("--no-foramina", o->no_foramina, "No small foramina");
    sub->add_flag("--no-foramen-magnum", o->no_foramen_magnum, "No foramen magnum");
    sub->add_flag("--no-scalp", o->no_scalp, "No soft tissue around the skull");
    sub->callback([o, &g] { run_phantom(*o, g); });
}

}  // namespace endocast::cli
