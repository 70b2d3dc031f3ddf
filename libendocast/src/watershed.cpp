#include "endocast/watershed.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "endocast/components.h"

namespace endocast {
namespace {

// Bucket queue: one FIFO per priority level; pops the highest non-empty level. Item is uint32_t
// for volumes below 2^32 voxels (half the queue memory), uint64_t otherwise.
template <class Item>
class BucketQueue {
public:
    explicit BucketQueue(size_t levels) : buckets_(levels), heads_(levels, 0) {}
    void push(size_t level, Item item) {
        buckets_[level].push_back(item);
        if (!any_ || level > current_) current_ = level;
        any_ = true;
    }
    // Returns false when empty.
    bool pop(Item& item) {
        while (any_) {
            auto& b = buckets_[current_];
            size_t& h = heads_[current_];
            if (h < b.size()) {
                item = b[h++];
                return true;
            }
            std::vector<Item>().swap(b);  // release the level's memory
            h = 0;
            if (current_ == 0) {
                any_ = false;
                return false;
            }
            --current_;
        }
        return false;
    }

private:
    std::vector<std::vector<Item>> buckets_;
    std::vector<size_t> heads_;
    size_t current_ = 0;
    bool any_ = false;
};

template <class Item>
void flood(Volume<uint8_t>& lab, const Volume<float>& distance, const std::vector<std::array<int, 3>>& offs,
           double quantum, size_t levels) {
    const Geometry& g = lab.geometry();
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const float* dist = distance.data();
    uint8_t* L = lab.data();
    auto level_of = [&](size_t i) {
        const float d = dist[i];
        if (!std::isfinite(d)) return levels - 1;
        return std::min(levels - 1, size_t(double(d) / quantum));
    };
    const int nn = int(offs.size());
    int64_t delta[26];
    for (int k = 0; k < nn; ++k) delta[k] = offs[size_t(k)][0] + nx * (offs[size_t(k)][1] + ny * offs[size_t(k)][2]);

    BucketQueue<Item> q(levels);
    // Seeds in raster order; a seed with no unlabelled neighbour is left out: labels are never
    // removed, so it would pop with nothing to do, and the order of the other items is the same.
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            const bool inner_row = y > 0 && z > 0 && y < ny - 1 && z < nz - 1;
            for (int64_t x = 0; x < nx; ++x) {
                const size_t i = size_t(x + nx * (y + ny * z));
                if (L[i] == kUnlabelled || L[i] == kBone) continue;
                bool open = false;
                if (inner_row && x > 0 && x < nx - 1) {
                    for (int k = 0; k < nn && !open; ++k) open = L[size_t(int64_t(i) + delta[k])] == kUnlabelled;
                } else {
                    for (int k = 0; k < nn && !open; ++k) {
                        const int64_t jx = x + offs[size_t(k)][0], jy = y + offs[size_t(k)][1], jz = z + offs[size_t(k)][2];
                        if (jx < 0 || jy < 0 || jz < 0 || jx >= nx || jy >= ny || jz >= nz) continue;
                        open = L[size_t(int64_t(i) + delta[k])] == kUnlabelled;
                    }
                }
                if (open) q.push(level_of(i), Item(i));
            }
        }

    Item item;
    while (q.pop(item)) {
        const size_t i = size_t(item);
        const uint8_t label = L[i];
        const int64_t t = int64_t(i) / nx;
        const int64_t x = int64_t(i) - t * nx;
        const int64_t z = t / ny;
        const int64_t y = t - z * ny;
        const bool interior = x > 0 && y > 0 && z > 0 && x < nx - 1 && y < ny - 1 && z < nz - 1;
        for (int k = 0; k < nn; ++k) {
            if (!interior) {
                const int64_t jx = x + offs[size_t(k)][0], jy = y + offs[size_t(k)][1], jz = z + offs[size_t(k)][2];
                if (jx < 0 || jy < 0 || jz < 0 || jx >= nx || jy >= ny || jz >= nz) continue;
            }
            const size_t j = size_t(int64_t(i) + delta[k]);
            if (L[j] != kUnlabelled) continue;
            L[j] = label;
            q.push(level_of(j), Item(j));
        }
    }
}

}  // namespace

WatershedResult watershed(const Volume<uint8_t>& seeds, const Volume<float>& distance,
                          const WatershedParams& p) {
    if (seeds.size() != distance.size())
        throw InvalidParameter("watershed: seed and distance volumes differ in size");
    const int conn = int(p.connectivity);
    if (conn != 6 && conn != 18 && conn != 26)
        throw InvalidParameter("watershed connectivity " + std::to_string(conn) +
                               ", expected 6, 18 or 26");
    const Geometry& g = seeds.geometry();
    const double quantum = p.quantum_mm > 0
                               ? p.quantum_mm
                               : std::min({g.spacing[0], g.spacing[1], g.spacing[2]}) / 64.0;
    float dmax = 0;
    const float* dist = distance.data();
#pragma omp parallel for schedule(static) reduction(max : dmax)
    for (int64_t i = 0; i < int64_t(distance.size()); ++i)
        if (std::isfinite(dist[i])) dmax = std::max(dmax, dist[i]);
    const size_t levels = size_t(double(dmax) / quantum) + 2;

    WatershedResult r;
    r.labels = seeds;
    const auto offs = neighbour_offsets(p.connectivity);
    if (r.labels.size() < (size_t(1) << 32))
        flood<uint32_t>(r.labels, distance, offs, quantum, levels);
    else
        flood<uint64_t>(r.labels, distance, offs, quantum, levels);

    const uint8_t* lab = r.labels.data();
    size_t endo = 0, other = 0, unreached = 0;
#pragma omp parallel for schedule(static) reduction(+ : endo, other, unreached)
    for (int64_t k = 0; k < int64_t(r.labels.size()); ++k) {
        const uint8_t l = lab[k];
        endo += l == kEndocast;
        other += l == kOther;
        unreached += l == kUnlabelled;
    }
    r.endocast_voxels = endo;
    r.other_voxels = other;
    r.unreached_voxels = unreached;
    return r;
}

}  // namespace endocast
