#pragma once
// Stage 5: watershed by flooding. Labels spread from the seeds down the distance field: the empty
// voxel of largest distance next to a labelled voxel is labelled next (priority flood, Meyer 1991;
// Beucher & Meyer 1993). Ties are broken first-in first-out, so the result is deterministic.
//
// Priorities are distances quantized to `quantum_mm` and kept in a bucket queue (one FIFO per
// quantum): O(V + number of buckets), no log factor. A neighbour whose priority is above the current
// level is processed next (the flood climbs into an unseeded basin it reaches first).
#include <algorithm>
#include <cstddef>
#include <cmath>
#include <cstdint>
#include <vector>

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

/// The levels a flood reached its voxels at: per voxel, the lowest priority (distance quantum) on
/// the path the flood took to it from its seed, a seed's own.
/// In the flood of a subset of the seeds, a voxel whose seed is kept keeps its label (the path that
/// brought it is still there, and no other got higher), up to ties within a quantum; the voxels of
/// the seeds taken away are flooded from their neighbours, each passing its label on at the level
/// it was reached at (resume_watershed): the watershed of the new seeds without flooding again.
struct FloodLevels {
    /// Per voxel, x fastest; written only where a resumed flood reads it: every voxel the flood
    /// reached from a neighbour and every seed it queued (a seed of the resumed flood is set to its
    /// own level by its caller); the others are left uninitialised.
    VoxelBuffer<uint16_t> level;
    double quantum_mm = 0;        ///< the flood's quantum
    size_t levels = 0;            ///< the flood's number of levels
    bool empty() const { return level.empty(); }
};
/// The priority a flood gives a voxel at distance d (mm): its quantum, the top one when not finite.
inline size_t flood_level(float d, double quantum_mm, size_t levels) {
    if (!std::isfinite(d)) return levels - 1;
    return std::min(levels - 1, size_t(double(d) / quantum_mm));
}
/// Floods with more levels than this record none (a distance beyond 1023 x 64 quanta).
constexpr size_t kMaxFloodLevels = 65535;

/// The watershed, its flood levels recorded in `levels` (left empty beyond kMaxFloodLevels).
WatershedResult watershed(Volume<uint8_t>&& seeds, const Volume<float>& distance, const WatershedParams& p,
                          FloodLevels& levels);

/// Resumes a flood: the kUnlabelled voxels of `labels` (a flood's result with some labels taken
/// away, and new seeds set, their levels their own) are flooded from the labelled voxels beside
/// them, each starting at its level in `levels` (the flood's, same params and distances), highest
/// first, then as watershed() floods. Throws InvalidParameter when the levels do not fit.
WatershedResult resume_watershed(Volume<uint8_t>&& labels, const FloodLevels& levels, const Volume<float>& distance,
                                 const WatershedParams& p = {});

}  // namespace endocast
