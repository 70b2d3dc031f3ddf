#pragma once
// Synthetic skull CT phantoms with a known (analytic) endocranial volume: the ground truth of the
// accuracy tests and the embedded default of the demo.
//
// Phantom frame (before tilt): x = left->right, y = posterior->anterior, z = inferior->superior,
// centred on the braincase centre. The braincase (true cavity) is an ellipsoid; the skull is the
// shell between it and a larger ellipsoid; openings (foramina) are closed at the inner skull surface
// for the ground truth, so the true ECV is exactly the ellipsoid's volume.
#include <cstdint>
#include <string>

#include "endocast/volume.h"

namespace endocast {

enum class PhantomPreset {
    Human,    ///< adult human head: brain ~35 HU, scalp, ~1300 mL
    Dry,      ///< dry human cranium: air-filled braincase, no soft tissue
    Macaque,  ///< small braincase (~90 mL), brain-filled, 0.5 mm voxels by default
};
PhantomPreset parse_phantom_preset(const std::string& s);  ///< "human|dry|macaque"
std::string to_string(PhantomPreset p);

struct PhantomParams {
    PhantomPreset preset = PhantomPreset::Human;
    uint64_t seed = 1;                 ///< noise and void placement
    double tilt_deg = 0.0;             ///< rotation of the skull about the x axis (pitch), degrees
    Dims size{0, 0, 0};                ///< voxels; 0 = automatic (head plus margin)
    Vec3 spacing{0.0, 0.0, 0.0};       ///< mm; 0 = preset default (1 mm human/dry, 0.5 mm macaque)
    Vec3 origin{0.0, 0.0, 0.0};        ///< world mm of voxel (0,0,0)
    bool noise = true;                 ///< Gaussian noise (sigma 20 HU)
    bool blur = true;                  ///< partial-volume blur (Gaussian, sigma 0.6 voxel)
    bool diploic_voids = true;         ///< low-density voids inside the bone shell
    bool crack = true;                 ///< a thin crack through the vault
    bool small_foramina = true;        ///< several 1.5-3 mm openings through the shell
    bool foramen_magnum = true;        ///< the large opening at the skull base
    bool scalp = true;                 ///< soft tissue around the skull (ignored for Dry)
};

struct PhantomResult {
    Volume<int16_t> ct;                ///< HU
    double true_ecv_ml = 0;            ///< analytic endocranial volume
    double suggested_iso = 0;          ///< HU, midway between cavity content and bone
    Vec3 cavity_centre_world{0, 0, 0}; ///< mm
    Vec3 cavity_semi_axes_mm{0, 0, 0}; ///< inner ellipsoid semi-axes (before tilt)
    Vec3 foramen_magnum_world{0, 0, 0};///< centre of the foramen magnum on the inner surface, mm
    double foramen_magnum_radius_mm = 0;
    double shell_thickness_mm = 0;     ///< skull thickness (outer semi-axes = inner + this)
    double sigma_mm = 0;               ///< partial-volume blur sigma used (0 when blur is off)
    std::string description;           ///< one line: preset, size, spacing, features
};

/// Generates a phantom. Deterministic for a given seed (the same bytes on every machine and
/// thread count). Throws InvalidParameter for non-positive spacing or a size too small for the head.
PhantomResult generate_phantom(const PhantomParams& p = {});

}  // namespace endocast
