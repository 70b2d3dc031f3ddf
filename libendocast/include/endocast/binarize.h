#pragma once
// Stage 1 of the method: bone = CT >= isovalue, keeping the largest bone component.
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
    /// to the isovalue (thin_bone_ridges). 0 disables (CLI --thin-bone 0). On the skull-base
    /// phantoms 0.5 (the default) stops the leaks through the 0.5-1 mm orbital roofs (farthest
    /// vertex outside the truth 11.7 -> 3.5 mm, mean distance 0.19 -> 0.09 mm); on cthead it also
    /// closes the thin walls of the sphenoid sinus, which would then join the braincase (the
    /// pipeline leaves air out of a tissue-filled cavity). Real scans move by 0.2 % or less
    /// (docs/accuracy.md).
    double thin_bone_prominence = 0.5;
};

struct BinarizeResult {
    Volume<uint8_t> bone;                  ///< 1 where CT >= isovalue (largest component)
    double isovalue = 0;                   ///< the value used
    bool isovalue_automatic = false;
    std::string isovalue_rule;             ///< how it was chosen ("given", "otsu-tissue-bone", ...)
    size_t bone_voxels = 0;
    size_t removed_fragment_voxels = 0;    ///< bone voxels dropped with the smaller components
    size_t thin_bone_voxels = 0;           ///< voxels below the isovalue taken as thin bone
};

/// Automatic bone isovalue from the histogram: Otsu's threshold t over all voxels, then Otsu's
/// threshold t' over the voxels above t. When the voxels between t and t' outnumber those above t'
/// twice or more, the scan holds soft tissue and t' (tissue/bone) is used; otherwise (a dry skull:
/// air and bone) t. `rule` receives which was taken. Throws NoResult on a constant volume.
double automatic_isovalue(const Volume<float>& ct, std::string* rule = nullptr);

/// Otsu's threshold of the values of `ct` that are > `above` (all values when above = -inf).
/// Returns a value v such that the classes are (<= v) and (> v). Throws NoResult on fewer than two
/// distinct values.
double otsu_threshold(const Volume<float>& ct, double above);

/// The level of the empty space around the bone (scan units): the median of the soft tissue when
/// the scan holds it (a living head), else of the air (a dry skull), split by Otsu's threshold.
double empty_space_level(const Volume<float>& ct, double isovalue);

/// Marks (sets to 1 in `bone`) the voxels of `ct` below `isovalue` that are ridges of thin bone
/// (BinarizeParams::thin_bone_prominence); returns how many. A plate of bone thinner than the
/// scanner's blur peaks below the isovalue, yet it is a local maximum across its thickness, far
/// above what lies on either side; the slope of a thick wall is not a maximum, nor is noise that
/// prominent. Parallel, deterministic.
size_t thin_bone_ridges(const Volume<float>& ct, double isovalue, double prominence, Volume<uint8_t>& bone);

/// Binarizes. Throws InvalidParameter for a non-finite isovalue, NoResult when no voxel (or every
/// voxel) is >= the isovalue, naming the value and the data range.
BinarizeResult binarize(const Volume<float>& ct, const BinarizeParams& p = {});

}  // namespace endocast
