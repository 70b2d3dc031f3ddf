// Watershed by priority flooding down the distance field, first-in first-out ties (watershed.h).
#include "endocast/stages/watershed.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "endocast/stages/components.h"
#include "endocast/errors.h"

namespace endocast {
namespace {

// Bucket queue: one FIFO per priority level; pops the highest non-empty level. Indices are
// uint32_t for volumes below 2^32 voxels (half the queue memory), uint64_t otherwise.
template <class Item>
class BucketQueue {
public:
    explicit BucketQueue(size_t levels) : buckets_(levels), heads_(levels, 0) {}
    void push(size_t level, Item item) {
        buckets_[level].push_back(item);
        if (!any_ || level > current_) current_ = level;
        any_ = true;
    }
    // The item `ahead` places after the next one in the current level, or nullptr (for prefetching:
    // the flood reads its neighbours a few items later).
    const Item* peek(size_t ahead) const {
        if (!any_) return nullptr;
        const auto& b = buckets_[current_];
        const size_t at = heads_[current_] + ahead;
        return at < b.size() ? &b[at] : nullptr;
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

// The flood runs on a copy of the labels with a one-voxel frame of kBone around it (a wall), so a
// neighbour needs no bounds test and a voxel's coordinates are never computed: a queue item holds
// the voxel's index in the framed copy (labels) and in the volume (distance). Seeds are pushed in
// the volume's raster order and neighbours visited in `offs` order, as without the frame, so the
// labels are the same. The flooded labels are written back into `out`, in `seeds`' layout.
// The copy covers only `box`: the unlabelled voxels' box grown by one voxel (FloodBox). Only
// unlabelled voxels change and every seed queued lies next to one, so the flood inside the box is
// the flood of the whole volume: a neighbour outside it is labelled or bone, skipped as the frame.
constexpr size_t kPrefetchAhead = 8;  // items ahead whose neighbours are prefetched

// `out` receives the labels; it may be `seeds` itself (whose voxels are not read once copied into
// the framed buffer), which saves a volume. `record` (voxels, may be null) receives the flood
// levels (FloodLevels); `start` (may be null) gives the levels the seeds start at instead of their
// own (resume_watershed).
struct FloodBox {
    std::array<int64_t, 3> lo{0, 0, 0}, dims{0, 0, 0};
    bool empty() const { return dims[0] == 0; }
};

// The box of the unlabelled voxels, grown by one voxel (within the volume); empty when there is none.
FloodBox flood_box(const Volume<uint8_t>& labels) {
    const int64_t nx = labels.nx(), ny = labels.ny(), nz = labels.nz();
    int64_t x0 = nx, x1 = -1, y0 = ny, y1 = -1, z0 = nz, z1 = -1;
#pragma omp parallel for schedule(static) reduction(min : x0, y0, z0) reduction(max : x1, y1, z1)
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            const uint8_t* row = labels.data() + labels.index(0, y, z);
            uint8_t any = 0;
            for (int64_t x = 0; x < nx; ++x) any |= uint8_t(row[x] == kUnlabelled);
            if (!any) continue;
            int64_t a = 0, b = nx - 1;
            while (row[a] != kUnlabelled) ++a;
            while (row[b] != kUnlabelled) --b;
            x0 = std::min(x0, a), x1 = std::max(x1, b);
            y0 = std::min(y0, y), y1 = std::max(y1, y);
            z0 = std::min(z0, z), z1 = std::max(z1, z);
        }
    FloodBox box;
    if (x1 < 0) return box;
    const int64_t lo[3] = {x0, y0, z0}, hi[3] = {x1, y1, z1}, n[3] = {nx, ny, nz};
    for (int a = 0; a < 3; ++a) {
        box.lo[size_t(a)] = std::max<int64_t>(0, lo[a] - 1);
        box.dims[size_t(a)] = std::min<int64_t>(n[a] - 1, hi[a] + 1) - box.lo[size_t(a)] + 1;
    }
    return box;
}

template <class Index>
void flood(const Volume<uint8_t>& seeds, const Volume<float>& distance, const std::vector<std::array<int, 3>>& offs,
           double quantum, size_t levels, const FloodBox& box, Volume<uint8_t>& out, uint16_t* record,
           const uint16_t* start) {
    struct Item {
        Index framed, voxel;
    };
    const Geometry& g = seeds.geometry();
    const int64_t vx = g.dims[0], vy = g.dims[1];  // the volume's strides
    const int64_t nx = box.dims[0], ny = box.dims[1], nz = box.dims[2];
    const int64_t fx = nx + 2, fy = ny + 2, fz = nz + 2;
    // Voxel (x, y, z) of the box in the volume.
    auto volume_index = [&](int64_t x, int64_t y, int64_t z) {
        return size_t((x + box.lo[0]) + vx * ((y + box.lo[1]) + vy * (z + box.lo[2])));
    };
    const float* dist = distance.data();
    auto level_of = [&](size_t i) { return flood_level(dist[i], quantum, levels); };
    const int nn = int(offs.size());
    int64_t fdelta[26], vdelta[26];
    for (int k = 0; k < nn; ++k) {
        const auto& o = offs[size_t(k)];
        fdelta[k] = o[0] + fx * (o[1] + fy * o[2]);
        vdelta[k] = o[0] + vx * (o[1] + vy * o[2]);
    }
    auto framed_row = [&](int64_t y, int64_t z) { return size_t(1 + fx * ((y + 1) + fy * (z + 1))); };

    // Filled slice by slice in parallel (a fresh allocation, so its pages are first touched here,
    // by several threads, instead of by one zero fill).
    VoxelBuffer<uint8_t> framed_labels(size_t(fx * fy * fz));
    uint8_t* const L = framed_labels.data();
    // Per framed row (fy * fz rows of fx; the frame's are all kBone): does it hold an unlabelled
    // voxel. near_unlabelled(y, z, k): does the row of box row (y, z)'s neighbour k.
    std::vector<uint8_t> row_unlabelled(size_t(fy * fz), 0);
    auto near_unlabelled = [&](int64_t y, int64_t z, int k) {
        const auto& o = offs[size_t(k)];
        return row_unlabelled[size_t((y + 1 + o[1]) + fy * (z + 1 + o[2]))] != 0;
    };
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < fz; ++z) {
        uint8_t* slice = L + size_t(fx * fy * z);
        if (z == 0 || z == fz - 1) {
            std::fill_n(slice, fx * fy, kBone);
            continue;
        }
        std::fill_n(slice, fx, kBone);
        std::fill_n(slice + fx * (fy - 1), fx, kBone);
        for (int64_t y = 0; y < ny; ++y) {
            uint8_t* row = L + framed_row(y, z - 1);
            row[-1] = kBone;
            std::copy_n(seeds.data() + volume_index(0, y, z - 1), nx, row);
            row[nx] = kBone;
            uint8_t any = 0;
            for (int64_t x = 0; x < nx; ++x) any |= uint8_t(row[x] == kUnlabelled);
            row_unlabelled[size_t((y + 1) + fy * z)] = any;
        }
    }

    // With a record of at most 2^15 levels, each voxel's own level is written into it first (on
    // all threads), flagged as not reached (the top bit): the flood then reads a neighbour's level
    // there, next to where it writes it, instead of its distance (a division and a second
    // scattered read per voxel queued). The flags left at the end are cleared (0, as before).
    constexpr uint16_t kNotReached = 0x8000;
    const bool own_in_record = record && levels <= kNotReached;
    auto for_box_rows = [&](auto&& fn) {  // fn(first voxel of a box row in the volume), in parallel
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < nz; ++z)
            for (int64_t y = 0; y < ny; ++y) fn(volume_index(0, y, z));
    };
    if (own_in_record) {
        // level_of in a form the compiler vectorizes, the same values: the distances are >= 0 or
        // +inf (NaN fails the test too), the top level is a whole number below 2^15, so the minimum
        // taken before the truncation gives the truncation's minimum.
        const double top = double(levels - 1);
        for_box_rows([&](size_t v0) {
            const float* d = dist + v0;
            uint16_t* r = record + v0;
            for (int64_t x = 0; x < nx; ++x) {
                const double t = double(d[x]) / quantum;
                r[x] = uint16_t(int32_t(t < top ? t : top)) | kNotReached;
            }
        });
    }
    // Seeds in raster order; a seed with no unlabelled neighbour is left out: labels are never
    // removed, so it would pop with nothing to do, and the order of the other items is the same.
    // Found slice by slice in parallel, then queued in slice order.
    struct Seed {
        size_t level;
        Item item;
    };
    // Per row, the neighbours' rows are tested whole (contiguous reads the compiler vectorizes:
    // near[x] = some neighbour of x unlabelled), then the row is scanned for the seeds.
    std::vector<std::vector<Seed>> slice_seeds(static_cast<size_t>(nz));
#pragma omp parallel
    {
        std::vector<uint8_t> near_row(static_cast<size_t>(nx));
#pragma omp for schedule(dynamic, 4)
        for (int64_t z = 0; z < nz; ++z) {
            std::vector<Seed>& out = slice_seeds[size_t(z)];
            for (int64_t y = 0; y < ny; ++y) {
                const size_t f0 = framed_row(y, z), v0 = volume_index(0, y, z);
                const uint8_t* __restrict row = L + f0;
                // A neighbour row without an unlabelled voxel adds nothing to `near`.
                bool any_near = false;
                for (int k = 0; k < nn && !any_near; ++k) any_near = near_unlabelled(y, z, k);
                if (!any_near) continue;
                uint8_t labelled = 0;
                for (int64_t x = 0; x < nx; ++x) labelled |= uint8_t((row[x] != kUnlabelled) & (row[x] != kBone));
                if (!labelled) continue;
                uint8_t* __restrict near = near_row.data();
                std::fill_n(near, nx, uint8_t(0));
                for (int k = 0; k < nn; ++k) {
                    if (!near_unlabelled(y, z, k)) continue;
                    const uint8_t* __restrict q = row + fdelta[k];
                    for (int64_t x = 0; x < nx; ++x) near[x] |= uint8_t(q[x] == kUnlabelled);
                }
                for (int64_t x = 0; x < nx; ++x) {
                    if (!near[x] || row[x] == kUnlabelled || row[x] == kBone) continue;
                    const size_t v = v0 + size_t(x);
                    out.push_back({start ? size_t(start[v]) : level_of(v), Item{Index(f0 + size_t(x)), Index(v)}});
                    if (record) record[v] = uint16_t(level_of(v));  // a queued seed's level is its own
                }
            }
        }
    }
    BucketQueue<Item> q(levels);
    for (auto& slice : slice_seeds) {
        for (const Seed& s : slice) q.push(s.level, s.item);
        std::vector<Seed>().swap(slice);
    }

    Item item;
    while (q.pop(item)) {
        // The neighbours of an item a few places ahead are fetched now, so that they are in cache
        // when it pops (the flood is bound by these scattered reads, not by arithmetic).
        if (const Item* next = q.peek(kPrefetchAhead)) {
            for (int k = 0; k < nn; ++k) {
                __builtin_prefetch(L + int64_t(next->framed) + fdelta[k], 1);
                if (!own_in_record) __builtin_prefetch(dist + int64_t(next->voxel) + vdelta[k], 0);
                if (record) __builtin_prefetch(record + int64_t(next->voxel) + vdelta[k], 1);
            }
            if (record) __builtin_prefetch(record + int64_t(next->voxel), 0);
        }
        const size_t f = size_t(item.framed);
        const uint8_t label = L[f];
        const uint16_t reached = record ? record[size_t(item.voxel)] : 0;
        for (int k = 0; k < nn; ++k) {
            const size_t j = size_t(int64_t(f) + fdelta[k]);
            if (L[j] != kUnlabelled) continue;
            L[j] = label;
            const size_t v = size_t(int64_t(item.voxel) + vdelta[k]);
            const size_t level = own_in_record ? size_t(record[v] & uint16_t(kNotReached - 1)) : level_of(v);
            q.push(level, Item{Index(j), Index(v)});
            if (record) record[v] = std::min(reached, uint16_t(level));
        }
    }

    if (own_in_record)
        for_box_rows([&](size_t v0) {
            for (int64_t x = 0; x < nx; ++x)
                if (record[v0 + size_t(x)] & kNotReached) record[v0 + size_t(x)] = 0;
        });
    if (&out != &seeds) out = seeds;  // the voxels outside the box as they are
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y)
            std::copy_n(L + framed_row(y, z), nx, out.data() + volume_index(0, y, z));
}

}  // namespace

namespace {

// The watershed of `seeds` into `out` (which may be `seeds`); with `record`, its flood levels too
// (left empty beyond 65535 levels); from `start`, resumed (resume_watershed).
WatershedResult run_watershed(const Volume<uint8_t>& seeds, const Volume<float>& distance, const WatershedParams& p,
                              Volume<uint8_t>& out, FloodLevels* record = nullptr, const FloodLevels* start = nullptr) {
    if (seeds.size() != distance.size())
        throw InvalidParameter("watershed: seed and distance volumes differ in size");
    const int conn = int(p.connectivity);
    if (conn != 6 && conn != 18 && conn != 26)
        throw InvalidParameter("watershed connectivity " + std::to_string(conn) +
                               ", expected 6, 18 or 26");
    const Geometry& g = seeds.geometry();
    const double quantum = p.quantum_mm > 0
                               ? p.quantum_mm
                               : g.smallest_spacing() / 64.0;
    float dmax = 0;
    const float* dist = distance.data();
#pragma omp parallel for schedule(static) reduction(max : dmax)
    for (int64_t i = 0; i < int64_t(distance.size()); ++i)
    {  // the largest finite distance (a test the compiler vectorizes: NaN and inf fail it)
        const float v = dist[i] <= std::numeric_limits<float>::max() ? dist[i] : 0.0f;
        dmax = dmax < v ? v : dmax;
    }
    const size_t levels = size_t(double(dmax) / quantum) + 2;

    WatershedResult r;
    const auto offs = neighbour_offsets(p.connectivity);
    const FloodBox box = flood_box(seeds);
    const size_t framed = size_t(box.dims[0] + 2) * size_t(box.dims[1] + 2) * size_t(box.dims[2] + 2);
    uint16_t* rec = nullptr;
    if (record) {
        *record = FloodLevels();
        if (levels <= kMaxFloodLevels) {
            record->level.resize(seeds.size());
            record->quantum_mm = quantum;
            record->levels = levels;
            rec = record->level.data();
        }
    }
    const uint16_t* st = nullptr;
    if (start) {
        if (start->level.size() != seeds.size() || start->quantum_mm != quantum || start->levels != levels)
            throw InvalidParameter("resume_watershed: the flood levels are not of these labels and distances at this quantum");
        st = start->level.data();
    }
    // The volume's indices (distance, levels) and the framed box's must fit the queue's items.
    if (box.empty()) {  // nothing to flood
        if (&out != &seeds) out = seeds;
    } else if (framed < (size_t(1) << 32) && seeds.size() < (size_t(1) << 32)) {
        flood<uint32_t>(seeds, distance, offs, quantum, levels, box, out, rec, st);
    } else {
        flood<uint64_t>(seeds, distance, offs, quantum, levels, box, out, rec, st);
    }
    r.labels = std::move(out);

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

}  // namespace

WatershedResult watershed(const Volume<uint8_t>& seeds, const Volume<float>& distance, const WatershedParams& p) {
    Volume<uint8_t> out;
    return run_watershed(seeds, distance, p, out);
}

WatershedResult watershed(Volume<uint8_t>&& seeds, const Volume<float>& distance, const WatershedParams& p) {
    Volume<uint8_t> own = std::move(seeds);
    return run_watershed(own, distance, p, own);
}

WatershedResult watershed(Volume<uint8_t>&& seeds, const Volume<float>& distance, const WatershedParams& p,
                          FloodLevels& levels) {
    Volume<uint8_t> own = std::move(seeds);
    return run_watershed(own, distance, p, own, &levels);
}

WatershedResult resume_watershed(Volume<uint8_t>&& labels, const FloodLevels& levels, const Volume<float>& distance,
                                 const WatershedParams& p) {
    Volume<uint8_t> own = std::move(labels);
    return run_watershed(own, distance, p, own, nullptr, &levels);
}

}  // namespace endocast
