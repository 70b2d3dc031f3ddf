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

namespace box_detail {
constexpr int64_t kChunk = 32;  // voxels tested together (a branch-free loop the compiler vectorizes)
}  // namespace box_detail

/// The first x of row[0..n) whose value passes `in`, n if none: chunks of kChunk tested branch-free,
/// then the chunk with a hit searched.
template <class In>
int64_t first_in(const uint8_t* row, int64_t n, In in) {
    int64_t x = 0;
    for (; x + box_detail::kChunk <= n; x += box_detail::kChunk) {
        uint8_t any = 0;
        for (int64_t k = 0; k < box_detail::kChunk; ++k) any |= uint8_t(in(row[x + k]));
        if (any) break;
    }
    for (; x < n; ++x)
        if (in(row[x])) return x;
    return n;
}

/// The last x of row[0..n) whose value passes `in`, -1 if none.
template <class In>
int64_t last_in(const uint8_t* row, int64_t n, In in) {
    int64_t x = n;
    for (; x - box_detail::kChunk >= 0; x -= box_detail::kChunk) {
        uint8_t any = 0;
        for (int64_t k = 1; k <= box_detail::kChunk; ++k) any |= uint8_t(in(row[x - k]));
        if (any) break;
    }
    for (; x > 0; --x)
        if (in(row[x - 1])) return x - 1;
    return -1;
}

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
            const int64_t first = first_in(row, d[0], in);
            if (first == d[0]) continue;
            const int64_t last = last_in(row, d[0], in);
            b.lo = {std::min(b.lo[0], first), std::min(b.lo[1], y), z};
            b.hi = {std::max(b.hi[0], last), std::max(b.hi[1], y), z};
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
