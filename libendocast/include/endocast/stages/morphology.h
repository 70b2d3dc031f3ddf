#pragma once
// Binary morphology with exact Euclidean balls, computed as thresholds of distance transforms
// (so the cost is O(V) for any radius), and the paper's void filling.
//
// Ball of radius r (mm) centred on a voxel: every voxel centre within distance <= r, measured with
// the volume's spacing. Outside the volume counts as background for dilation and as foreground for
// erosion, so closing(A) always contains A.
#include <array>
#include <cstddef>
#include <optional>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

/// The squared radius (mm^2) the ball operations compare squared distances with: r^2 with a
/// relative slack, so that voxels exactly on the sphere are inside despite float rounding.
double ball_squared_radius(double radius_mm);

/// Voxels within r mm of a non-zero voxel (mask ⊕ ball). Output 0/1.
Volume<uint8_t> dilate_ball(const Volume<uint8_t>& mask, double radius_mm);
/// Voxels whose ball of radius r mm lies inside the mask (mask ⊖ ball). Output 0/1.
Volume<uint8_t> erode_ball(const Volume<uint8_t>& mask, double radius_mm);
/// Closing: erode_ball(dilate_ball(mask, r), r). Output 0/1.
Volume<uint8_t> close_ball(const Volume<uint8_t>& mask, double radius_mm);

/// The faces of a volume (-x, +x, -y, +y, -z, +z) beyond which the mask goes on as foreground.
using WalledFaces = std::array<bool, 6>;
/// Closing with the faces in `walls` taken as walls of foreground going on beyond the volume (a
/// scan cropped through the cavity: the crop plane is a wall), so that the ball fills the corners
/// the mask makes with them, and gaps between the mask and such a face narrower than the ball, as
/// it would the mask's own corners; the other faces as in close_ball. Output 0/1.
Volume<uint8_t> close_ball(const Volume<uint8_t>& mask, double radius_mm, const WalledFaces& walls);

struct VoidFillParams {
    double radius_voxels = 6.0;            ///< ball radius in voxels of the smallest spacing (paper: 6)
    std::optional<double> radius_mm;       ///< if set, overrides radius_voxels (mm)
    /// Also keep the bone's dilations by these ball radii (mm, each at most the fill's radius):
    /// read off the fill's own dilation, so they cost no transform (restore_creases' closings).
    std::vector<double> keep_dilations_mm;
};

struct VoidFillResult {
    Volume<uint8_t> bone;                  ///< bone with voids filled (0/1)
    double radius_mm = 0;                  ///< the ball radius used
    size_t filled_voxels = 0;              ///< voxels added (the black-hat)
    /// The bone dilated by each of VoidFillParams::keep_dilations_mm (exactly dilate_ball's voxels).
    std::vector<PackedMask> dilations;
};

/// Fills small voids in bone (diploic space, cracks, small foramina) with the black-hat of a ball:
/// bone ∪ (close_ball(bone, r) \ bone). A radius of 0 returns the bone unchanged.
/// Throws InvalidParameter for a negative or non-finite radius.
VoidFillResult fill_voids(const Volume<uint8_t>& bone, const VoidFillParams& p = {});

/// The radius in mm that VoidFillParams resolves to for the given geometry.
double void_fill_radius_mm(const VoidFillParams& p, const Geometry& g);

}  // namespace endocast
