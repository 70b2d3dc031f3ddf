#pragma once
// Stage 1 of the method: bone = CT >= isovalue, keeping the largest bone component. The CT is a
// Volume<float> or a Volume<int16_t> (an integer-valued scan kept in half the memory; its samples
// are compared as floats, so both give the same result).
#include <cstddef>
#include <optional>
#include <string>

#include "endocast/volume.h"

namespace endocast {

struct BinarizeParams {
    std::optional<double> isovalue;        ///< in the scan's units; unset = automatic (histogram)
    bool keep_largest_component = true;    ///< drop bone fragments not connected to the skull
    Connectivity connectivity = Connectivity::Vertex26;  ///< for the bone components
    /// Thin bone (an orbital roof, the cribriform plate, 0.5-1 mm) blurs below the isovalue: a voxel
    /// below it is bone too when it is a ridge of the CT along an axis (not below either neighbour)
    /// that rises above the higher of the two values two voxels away (itself below the midpoint of
    /// the isovalue and empty_space_level) by at least this fraction of the way from that value up
    /// to the isovalue (thin_bone_ridges). In [0, 1]; 0 disables (CLI --thin-bone 0). Why 0.5:
    /// docs/method/defaults.md.
    double thin_bone_prominence = 0.5;
    /// With thin bone: give back to the endocast, once the segmentation is done, the thin-bone voxels
    /// with the cavity on both sides and around them (return_thin_bone_tips; the pipeline runs it).
    /// On the skull-base phantoms the false plate at the sella's rim cut 2.09 mm (dry) and 2.74 mm
    /// (dry, tilted 25 degrees) into the cavity: 1.72 and 1.99 with it.
    bool thin_bone_tips = true;
};

struct BinarizeResult {
    Volume<uint8_t> bone;                  ///< 1 where CT >= isovalue (largest component)
    double isovalue = 0;                   ///< the value used
    bool isovalue_automatic = false;
    std::string isovalue_rule;             ///< how it was chosen ("given", "otsu-tissue-bone", ...)
    size_t bone_voxels = 0;
    size_t removed_fragment_voxels = 0;    ///< bone voxels dropped with the smaller components
    size_t thin_bone_voxels = 0;           ///< voxels below the isovalue taken as thin bone
    /// The level both sides of a thin plate lie below (thin_bone_side_limit); 0 when thin bone is off.
    double thin_bone_side_limit = 0;
    /// Otsu's threshold over all voxels (air / the rest), computed for the side limit; 0 when thin
    /// bone is off. The pipeline's air exclusion reuses it.
    double air_threshold = 0;
};

/// Automatic bone isovalue from the histogram: Otsu's threshold t over all voxels, then Otsu's
/// threshold t' over the voxels above t. The rules, in order (`rule` receives the name):
///  - "otsu-tissue-bone": t' (soft tissue/bone), when the voxels between t and t' outnumber those
///    above t' twice or more and form a class of their own: a peak (the highest interior group of
///    about 32 between t and t', smoothed over three, at least twice the higher one next to the
///    ends). A living head: air below t, soft tissue between, bone above t'.
///  - "otsu-tissue-near-air": t, when instead the voxels below t hold two classes, air and soft
///    tissue near it (parted by Otsu's threshold t0 of the voxels <= t, with a valley below half
///    the lower of their modes between them), and those in (t0, t] outnumber the voxels above t
///    twice or more. Small-animal microCT: soft tissue close to air against bright bone, while the
///    voxels between t and t' are the falling tail of thin bone's partial volumes, not a class (t'
///    there lies where thin bone vanishes).
///  - "otsu-air-bone": t otherwise (a dry skull: air and bone).
///  - "otsu": t, when nothing above t can be split.
/// `other` receives the threshold not taken (t or t'; NaN for "otsu"); `margin` the smallest factor
/// by which a test deciding the rule cleared its bound (>= 1; near 1 the rule could have gone the
/// other way on a similar scan; NaN for "otsu"). Throws NoResult on a constant volume.
template <class T>
double automatic_isovalue(const Volume<T>& ct, std::string* rule = nullptr, double* other = nullptr,
                          double* margin = nullptr);

/// Otsu's threshold of the values of `ct` that are > `above` (all values when above = -inf).
/// Returns a value v such that the classes are (<= v) and (> v). Throws NoResult on fewer than two
/// distinct values.
template <class T>
double otsu_threshold(const Volume<T>& ct, double above);

/// The level of the empty space around the bone (scan units): the median of the soft tissue when
/// the scan holds it (a living head), else of the air (a dry skull), split by Otsu's threshold.
template <class T>
double empty_space_level(const Volume<T>& ct, double isovalue);

/// Marks (sets to 1 in `bone`) the voxels of `ct` below `isovalue` that are ridges of thin bone
/// (BinarizeParams::thin_bone_prominence); returns how many. A plate of bone thinner than the
/// scanner's blur peaks below the isovalue, yet it is a local maximum across its thickness, far
/// above what lies on either side; the slope of a thick wall is not a maximum, nor is noise that
/// prominent. Parallel, deterministic.
template <class T>
size_t thin_bone_ridges(const Volume<T>& ct, double isovalue, double prominence, Volume<uint8_t>& bone);

/// The level under which both sides of a thin plate lie: the midpoint between the isovalue and
/// empty_space_level (a voxel on the slope of a thick wall, seen along the wall, has neighbours
/// just below the isovalue: not a plate).
template <class T>
double thin_bone_side_limit(const Volume<T>& ct, double isovalue);
/// empty_space_level with Otsu's threshold over all voxels already known (`air_threshold`).
template <class T>
double empty_space_level(const Volume<T>& ct, double isovalue, double air_threshold);

/// Gives back to the endocast (kEndocast) the thin-bone voxels that are not bone: the ridge
/// thin_bone_ridges reads past the tip of a bony lip (the sella's rim, where the floor over the
/// fossa and the wall of the sella below meet in a thin wedge). The blur carries the wedge's ridge
/// a voxel or two beyond its tip, so that voxel is a ridge across the wedge's plane like a plate's;
/// but a plate parts two spaces, and there the cavity lies on both sides and wraps around it. A
/// voxel goes back when it is not the endocast, lies below `isovalue`, is a thin-bone ridge along an
/// axis (`prominence`, `side_limit` as thin_bone_ridges) whose two neighbours along that axis are
/// the endocast, and one of its 8 neighbours across that axis has the endocast on both sides too
/// and is the endocast itself (the cavity meets around it within a voxel). A plate between the
/// cavity and an orbit, or one as wide as the section, keeps every voxel; a free edge of a plate
/// inside the cavity (the dorsum sellae's top) gives back its last voxel. One pass over the labels
/// as they are (a voxel given back does not free its neighbours). Run once the segmentation is
/// done; the pipeline runs it after the creases and before the handles (the false plate can bridge
/// a lip to bone across the cavity, a handle that would be cut through the cavity). Parallel,
/// deterministic. Returns how many.
template <class T>
size_t return_thin_bone_tips(Volume<uint8_t>& labels, const Volume<T>& ct, double isovalue, double prominence,
                             double side_limit);

/// Binarizes. Throws InvalidParameter for a non-finite isovalue, NoResult when no voxel (or every
/// voxel) is >= the isovalue, naming the value and the data range.
template <class T>
BinarizeResult binarize(const Volume<T>& ct, const BinarizeParams& p = {});

}  // namespace endocast
