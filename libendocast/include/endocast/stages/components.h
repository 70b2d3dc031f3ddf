#pragma once
// Connected components of binary masks (breadth-first labelling in scan order: deterministic).
#include <cstdint>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

struct Components {
    std::vector<uint32_t> labels;   ///< per voxel: 0 = not in the mask, k >= 1 = component k
    std::vector<size_t> sizes;      ///< sizes[k-1] = voxels of component k (numbered in scan order)
    std::vector<bool> touches_border;  ///< component k-1 has a voxel on a face of the volume
};

/// Labels the components of the non-zero voxels of `mask`.
Components connected_components(const Volume<uint8_t>& mask, Connectivity c);

/// Keeps only the largest component (ties: the first in scan order). Returns the number of voxels
/// removed. A mask without non-zero voxels is left unchanged.
size_t keep_largest_component(Volume<uint8_t>& mask, Connectivity c);

/// Keeps only the component holding voxel `index` (every voxel of `mask` becomes 0 or 1); when
/// that voxel is zero (or `index` lies outside the volume) the whole mask becomes 0. Needs no
/// per-voxel label volume. Returns the number of voxels kept.
size_t keep_component_at(Volume<uint8_t>& mask, size_t index, Connectivity c);

/// Sets to 1 every zero voxel of `mask` not connected (with connectivity c) to the volume's faces
/// through zero voxels: fills enclosed holes. Returns the number of voxels filled.
size_t fill_holes(Volume<uint8_t>& mask, Connectivity c);

/// Neighbour offsets (dx, dy, dz) for a connectivity, in a fixed order.
std::vector<std::array<int, 3>> neighbour_offsets(Connectivity c);

}  // namespace endocast
