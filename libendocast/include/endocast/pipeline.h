#pragma once
// The whole method: binarize -> fill voids -> distance transform -> seeds -> watershed -> polygonize.
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "endocast/stages/binarize.h"
#include "endocast/stages/bone_contact.h"
#include "endocast/stages/creases.h"
#include "endocast/stages/dips.h"
#include "endocast/stages/handles.h"
#include "endocast/stages/polygonize.h"
#include "endocast/stages/morphology.h"
#include "endocast/stages/resample.h"
#include "endocast/stages/openings.h"
#include "endocast/stages/seeds.h"
#include "endocast/volume.h"
#include "endocast/stages/watershed.h"
#include "meshpost/mesh.h"
#include "meshpost/topology.h"

namespace endocast {

/// Called at the start of each stage with its name ("binarize", "void_fill", "distance", "seeds",
/// "watershed", "openings" (when enabled), "polygonize").
using ProgressCallback = std::function<void(const std::string& stage)>;

/// A plane that closes an opening: every empty voxel on the side the normal points to is "other".
struct CutPlane {
    Vec3 point{0, 0, 0};    ///< a point of the plane, world mm
    Vec3 normal{0, 0, -1};  ///< points away from the braincase (need not be unit length)
};

struct ExtractParams {
    BinarizeParams binarize;
    VoidFillParams void_fill;
    SeedParams seeds;
    WatershedParams watershed;
    /// Give back to the endocast the creases of the cavity that the void fill closed (creases.h).
    CreaseParams creases;
    /// With close_openings: closing surfaces that dip into a hole the void fill plugged are made
    /// flush with its rim (dips.h).
    DipParams dips;
    std::vector<CutPlane> cut_planes;   ///< user cuts, applied to the seeds before the flood
    /// Move the boundary from where the floods meet to the rims of openings (openings.h).
    bool close_openings = true;
    OpeningParams openings;
    /// With close_openings: cut each handle of the endocast region where it is narrowest
    /// (handles.h), so that the mesh has genus 0 like a braincase.
    bool close_handles = true;
    /// A braincase is enclosed by bone: when less than this fraction of the faces between the
    /// endocast and the rest are bone faces, a warning is given (a braincase scores > 0.9).
    double min_enclosure = 0.6;
    /// NoResult (exit 5) unless the chosen cavity holds at least this many voxels and, of its
    /// boundary faces away from the volume border, at least min_enclosure are bone faces.
    size_t min_cavity_voxels = 1000;
    /// Bone contact of the mesh (bone_contact.h, with the segmentation's labels: the skull's thin
    /// bone and filled voids count as bone): when less than this share of its area lies on bone,
    /// a warning is given (a braincase scores > 0.9; caps across openings and leaks lower it).
    double min_bone_contact = 0.85;
    /// offset_mm 0 (the default here): max(smallest spacing, depth / 50), the depth being the
    /// cavity's (ExtractionResult::max_distance_mm).
    BoneContactParams bone_contact = {0.0};
    /// The share of the surface facing other empty space (not bone, not the cap of an opening the
    /// closure cut) above which a leak is warned of (ExtractionResult::leak_share).
    double max_leak_share = 0.14;
    /// Iso: the isosurface at T; HalfMax: the half-maximum-height surface (marching_cubes.h).
    SurfaceMode surface = SurfaceMode::Iso;
    ProgressCallback progress;       ///< optional
    /// Keep the final label volume in ExtractionResult::labels (the coarse-to-fine path, refine.h).
    bool keep_labels = false;
    /// Keep ExtractionResult::mask (false: left empty, for a caller that writes no mask or picture).
    bool keep_mask = true;
    /// Run the stages after binarize on the bone's box (bone_work_box: the bone's bounding box
    /// grown by a margin of empty space) instead of the whole volume: the same cavity in less time
    /// and memory when air surrounds the skull. False: the whole volume (the method as written).
    bool bone_box = true;
};

/// Wall-clock seconds per stage.
struct StageTimings {
    double binarize = 0, void_fill = 0, distance = 0, seeds = 0, watershed = 0, openings = 0,
           polygonize = 0, dips = 0, bone_contact = 0, total = 0;
};

/// The concrete values an extraction runs with, resolved once from the user's parameters and the
/// volume (resolve()); the stages take these, and the result and the report carry them.
struct ResolvedParams {
    double isovalue = 0;             ///< bone isovalue T (scan units)
    bool isovalue_automatic = false;
    std::string isovalue_rule;       ///< "given", "otsu-tissue-bone", ... (automatic_isovalue)
    /// Automatic: the threshold of the rule not taken (automatic_isovalue's `other`); else NaN.
    double isovalue_other = std::numeric_limits<double>::quiet_NaN();
    /// Automatic: how clearly the rule was decided (automatic_isovalue's `margin`, >= 1); else NaN.
    double isovalue_margin = std::numeric_limits<double>::quiet_NaN();
    double smallest_spacing_mm = 0;  ///< "voxels" of lengths below are of this size
    double void_radius_mm = 0;       ///< the void fill's ball radius
    double void_radius_voxels = 0;   ///< the same in voxels of the smallest spacing
    double thin_bone_prominence = 0; ///< 0 = off
    SeedMode seed_mode = SeedMode::Auto;
    double seed_scale = 0;
    SurfaceMode surface = SurfaceMode::Iso;
};

/// Resolves `p` on `ct`: the isovalue (automatic when unset: automatic_isovalue), the void fill's
/// radius in mm and voxels, the seed mode and scale, the surface. Throws InvalidParameter for a
/// non-finite isovalue, a negative or non-finite void radius or a seed scale outside (0, 1), and
/// NoResult when no isovalue can be chosen automatically.
template <class T>
ResolvedParams resolve(const Volume<T>& ct, const ExtractParams& p);

struct ExtractionResult {
    meshpost::TriangleMesh mesh;     ///< closed, outward, world mm
    Volume<uint8_t> mask;            ///< 1 = endocast, input geometry (empty: ExtractParams::keep_mask false)
    /// With ExtractParams::keep_labels: the final labels (kEndocast, kOther, kBone = bone after
    /// the void fill, kUnlabelled), input geometry; else empty.
    Volume<uint8_t> labels;
    ResolvedParams params;           ///< what the method ran with (resolve())
    size_t void_filled_voxels = 0;
    size_t bone_voxels = 0;
    size_t bone_fragments_removed_voxels = 0;
    size_t thin_bone_voxels = 0;     ///< voxels below the isovalue taken as thin bone (binarize)
    /// Of those, the ones given back to the endocast: the cavity on both sides and around them
    /// (return_thin_bone_tips).
    size_t thin_bone_tips_returned = 0;
    /// With thin bone: cavity voxels of air (and within 2 voxels of it) dropped from a tissue-filled
    /// cavity (a sinus whose thin walls closed, joined through a gap).
    size_t air_excluded_voxels = 0;
    double border_seed_scale = 0;        ///< scale of the border seed balls used (see SeedParams)
    std::vector<Vec3> endocast_seeds_world;
    std::vector<double> endocast_seed_radii_mm;
    double max_distance_mm = 0;      ///< d at the endocast seed
    size_t watershed_unreached_voxels = 0;
    /// The watershed resumed the seeds' candidate flood (SeedParams::keep_flood) instead of
    /// flooding the whole volume again (SeedMode::Auto, no cut planes, default watershed).
    bool watershed_resumed = false;
    CreaseResult creases;            ///< creases given back to the endocast (restore_creases)
    DipResult dips;                  ///< closing surfaces made flush with their rims (flush_dips)
    std::vector<CavityCandidate> candidates;  ///< SeedMode::Auto: the cavities examined
    size_t cut_voxels = 0;           ///< empty voxels set to "other" by the cut planes
    OpeningsResult openings;         ///< openings closed at their rims
    HandleClosing handles;           ///< handles of the region cut (close_handles)
    double enclosure = 0;            ///< fraction of the endocast's boundary faces that are bone
    /// Area (mm^2) of the endocast region's voxel faces on the volume border (0: the volume holds
    /// the whole cavity; otherwise the mesh is closed flat there and the ECV is a lower bound).
    double border_contact_mm2 = 0;
    std::vector<Warning> warnings;   ///< things a careful user should look at (errors.h)
    double other_value = 0;          ///< value that non-endocast voxels were raised to
    HalfMaxInfo half_max;            ///< SurfaceMode::HalfMax only
    double mask_volume_ml = 0;       ///< voxel count x voxel volume
    double ecv_ml = 0;               ///< from the closed mesh
    double surface_area_mm2 = 0;
    /// Share of the mesh's area lying on bone, in [0, 1] (bone_contact.h: the CT
    /// bone_contact_offset_mm outside each face >= isovalue, or a voxel labelled bone there);
    /// below min_bone_contact a warning is given.
    double bone_contact = 0;
    double bone_contact_offset_mm = 0;  ///< the probe's distance used
    std::vector<uint8_t> face_on_bone;  ///< per face of `mesh`: 1 = on bone (for the QC picture)
    /// Per face of `mesh`: 1 = on bone by the CT alone (the closing surfaces: the dips, the
    /// openings' list, the coarse-to-fine path's clip).
    std::vector<uint8_t> face_on_bone_ct;
    /// Share of the mesh's area whose outside (a voxel out) is other empty space, the caps of the
    /// openings the closure cut left out: where the surface leaves the braincase through a gap
    /// into the nasal cavity, an orbit or a canal. Above max_leak_share a warning is given.
    double leak_share = 0;
    std::vector<uint8_t> face_leaks;    ///< per face of `mesh`: 1 = counted in leak_share
    /// meshpost::analyze_topology(mesh), when the dips ran (their loop is sequential: the faces'
    /// analysis runs beside it, on a core that would be idle); unset otherwise.
    std::optional<meshpost::TopologyReport> topology;
    /// With ExtractParams::bone_box: the box of the input's voxels the stages after binarize ran on
    /// (unset: the whole volume). `mask` and `labels` are on the input's grid either way.
    std::optional<CropBox> work_box;
    StageTimings timings_s;
};

/// A length the method used, in mm, with the rule that derived it (docs/lengths.md): every one
/// follows the cavity's depth (ExtractionResult::max_distance_mm, its largest inscribed ball) or
/// the voxel (the grid's smallest spacing), so a mouse at 35 um and a human at 1 mm get the same
/// method.
struct DerivedLength {
    std::string name;   ///< report key (lengths_mm.NAME)
    double mm = 0;
    std::string rule;   ///< e.g. "0.3 x depth"
};

/// The lengths `r` was extracted with under `p` (in report order).
std::vector<DerivedLength> derived_lengths(const ExtractParams& p, const ExtractionResult& r);

/// The box the stages after binarize run on: the bounding box of `bone` (binarize's, after its
/// fragments are removed) grown on each axis a by ceil(2 r / spacing[a]) + 2 voxels (r =
/// `void_radius_mm`), clamped to the volume. The void fill's closing (a ball of radius r) then
/// gives the same voxels as on the whole volume; every voxel outside the box is empty space joined
/// to the border, so the distance to bone is the same in it and the outside seeds stand on its
/// faces. Unset when the box is the whole volume or there is no bone.
std::optional<CropBox> bone_work_box(const Volume<uint8_t>& bone, double void_radius_mm);

/// Sets to kOther every non-bone voxel on the positive side of any plane; returns how many changed.
/// Throws InvalidParameter for a zero normal.
size_t apply_cut_planes(Volume<uint8_t>& labels, const std::vector<CutPlane>& planes);

/// The faces between kEndocast voxels and the rest: toward kBone, toward other labels, and on the
/// volume border (with their area, mm^2).
struct EnclosureFaces {
    size_t bone = 0, other = 0, border = 0;
    double border_area_mm2 = 0;
};
EnclosureFaces enclosure_faces(const Volume<uint8_t>& labels);

/// Fraction of the faces between kEndocast voxels and other voxels (or the volume border) that
/// face kBone voxels. 0 when there is no endocast voxel.
double enclosure_by_bone(const Volume<uint8_t>& labels);

/// Runs the method on a CT volume: float, or int16 for an integer-valued scan (exact_int16 in
/// volume.h: the same result in half the memory). Throws InvalidParameter / NoResult (see the stages).
template <class T>
ExtractionResult extract_endocast(const Volume<T>& ct, const ExtractParams& p = {});

/// The same, taking the CT over: once the stages after binarize have their copy of the bone's box
/// (ExtractionResult::work_box), the rest of the volume is released (peak memory).
template <class T>
ExtractionResult extract_endocast(Volume<T>&& ct, const ExtractParams& p = {});

}  // namespace endocast
