#include "endocast/components.h"

#include <algorithm>
#include <cstdlib>
#include <deque>

namespace endocast {

std::vector<std::array<int, 3>> neighbour_offsets(Connectivity c) {
    std::vector<std::array<int, 3>> out;
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const int n = std::abs(dx) + std::abs(dy) + std::abs(dz);
                if (n == 0) continue;
                if (c == Connectivity::Face6 && n > 1) continue;
                if (c == Connectivity::Edge18 && n > 2) continue;
                out.push_back({dx, dy, dz});
            }
    return out;
}

namespace {

// Breadth-first labelling of voxels where `in(i)` holds.
template <class Pred>
Components label(const Geometry& g, Pred in, Connectivity c) {
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const auto offs = neighbour_offsets(c);
    Components comp;
    comp.labels.assign(g.voxel_count(), 0);
    std::vector<size_t> queue;
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y)
            for (int64_t x = 0; x < nx; ++x) {
                const size_t start = size_t(x + nx * (y + ny * z));
                if (comp.labels[start] || !in(start)) continue;
                const uint32_t id = uint32_t(comp.sizes.size() + 1);
                size_t count = 0;
                bool border = false;
                queue.clear();
                queue.push_back(start);
                comp.labels[start] = id;
                for (size_t head = 0; head < queue.size(); ++head) {
                    const size_t i = queue[head];
                    ++count;
                    const int64_t ix = int64_t(i % size_t(nx));
                    const int64_t iy = int64_t((i / size_t(nx)) % size_t(ny));
                    const int64_t iz = int64_t(i / size_t(nx * ny));
                    if (ix == 0 || iy == 0 || iz == 0 || ix == nx - 1 || iy == ny - 1 ||
                        iz == nz - 1)
                        border = true;
                    for (const auto& o : offs) {
                        const int64_t jx = ix + o[0], jy = iy + o[1], jz = iz + o[2];
                        if (jx < 0 || jy < 0 || jz < 0 || jx >= nx || jy >= ny || jz >= nz)
                            continue;
                        const size_t j = size_t(jx + nx * (jy + ny * jz));
                        if (comp.labels[j] || !in(j)) continue;
                        comp.labels[j] = id;
                        queue.push_back(j);
                    }
                }
                comp.sizes.push_back(count);
                comp.touches_border.push_back(border);
            }
    return comp;
}

}  // namespace

Components connected_components(const Volume<uint8_t>& mask, Connectivity c) {
    return label(mask.geometry(), [&](size_t i) { return mask[i] != 0; }, c);
}

size_t keep_largest_component(Volume<uint8_t>& mask, Connectivity c) {
    const Components comp = connected_components(mask, c);
    if (comp.sizes.size() <= 1) return 0;
    const size_t best =
        size_t(std::max_element(comp.sizes.begin(), comp.sizes.end()) - comp.sizes.begin()) + 1;
    size_t removed = 0;
    for (size_t i = 0; i < mask.size(); ++i)
        if (comp.labels[i] && comp.labels[i] != best) {
            mask[i] = 0;
            ++removed;
        }
    return removed;
}

size_t fill_holes(Volume<uint8_t>& mask, Connectivity c) {
    const Components comp = label(mask.geometry(), [&](size_t i) { return mask[i] == 0; }, c);
    size_t filled = 0;
    for (size_t i = 0; i < mask.size(); ++i) {
        const uint32_t l = comp.labels[i];
        if (l && !comp.touches_border[l - 1]) {
            mask[i] = 1;
            ++filled;
        }
    }
    return filled;
}

}  // namespace endocast
