#include "endocast/watershed.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "endocast/components.h"

namespace endocast {
namespace {

// Bucket queue: one FIFO per priority level; pops the highest non-empty level.
class BucketQueue {
public:
    explicit BucketQueue(size_t levels) : buckets_(levels), heads_(levels, 0) {}
    void push(size_t level, uint64_t item) {
        buckets_[level].push_back(item);
        if (!any_ || level > current_) current_ = level;
        any_ = true;
    }
    // Returns false when empty.
    bool pop(uint64_t& item) {
        while (any_) {
            auto& b = buckets_[current_];
            size_t& h = heads_[current_];
            if (h < b.size()) {
                item = b[h++];
                return true;
            }
            std::vector<uint64_t>().swap(b);  // release the level's memory
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
    std::vector<std::vector<uint64_t>> buckets_;
    std::vector<size_t> heads_;
    size_t current_ = 0;
    bool any_ = false;
};

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
    for (size_t i = 0; i < distance.size(); ++i)
        if (std::isfinite(distance[i])) dmax = std::max(dmax, distance[i]);
    const size_t levels = size_t(double(dmax) / quantum) + 2;
    auto level_of = [&](size_t i) {
        const float d = distance[i];
        if (!std::isfinite(d)) return levels - 1;
        return std::min(levels - 1, size_t(double(d) / quantum));
    };

    WatershedResult r;
    r.labels = seeds;
    Volume<uint8_t>& lab = r.labels;
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const auto offs = neighbour_offsets(p.connectivity);
    std::vector<int64_t> delta;
    for (const auto& o : offs) delta.push_back(o[0] + nx * (o[1] + ny * o[2]));

    BucketQueue q(levels);
    for (size_t i = 0; i < lab.size(); ++i)
        if (lab[i] != kUnlabelled && lab[i] != kBone) q.push(level_of(i), i);

    uint64_t i;
    while (q.pop(i)) {
        const uint8_t L = lab[i];
        const int64_t x = int64_t(i % uint64_t(nx));
        const int64_t y = int64_t((i / uint64_t(nx)) % uint64_t(ny));
        const int64_t z = int64_t(i / uint64_t(nx * ny));
        const bool interior = x > 0 && y > 0 && z > 0 && x < nx - 1 && y < ny - 1 && z < nz - 1;
        for (size_t k = 0; k < offs.size(); ++k) {
            if (!interior) {
                const int64_t jx = x + offs[k][0], jy = y + offs[k][1], jz = z + offs[k][2];
                if (jx < 0 || jy < 0 || jz < 0 || jx >= nx || jy >= ny || jz >= nz) continue;
            }
            const uint64_t j = uint64_t(int64_t(i) + delta[k]);
            if (lab[j] != kUnlabelled) continue;
            lab[j] = L;
            q.push(level_of(j), j);
        }
    }
    for (size_t k = 0; k < lab.size(); ++k) {
        if (lab[k] == kEndocast) ++r.endocast_voxels;
        else if (lab[k] == kOther) ++r.other_voxels;
        else if (lab[k] == kUnlabelled) ++r.unreached_voxels;
    }
    return r;
}

}  // namespace endocast
