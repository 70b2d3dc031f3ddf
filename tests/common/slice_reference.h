#pragma once
// A brute-force reference for real-scan tests, independent of the pipeline: the braincase's
// cross-section in one axial slice where bone closes it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "endocast/volume.h"

namespace test_reference {

/// Pixels of slice z with CT < iso, after a 2-D closing of the bone (CT >= iso) with a square of
/// half-width `radius` pixels (closes gaps up to 2 radius wide), that are not 4-connected to the
/// slice's border: returns the mask of the largest such region and its pixel count.
inline std::pair<std::vector<uint8_t>, size_t> enclosed_region_2d(const endocast::Volume<float>& ct,
                                                                  int64_t z, float iso, int radius) {
    const int64_t nx = ct.nx(), ny = ct.ny(), n = nx * ny;
    std::vector<uint8_t> bone(static_cast<size_t>(n)), tmp(bone.size()), closed(bone.size());
    for (int64_t i = 0; i < n; ++i) bone[size_t(i)] = ct(i % nx, i / nx, z) >= iso;
    // Separable square dilation (max) or erosion (min) along x then y; outside counts as not bone.
    auto filter = [&](const std::vector<uint8_t>& in, std::vector<uint8_t>& out, bool dilate) {
        for (int pass = 0; pass < 2; ++pass) {
            const std::vector<uint8_t>& src = pass == 0 ? in : tmp;
            std::vector<uint8_t>& dst = pass == 0 ? tmp : out;
            for (int64_t y = 0; y < ny; ++y)
                for (int64_t x = 0; x < nx; ++x) {
                    bool hit = !dilate;
                    for (int d = -radius; d <= radius; ++d) {
                        const int64_t X = pass == 0 ? x + d : x, Y = pass == 0 ? y : y + d;
                        const bool b = X >= 0 && Y >= 0 && X < nx && Y < ny && src[size_t(Y * nx + X)];
                        if (dilate && b) { hit = true; break; }
                        if (!dilate && !b) { hit = false; break; }
                    }
                    dst[size_t(y * nx + x)] = hit;
                }
        }
    };
    std::vector<uint8_t> grown(bone.size());
    filter(bone, grown, true);
    filter(grown, closed, false);
    // 0 = empty and unvisited, 1 = bone or outside, k >= 2 = enclosed region k.
    std::vector<int> label(bone.size());
    for (size_t i = 0; i < label.size(); ++i) label[i] = (closed[i] || bone[i]) ? 1 : 0;
    std::vector<int64_t> stack;
    auto flood = [&](int64_t seed, int id) {
        size_t count = 0;
        stack.assign(1, seed);
        label[size_t(seed)] = id;
        while (!stack.empty()) {
            const int64_t i = stack.back();
            stack.pop_back();
            ++count;
            const int64_t x = i % nx, y = i / nx;
            const int64_t next[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
            for (const auto& q : next) {
                if (q[0] < 0 || q[1] < 0 || q[0] >= nx || q[1] >= ny) continue;
                const int64_t j = q[1] * nx + q[0];
                if (label[size_t(j)] == 0) {
                    label[size_t(j)] = id;
                    stack.push_back(j);
                }
            }
        }
        return count;
    };
    for (int64_t i = 0; i < n; ++i) {
        const int64_t x = i % nx, y = i / nx;
        if ((x == 0 || y == 0 || x == nx - 1 || y == ny - 1) && label[size_t(i)] == 0) flood(i, 1);
    }
    int best = -1, id = 2;
    size_t best_count = 0;
    for (int64_t i = 0; i < n; ++i)
        if (label[size_t(i)] == 0) {
            const size_t c = flood(i, id);
            if (c > best_count) best_count = c, best = id;
            ++id;
        }
    std::vector<uint8_t> region(bone.size());
    for (size_t i = 0; i < region.size(); ++i) region[i] = label[i] == best;
    return {region, best_count};
}

/// Compares the endocast `mask` (same grid as `ct`) with enclosed_region_2d in slices [z0, z1)
/// whose region has at least `min_area` pixels. Per slice: `inside` = mask pixels in the region.
struct SliceComparison {
    int64_t z = 0;
    size_t mask = 0, region = 0, inside = 0;
};
inline std::vector<SliceComparison> compare_slices(const endocast::Volume<float>& ct,
                                                   const endocast::Volume<uint8_t>& mask, int64_t z0,
                                                   int64_t z1, float iso, int radius, size_t min_area) {
    std::vector<SliceComparison> out;
    const size_t plane = size_t(ct.nx() * ct.ny());
    for (int64_t z = z0; z < z1; ++z) {
        const auto [region, area] = enclosed_region_2d(ct, z, iso, radius);
        if (area < min_area) continue;
        SliceComparison c{z, 0, area, 0};
        for (size_t i = 0; i < plane; ++i) {
            const bool e = mask.data()[size_t(z) * plane + i] != 0;
            c.mask += e;
            c.inside += e && region[i];
        }
        out.push_back(c);
    }
    return out;
}

/// Expects, in every compared slice, inside >= inside_min x mask and lo x region <= mask <= hi x
/// region; returns the summed ratio (sum of mask) / (sum of region).
inline double expect_slices_match(const std::vector<SliceComparison>& slices, double inside_min, double lo,
                                  double hi) {
    size_t mask_sum = 0, region_sum = 0;
    for (const auto& s : slices) {
        mask_sum += s.mask;
        region_sum += s.region;
        EXPECT_GE(double(s.inside), inside_min * double(s.mask)) << "slice " << s.z;
        EXPECT_GE(double(s.mask), lo * double(s.region)) << "slice " << s.z;
        EXPECT_LE(double(s.mask), hi * double(s.region)) << "slice " << s.z;
    }
    return region_sum ? double(mask_sum) / double(region_sum) : 0.0;
}

}  // namespace test_reference
