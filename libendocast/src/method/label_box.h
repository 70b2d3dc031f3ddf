#pragma once
// Bounding box of the voxels carrying one label (internal to the method's steps).
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

/// Voxel index box (inclusive) of the voxels of `labels` equal to `label`; hi[0] < 0 when there
/// is none. Per slice in parallel (min and max: the same box for any thread count).
struct LabelBox {
    std::array<int64_t, 3> lo{0, 0, 0}, hi{-1, -1, -1};
    bool empty() const { return hi[0] < 0; }
};

/// The box of the voxels whose value passes `in` (uint8_t -> bool).
template <class In>
LabelBox box_of(const Volume<uint8_t>& labels, In in) {
    const Dims& d = labels.dims();
    std::vector<LabelBox> slices(static_cast<size_t>(d[2]));
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < d[2]; ++z) {
        LabelBox& b = slices[size_t(z)];
        b.lo = {d[0], d[1], z};
        for (int64_t y = 0; y < d[1]; ++y) {
            const uint8_t* row = labels.data() + labels.index(0, y, z);
            for (int64_t x = 0; x < d[0]; ++x)
                if (in(row[x])) {
                    b.lo = {std::min(b.lo[0], x), std::min(b.lo[1], y), z};
                    b.hi = {std::max(b.hi[0], x), std::max(b.hi[1], y), z};
                }
        }
    }
    LabelBox b;
    b.lo = {d[0], d[1], d[2]};
    for (const LabelBox& s : slices) {
        if (s.empty()) continue;
        for (int a = 0; a < 3; ++a) {
            b.lo[size_t(a)] = std::min(b.lo[size_t(a)], s.lo[size_t(a)]);
            b.hi[size_t(a)] = std::max(b.hi[size_t(a)], s.hi[size_t(a)]);
        }
    }
    return b;
}

inline LabelBox label_box(const Volume<uint8_t>& labels, uint8_t label) {
    return box_of(labels, [label](uint8_t v) { return v == label; });
}

}  // namespace endocast
