#pragma once
// Stage 5: watershed by flooding. Labels spread from the seeds down the distance field: the empty
// voxel of largest distance next to a labelled voxel is labelled next (priority flood, Meyer 1991;
// Beucher & Meyer 1993). Ties are broken first-in first-out, so the result is deterministic.
//
// Priorities are distances quantized to `quantum_mm` and kept in a bucket queue (one FIFO per
// quantum): O(V + number of buckets), no log factor. A neighbour whose priority is above the current
// level is processed next (the flood climbs into an unseeded basin it reaches first).
#include <cstddef>

#include "endocast/volume.h"

namespace endocast {

struct WatershedParams {
    Connectivity connectivity = Connectivity::Face6;  ///< neighbourhood of the flood
    double quantum_mm = 0;  ///< priority resolution (mm); 0 = smallest spacing / 64
};

struct WatershedResult {
    Volume<uint8_t> labels;      ///< every empty voxel reachable from a seed gets that seed's label
    size_t endocast_voxels = 0;
    size_t other_voxels = 0;
    size_t unreached_voxels = 0; ///< empty voxels no flood reached (enclosed pockets): kUnlabelled
};

/// Floods `seeds` down `distance` (mm): kBone voxels are walls, kUnlabelled voxels are filled, and
/// every other value is a seed label that spreads (kEndocast, kOther, or any label > kBone, e.g.
/// one per candidate cavity).
/// Throws InvalidParameter when the sizes differ or the connectivity is not 6/18/26.
WatershedResult watershed(const Volume<uint8_t>& seeds, const Volume<float>& distance,
                          const WatershedParams& p = {});
/// The same, the seeds' memory reused for the result (one label volume less at the peak).
WatershedResult watershed(Volume<uint8_t>&& seeds, const Volume<float>& distance, const WatershedParams& p = {});

}  // namespace endocast
