// Connected components of binary masks by union-find over runs.
//
// Each row (fixed y, z) of the mask is cut into maximal runs of selected voxels (extracted in
// parallel, slab by slab, then concatenated in scan order). A run is joined to the runs of the
// already-visited neighbouring rows it touches: (y-1, z) and (y, z-1) for every connectivity, plus
// (y-1, z-1) and (y+1, z-1) for 18 and 26; x-ranges must overlap, or overlap once widened by one
// voxel where the connectivity allows the diagonal step. Union keeps the smaller run index as the
// root, so after the merge every root is the first run of its component in scan order, and
// numbering roots in run order numbers components exactly as a scan-order breadth-first search
// would (the component of the first unvisited voxel gets the next number). The result does not
// depend on the thread count. Cost O(V) for the scan plus O(runs * alpha) for the merging; memory
// proportional to the number of runs, not to the voxels (except for connected_components' labels).
#include "endocast/stages/components.h"

#include <algorithm>
#include <cstdlib>

#include <omp.h>

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

struct Run {
    int32_t x0, x1;  ///< inclusive x range
};

struct RunLabels {
    std::vector<Run> runs;            ///< in scan order
    std::vector<size_t> row_start;    ///< runs of row r (= y + ny*z) are [row_start[r], row_start[r+1])
    std::vector<uint32_t> comp;       ///< component (0-based, scan order) of each run
    std::vector<size_t> sizes;        ///< voxels per component
    std::vector<bool> touches_border;
};

template <class Pred>
RunLabels label_runs(const Geometry& g, Pred in, Connectivity c) {
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const int64_t rows = ny * nz;
    RunLabels rl;
    rl.row_start.assign(size_t(rows) + 1, 0);

    // 1. Runs, per slab of z in parallel, concatenated in order.
    const int threads = std::max(1, std::min<int>(omp_get_max_threads(), int(nz)));
    std::vector<std::vector<Run>> part(static_cast<size_t>(threads));
    std::vector<size_t> row_count(size_t(rows), 0);
#pragma omp parallel num_threads(threads)
    {
        const int t = omp_get_thread_num();
        const int64_t z0 = nz * t / threads, z1 = nz * (t + 1) / threads;
        std::vector<Run>& out = part[size_t(t)];
        for (int64_t z = z0; z < z1; ++z)
            for (int64_t y = 0; y < ny; ++y) {
                const size_t base = size_t(nx * (y + ny * z));
                const size_t before = out.size();
                int64_t x = 0;
                while (x < nx) {
                    while (x < nx && !in(base + size_t(x))) ++x;
                    if (x == nx) break;
                    const int64_t s = x;
                    while (x < nx && in(base + size_t(x))) ++x;
                    out.push_back({int32_t(s), int32_t(x - 1)});
                }
                row_count[size_t(y + ny * z)] = out.size() - before;
            }
    }
    size_t total = 0;
    for (const auto& p : part) total += p.size();
    rl.runs.reserve(total);
    for (auto& p : part) {
        rl.runs.insert(rl.runs.end(), p.begin(), p.end());
        std::vector<Run>().swap(p);
    }
    for (int64_t r = 0; r < rows; ++r) rl.row_start[size_t(r + 1)] = rl.row_start[size_t(r)] + row_count[size_t(r)];
    std::vector<size_t>().swap(row_count);

    // 2. Union-find over runs (root = smallest index).
    const size_t nr = rl.runs.size();
    std::vector<uint32_t> parent(nr);
    for (size_t i = 0; i < nr; ++i) parent[i] = uint32_t(i);
    auto find = [&](uint32_t a) {
        while (parent[a] != a) {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        return a;
    };
    auto unite = [&](uint32_t a, uint32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) return;
        if (a < b) parent[b] = a;
        else parent[a] = b;
    };
    const bool wide_plane = c != Connectivity::Face6;          // (dx,dy) / (dx,dz) diagonals
    const bool corner_rows = c != Connectivity::Face6;         // rows (y-1,z-1), (y+1,z-1)
    const bool wide_corner = c == Connectivity::Vertex26;      // (dx,dy,dz) corners
    auto join_rows = [&](size_t a0, size_t a1, size_t b0, size_t b1, int32_t widen) {
        size_t j = b0;
        for (size_t i = a0; i < a1 && j < b1; ++i) {
            const Run& r = rl.runs[i];
            // Skip runs of b that end before r starts (minus widen).
            while (j < b1 && rl.runs[j].x1 + widen < r.x0) ++j;
            size_t k = j;
            while (k < b1 && rl.runs[k].x0 <= r.x1 + widen) {
                unite(uint32_t(i), uint32_t(k));
                ++k;
            }
        }
    };
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            const size_t row = size_t(y + ny * z);
            const size_t a0 = rl.row_start[row], a1 = rl.row_start[row + 1];
            if (a0 == a1) continue;
            auto with = [&](int64_t yy, int64_t zz, int32_t widen) {
                if (yy < 0 || yy >= ny || zz < 0) return;
                const size_t r2 = size_t(yy + ny * zz);
                join_rows(a0, a1, rl.row_start[r2], rl.row_start[r2 + 1], widen);
            };
            with(y - 1, z, wide_plane ? 1 : 0);
            with(y, z - 1, wide_plane ? 1 : 0);
            if (corner_rows) {
                with(y - 1, z - 1, wide_corner ? 1 : 0);
                with(y + 1, z - 1, wide_corner ? 1 : 0);
            }
        }

    // 3. Components numbered by their first run; sizes and border contact.
    rl.comp.resize(nr);
    for (size_t i = 0; i < nr; ++i) {
        const uint32_t root = find(uint32_t(i));
        if (root == i) {
            rl.comp[i] = uint32_t(rl.sizes.size());
            rl.sizes.push_back(0);
            rl.touches_border.push_back(false);
        } else {
            rl.comp[i] = rl.comp[root];  // root < i: already numbered
        }
    }
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            const size_t row = size_t(y + ny * z);
            const bool border_row = y == 0 || z == 0 || y == ny - 1 || z == nz - 1;
            for (size_t i = rl.row_start[row]; i < rl.row_start[row + 1]; ++i) {
                const Run& r = rl.runs[i];
                const uint32_t k = rl.comp[i];
                rl.sizes[k] += size_t(r.x1 - r.x0 + 1);
                if (border_row || r.x0 == 0 || r.x1 == nx - 1) rl.touches_border[k] = true;
            }
        }
    return rl;
}

// Calls fn(z, y, base_index, run, component) for every run, in parallel over z.
template <class Fn>
void for_each_run(const RunLabels& rl, const Geometry& g, Fn fn) {
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            const size_t row = size_t(y + ny * z);
            const size_t base = size_t(nx * (y + ny * z));
            for (size_t i = rl.row_start[row]; i < rl.row_start[row + 1]; ++i)
                fn(base, rl.runs[i], rl.comp[i]);
        }
}

}  // namespace

Components connected_components(const Volume<uint8_t>& mask, Connectivity c) {
    const RunLabels rl = label_runs(mask.geometry(), [&](size_t i) { return mask[i] != 0; }, c);
    Components comp;
    comp.labels.assign(mask.size(), 0);
    uint32_t* lab = comp.labels.data();
    for_each_run(rl, mask.geometry(), [&](size_t base, const Run& r, uint32_t k) {
        std::fill(lab + base + size_t(r.x0), lab + base + size_t(r.x1) + 1, k + 1);
    });
    comp.sizes = rl.sizes;
    comp.touches_border = rl.touches_border;
    return comp;
}

size_t keep_largest_component(Volume<uint8_t>& mask, Connectivity c) {
    const RunLabels rl = label_runs(mask.geometry(), [&](size_t i) { return mask[i] != 0; }, c);
    if (rl.sizes.size() <= 1) return 0;
    const uint32_t best =
        uint32_t(std::max_element(rl.sizes.begin(), rl.sizes.end()) - rl.sizes.begin());
    uint8_t* m = mask.data();
    for_each_run(rl, mask.geometry(), [&](size_t base, const Run& r, uint32_t k) {
        if (k != best) std::fill(m + base + size_t(r.x0), m + base + size_t(r.x1) + 1, uint8_t(0));
    });
    size_t removed = 0;
    for (size_t k = 0; k < rl.sizes.size(); ++k)
        if (k != best) removed += rl.sizes[k];
    return removed;
}

size_t keep_component_at(Volume<uint8_t>& mask, size_t index, Connectivity c) {
    const RunLabels rl = label_runs(mask.geometry(), [&](size_t i) { return mask[i] != 0; }, c);
    // The run holding `index`, if any.
    int64_t keep = -1;
    if (index < mask.size()) {
        const int64_t nx = mask.nx();
        const size_t row = index / size_t(nx);
        const int32_t x = int32_t(index % size_t(nx));
        for (size_t i = rl.row_start[row]; i < rl.row_start[row + 1]; ++i)
            if (rl.runs[i].x0 <= x && x <= rl.runs[i].x1) keep = int64_t(rl.comp[i]);
    }
    uint8_t* m = mask.data();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(mask.size()); ++i) m[i] = 0;
    if (keep < 0) return 0;
    for_each_run(rl, mask.geometry(), [&](size_t base, const Run& r, uint32_t k) {
        if (int64_t(k) == keep) std::fill(m + base + size_t(r.x0), m + base + size_t(r.x1) + 1, uint8_t(1));
    });
    return rl.sizes[size_t(keep)];
}

size_t fill_holes(Volume<uint8_t>& mask, Connectivity c) {
    const RunLabels rl = label_runs(mask.geometry(), [&](size_t i) { return mask[i] == 0; }, c);
    uint8_t* m = mask.data();
    for_each_run(rl, mask.geometry(), [&](size_t base, const Run& r, uint32_t k) {
        if (!rl.touches_border[k]) std::fill(m + base + size_t(r.x0), m + base + size_t(r.x1) + 1, uint8_t(1));
    });
    size_t filled = 0;
    for (size_t k = 0; k < rl.sizes.size(); ++k)
        if (!rl.touches_border[k]) filled += rl.sizes[k];
    return filled;
}

}  // namespace endocast
