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
};

struct BinarizeResult {
    Volume<uint8_t> bone;                  ///< 1 where CT >= isovalue (largest component)
    double isovalue = 0;                   ///< the value used
    bool isovalue_automatic = false;
    std::string isovalue_rule;             ///< how it was chosen ("given", "otsu-tissue-bone", ...)
    size_t bone_voxels = 0;
    size_t removed_fragment_voxels = 0;    ///< bone voxels dropped with the smaller components
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

/// Binarizes. Throws InvalidParameter for a non-finite isovalue, NoResult when no voxel (or every
/// voxel) is >= the isovalue, naming the value and the data range.
BinarizeResult binarize(const Volume<float>& ct, const BinarizeParams& p = {});

}  // namespace endocast
