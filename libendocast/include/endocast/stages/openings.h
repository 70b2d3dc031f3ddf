#pragma once
// Closing the openings of the braincase at their rim (foramen magnum, optic canals, ...).
//
// The watershed stops the endocast wherever its flood meets the outside flood; in a canal of
// constant width (the spinal canal) that can be anywhere along it. This stage moves the boundary to
// the opening itself:
//  1. core: the part of the endocast region E that balls of radius R (a fraction of the cavity's
//     depth) reach without touching bone: E minus close_ball(bone, R), the component of the deepest
//     point. Balls that large cannot pass an opening narrower than R; they dip into it by at most
//     R - sqrt(R^2 - a^2) for an opening of radius a.
//  2. openings: the components of the far part of E (more than tau = far_voxels from the core)
//     that touch space outside E or the volume border, or that reach deeper than
//     canal_reach_fraction x R from the core (a canal sealed by tissue above the isovalue). The thin layer between the core and a bumpy
//     wall is nearer than tau and stays; so do deep corners that touch only bone. Of those within
//     the reach, only tubes are openings (max_tubeness: a canal, a hole's channel); a pocket of
//     the skull base below the core's balls (a middle cranial fossa with foramina in its floor)
//     holds 3-8 times a tube's volume and stays whole: the watershed already ends it at its holes.
//  3. for each opening, a plane is fitted (least squares) to its rim: the core voxels on the inner
//     skull surface (26-adjacent to bone) within tau + 2 voxels of the opening, a ring around the
//     hole. Every endocast voxel beyond the plane that belongs to the opening, or lies within the
//     rim's radius of its centre (and less than R beyond the plane), becomes "other"; the rest
//     stays endocast. The mesh then closes with a flat cap across the hole. An opening with too
//     small a rim is removed whole; specks under min_opening_voxels are dropped and not listed.
//  4. (in the pipeline, after meshing) where the surface has a handle next to an opening, its
//     collar is cut too (cut_collar) and kept only if the handle goes away.
//
// R is 0.3 x the cavity's depth by default: larger than the canals beyond the openings and than the
// foramen magnum, small enough that the core reaches into the cavity's corners (the measurements:
// docs/method/defaults.md).
//
// A second look with balls of R2 = wide_radius_fraction x depth (larger than R) finds the canals
// as wide as R, which the first core runs through and so never sees: a rodent's spinal canal is
// about a third of its braincase's depth wide (a human's about a sixth), so at R its core reaches
// down the canal to wherever the floods met. In the second look a far part is an opening only when
// it is a canal: it reaches farther than canal_reach_fraction x R2 from the second core (sealed),
// or it touches other empty space and is at least as wide as the first look's balls (a canal the
// first core ran through): through a section that wide (a voxel touching the outside R or more
// from bone), or with its deepest voxel R or more from bone and reaching at least twice that
// depth from the second core (longer than wide); and it is a tube, not deeper than 1.15 times its
// mouth (where it meets the second core: a chamber behind a narrower mouth, as a rodent's
// olfactory bulbs behind their junction with the cerebrum, stays). Corners and pockets beyond
// the second core stay: it only cuts canals.
#include <array>
#include <cstddef>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

struct OpeningParams {
    double radius_fraction = 0.3;   ///< R = radius_fraction * depth of the cavity (mm)
    double radius_mm = 0;           ///< if > 0, R in mm (overrides the fraction)
    double far_voxels = 2.0;        ///< tau: E voxels farther than this from the core (voxels of the
                                    ///< smallest spacing) form the candidate openings
    size_t min_rim_voxels = 6;      ///< fewer rim voxels: the whole opening becomes "other"
    size_t min_opening_voxels = 27; ///< smaller openings are dropped whole, not listed
    /// A far component reaching farther than this x R from the core is an opening even when it
    /// touches only bone: a canal sealed below by tissue above the isovalue. Corners of the cavity
    /// reach a few mm. 0 disables.
    double canal_reach_fraction = 1.5;
    /// A far part touching the outside is an opening only when its volume is at most this many
    /// times that of a tube as wide as its deepest voxel and as long as its reach from the core
    /// (a canal: ~1); a pocket or sheet of the skull base below the core's balls holds 3-8 times
    /// more and stays (its foramina are where the watershed ends it). 0 disables.
    double max_tubeness = 2.0;
    /// Collar (see cut_collar), in voxels of the largest spacing; 0 disables.
    double collar_width_voxels = 2.0;
    /// The second look's ball radius R2 = wide_radius_fraction x depth (see above); 0 disables it,
    /// and so does an explicit radius_mm (the user's R is the only one).
    double wide_radius_fraction = 0.5;
};

struct Opening {
    Vec3 centre_world{0, 0, 0};     ///< centre of the rim (mm)
    Vec3 normal{0, 0, 0};           ///< unit, pointing out of the braincase
    double radius_mm = 0;           ///< largest distance of a rim voxel from the centre
    double area_mm2 = 0;            ///< area of the closing surface across the opening (mm^2)
    size_t voxels_removed = 0;      ///< endocast voxels that became "other" (collar included)
    size_t collar_voxels = 0;       ///< of which by cut_collar
    bool plane_fitted = false;      ///< false: too small a rim, removed whole
    bool wide = false;              ///< found by the second look (a canal as wide as R)
    /// true: an opening cut by close_openings; false: a closing surface the watershed left (a
    /// foramen of a pocket, a thin-bone gap: the patch of the mesh not on bone; centre, normal,
    /// area from that patch, radius_mm that of a disk of its area).
    bool cut = true;
};

struct OpeningsResult {
    double radius_mm = 0;           ///< R used
    double wide_radius_mm = 0;      ///< R2 of the second look (0: not run)
    size_t core_voxels = 0;
    size_t corner_voxels = 0;       ///< endocast voxels outside the core (wall layer, corners)
    size_t small_openings_voxels = 0;  ///< voxels of specks touching the outside, dropped
    std::vector<Opening> openings;
};

/// Moves the endocast boundary to the rims of the openings (see above). `labels` holds the
/// watershed result (kEndocast, kOther, kBone, kUnlabelled); `bone` the bone after void filling;
/// `distance` the distance to bone (mm). Deterministic.
OpeningsResult close_openings(Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                              const Volume<float>& distance, const OpeningParams& p = {});

/// All close_openings needs of the distance to bone: the endocast's (kEndocast voxels') bounding
/// box and its deepest voxel, and (with the parameters) where the closing's balls fit.
struct EndocastExtent {
    float depth = -1;                   ///< largest distance (mm) of an endocast voxel from bone
    size_t deepest = 0;                 ///< index of that voxel (the first in scan order)
    std::array<int64_t, 3> lo{0, 0, 0}; ///< bounding box, voxel indices, inclusive
    std::array<int64_t, 3> hi{-1, -1, -1};  ///< hi < lo: no endocast voxel
    /// Over close_openings' sub-volume (the box grown by 2R): the voxels farther than R from bone,
    /// i.e. the centres of the balls of radius R that fit in the empty space. The voxels outside
    /// the closing of the bone by that ball are those within R of one of them, so close_openings
    /// needs one transform instead of two. Empty unless endocast_extent was given the parameters.
    Volume<uint8_t> ball_centres;
    /// The same for the second look's radius R2, over its own (larger) sub-volume; empty when the
    /// second look is off.
    Volume<uint8_t> wide_ball_centres;
    /// Over the endocast's bounding box (lo..hi): the distance to bone (mm), for the tube test and
    /// close_handles (empty unless endocast_extent was given the parameters), and the index in the
    /// full volume of its voxel (0, 0, 0) (= lo). Every voxel the later steps ask it of lies in the
    /// box: the far parts are endocast; a voxel the creases or the thin bone's tips give back
    /// outside it was bone (distance 0, what close_handles takes outside the box).
    Volume<float> sub_distance;
    std::array<int64_t, 3> sub_first{0, 0, 0};
};
EndocastExtent endocast_extent(const Volume<uint8_t>& labels, const Volume<float>& distance);
/// The same, and ball_centres (and wide_ball_centres) for close_openings with parameters p.
EndocastExtent endocast_extent(const Volume<uint8_t>& labels, const Volume<float>& distance,
                               const OpeningParams& p);

/// close_openings with the extent computed beforehand (so that the caller can release the
/// distance volume first): the same result as the overload above.
OpeningsResult close_openings(Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                              const EndocastExtent& extent, const OpeningParams& p = {});

/// The collar of a fitted opening: endocast voxels beyond its plane by at most
/// p.collar_width_voxels voxels (of the largest spacing) and at most as far outside the rim's
/// cylinder (radius_mm + one voxel), joined through such voxels to the cut (the "other" voxels of
/// the cylinder just beyond the plane). Where the wall flares into a funnel around the hole the
/// collar is a ring around the canal: a handle on the surface (the human-full phantom tilted 30 deg,
/// left optic canal). They become "other"; returns their indices in `labels` (to undo). The pipeline
/// calls it only where the mesh has a handle near the opening: a collar is cavity elsewhere.
std::vector<size_t> cut_collar(Volume<uint8_t>& labels, const Opening& op, const OpeningParams& p);

}  // namespace endocast
