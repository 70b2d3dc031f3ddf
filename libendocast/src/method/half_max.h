#pragma once
// The half-maximum-height surface of polygonize() (SurfaceMode::HalfMax, marching_cubes.h).
#include <array>
#include <cstdint>

#include "endocast/stages/polygonize.h"
#include "endocast/volume.h"

namespace endocast {

/// Re-classifies the band around the region r.mask (E, already the largest component with holes
/// filled; its voxels lie in the box [lo, hi]) by local half-maximum thresholds and returns the field
/// to mesh at level 0 (CT - tau). Sets r.mask, r.mask_voxels, r.other_value and r.half_max.
/// `region_median` is the median CT of E (the cavity level when E has no core).
Volume<float> half_max_field(const Volume<float>& ct, const Volume<uint8_t>& labels,
                             const PolygonizeParams& p, double region_median,
                             const std::array<int64_t, 3>& lo, const std::array<int64_t, 3>& hi,
                             PolygonizeResult& r);

}  // namespace endocast
