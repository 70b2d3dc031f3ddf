#pragma once
// Creases of the cavity that the void fill closed, given back to the endocast.
//
// The void fill (morphology.h) closes the bone with a ball of radius r (6 voxels): it fills the
// diploic space and the small foramina, and also every crease of the cavity narrower than 2r (the
// olfactory groove between the orbital roofs, the sella turcica, the angles between the skull
// base's floors and walls). The watershed leaves those to bone, so the mesh rounds them off
// (an inward bias along the skull base, a pocket cut). restore_creases gives back to the endocast
// each connected piece of what the void fill added that is not closed by a smaller ball too (the
// foramina are: a ball of half the void-fill radius, then of a quarter, closes them, so a crease
// and a foramen that opens in its floor come apart), that touches the endocast and nothing else
// that is empty space (no "other", no unlabelled voxel, not the volume border unless the border
// cuts the cavity itself, as in a scan cropped through the base), and that is not
// far deeper than its mouth is wide, or, if it is, whose mouth is wide for its width (a pocket
// whose rim leans over it, like the sella under the dorsum): a pocket of the cavity, not a channel
// out of it nor a chamber behind a gap in its wall.
#include <cstddef>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

struct CreaseParams {
    bool enabled = true;
    /// Ball radii of the closings that keep foramina closed, as fractions of the void fill's
    /// radius, one pass each, largest first (0.5: 3 voxels with the paper's 6): in a pass the void
    /// fill's voxels that closing fills too stay bone, so openings up to ~2 x that radius wide
    /// stay closed and a crease comes apart from a foramen in its floor; a later, smaller ball
    /// gives back the narrower creases (a sella 6 mm wide) that do not touch an opening. Where the
    /// volume's border cuts the cavity it is a wall for these closings too (close_ball with
    /// walled faces): a fissure the border cuts open is closed against it as against bone, so it
    /// does not join a crease beside it to the space beyond (the cropped skull-base phantom's
    /// superior orbital fissure and the sliver along its middle fossa's wall: 2.21 -> 1.05 mm inside).
    std::vector<double> keep_closed_fractions = {0.5, 0.25};
    /// A piece is a crease when its volume over its mouth's area (the mean depth below the mouth,
    /// mm) is at most this multiple of the void fill's radius (2: 12 voxels with the paper's 6);
    /// a deeper one is a chamber behind a gap in the wall and stays bone (docs/method/defaults.md).
    double max_mean_depth_fraction = 2.0;
    /// A deeper piece is still given back (a pocket, not a chamber behind a gap) when its mouth is
    /// at least pocket_mouth_fraction of its widest cross-section (pi r^2, r the radius of the
    /// largest ball inside it) and that ball holds at least pocket_ball_fraction of its volume
    /// (docs/method/defaults.md). Both in [0, 1]; 0 for pocket_mouth_fraction disables.
    double pocket_mouth_fraction = 0.25;
    double pocket_ball_fraction = 0.5;
    /// Then the void fill's voxels left as sheets at most 2 x sheet_voxels - 1 thick with the
    /// endocast on both sides along an axis (a lid's remnant over a pocket given back) are given
    /// back too. 0 disables.
    int sheet_voxels = 2;
    /// A piece that touches both the endocast and other empty space is a hole's plug, and the
    /// ball may have joined to it a crease beside the hole's mouth (the wedge between the petrous
    /// ridge and the internal acoustic meatus). Such a piece is flooded from both sides down the
    /// distance to the bone (as the watershed floods the cavity), other space leading by this many
    /// voxels (of the largest spacing): the endocast gets back what is at least that much wider
    /// than the hole's narrowest cross-section between it and the outside, and the creases below
    /// it, with what the balls inside it cover, when that part is a crease by
    /// max_mean_depth_fraction. The grid's distances along a canal of even width vary by up to
    /// half a voxel's diagonal (0.87 voxel): on the skull-base phantoms a lead of 0.75 leaks 5.6 mm
    /// down the tilted phantoms' oblique foramina lacera, and at 1.25 the wedge stays closed.
    /// 0 disables.
    double plug_lead_voxels = 1.0;
};

struct CreaseResult {
    size_t pieces = 0;            ///< pieces given back
    size_t voxels = 0;            ///< voxels given back (kBone -> kEndocast)
    size_t pieces_kept_closed = 0;  ///< pieces touching the endocast and other empty space
    size_t pieces_too_deep = 0;     ///< pieces deeper below their mouth than max_mean_depth_fraction allows, not pockets
    size_t deep_pockets = 0;        ///< pieces deeper than that given back as pockets (pocket_mouth_fraction)
    size_t sheet_voxels = 0;        ///< the void fill's voxels left as sheets in the endocast, given back
    size_t plugs_split = 0;         ///< plugs whose side toward the endocast was given back (plug_lead_voxels)
    size_t plug_voxels = 0;         ///< voxels of those given back (counted in `voxels` too)
};

/// labels: the watershed's (kEndocast, kOther, kBone, kUnlabelled); bone: the binarized bone
/// before the void fill; filled: after it (0/1, same grid). The pieces given back become kEndocast
/// in `labels` and 0 in `filled`. Works in the endocast's bounding box plus twice the void-fill
/// radius (a piece reaching its edge stays closed); deterministic. Throws InvalidParameter for
/// grids that differ or a fraction outside [0, 1].
CreaseResult restore_creases(Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                             Volume<uint8_t>& filled, double void_radius_mm,
                             const CreaseParams& p = {});

/// The same with the bone's dilations by each keep_closed_fraction x void_radius_mm, in order, on
/// the labels' grid (fill_voids' VoidFillParams::keep_dilations_mm, read off its own transform): a
/// closing then costs one transform (the erosion) instead of two. The same result.
CreaseResult restore_creases(Volume<uint8_t>& labels, const Volume<uint8_t>& bone, Volume<uint8_t>& filled,
                             double void_radius_mm, const CreaseParams& p,
                             const std::vector<PackedMask>& bone_dilations);

}  // namespace endocast
