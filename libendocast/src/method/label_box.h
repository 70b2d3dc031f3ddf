#pragma once
// Bounding box of the voxels carrying one label (internal to the method's steps).
#include <algorithm>
#include <array>
#include <cstdint>

#include "endocast/volume.h"

namespace endocast {

/// Voxel index box (inclusive) of the voxels of `labels` equal to `label`; hi[0] < 0 when there
/// is none. Serial, in scan order.
struct LabelBox {
    std::array<int64_t, 3> lo{0, 0, 0}, hi{-1, -1, -1};
    bool empty() const { return hi[0] < 0; }
};

inline LabelBox label_box(const Volume<uint8_t>& labels, uint8_t label) {
    const Dims& d = labels.dims();
    LabelBox b;
    b.lo = {d[0], d[1], d[2]};
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x)
                if (labels(x, y, z) == label) {
                    b.lo = {std::min(b.lo[0], x), std::min(b.lo[1], y), std::min(b.lo[2], z)};
                    b.hi = {std::max(b.hi[0], x), std::max(b.hi[1], y), std::max(b.hi[2], z)};
                }
    return b;
}

}  // namespace endocast
