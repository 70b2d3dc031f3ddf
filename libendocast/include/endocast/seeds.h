#pragma once
// Stage 4: seeds for the watershed, on the distance field d (mm) of the empty space.
//
// SeedMode::Auto (the paper's rule): "other" = every empty voxel b on the faces of the volume and
//   every voxel within s*d(b) of one; "endocast" = the voxel e of largest distance outside the other
//   seeds and every voxel within s*d(e) of it (s = scale < 1). The union of balls of varying radius is
//   exact: a generalized distance transform with f0(b) = -(s d(b))^2.
// SeedMode::Distance (the paper's alternative for small braincases): components of {d >= t};
//   those touching the volume's faces are "other", the largest remaining one is "endocast".
// SeedMode::Point: "endocast" = the ball of radius s*d(p) around a given world point p (mm);
//   "other" as in Auto.
#include <cstddef>
#include <string>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

enum class SeedMode { Auto, Distance, Point };
SeedMode parse_seed_mode(const std::string& s);  ///< "auto|distance|point"
std::string to_string(SeedMode m);

struct SeedParams {
    SeedMode mode = SeedMode::Auto;
    double scale = 0.9;                    ///< s in (0, 1): ball radius as a fraction of d
    double distance_threshold_mm = 0;      ///< t for SeedMode::Distance (mm, > 0)
    std::vector<Vec3> points_world;        ///< SeedMode::Point: points inside the braincase (mm)
};

struct SeedResult {
    /// Per voxel: kBone where bone, kOther / kEndocast for seeds, kUnlabelled elsewhere.
    Volume<uint8_t> labels;
    std::vector<Vec3> endocast_seeds_world;  ///< centres of the endocast seed balls (mm)
    std::vector<double> endocast_seed_radii_mm;
    double endocast_seed_distance_mm = 0;    ///< d at the (first) endocast seed centre
    size_t endocast_seed_voxels = 0;
    size_t other_seed_voxels = 0;
};

/// Places seeds. `bone` is 0/1, `distance` the distance (mm) of each voxel to the nearest bone.
/// Throws InvalidParameter (bad scale/threshold, a seed point outside the volume or in bone) or
/// NoResult (no empty voxel left for the endocast, no component above the threshold).
SeedResult place_seeds(const Volume<uint8_t>& bone, const Volume<float>& distance,
                       const SeedParams& p = {});

}  // namespace endocast
