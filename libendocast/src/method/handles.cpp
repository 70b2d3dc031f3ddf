// Handles of the endocast region in the polygonizer's Freudenthal triangulation: the Euler
// characteristic by counting simplices, and close_handles, a ball grown by simple points in order
// of decreasing distance to bone (topology-preserving region growing, as in the topology correction
// of Han, Xu and Prince 2002), so each handle is cut where it is narrowest.
#include "endocast/stages/handles.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "endocast/stages/components.h"
#include "kernels/freudenthal.h"
#include "method/label_box.h"

namespace endocast {
namespace {

// The simplices of the Freudenthal triangulation with lowest vertex p are the chains
// p < p + u < p + u + v < ... whose increments have disjoint supports in {0,1}^3.
struct Chains {
    std::vector<std::array<int, 3>> edges;                          // u
    std::vector<std::array<std::array<int, 3>, 2>> triangles;       // u, u + v
    std::vector<std::array<std::array<int, 3>, 3>> tetrahedra;      // e_a, e_a + e_b, (1,1,1)
    Chains() {
        for (int m = 1; m < 8; ++m) edges.push_back({m & 1, (m >> 1) & 1, (m >> 2) & 1});
        for (int u = 1; u < 8; ++u)
            for (int v = 1; v < 8; ++v)
                if (!(u & v) && (u | v) < 8)
                    triangles.push_back({{{u & 1, (u >> 1) & 1, (u >> 2) & 1},
                                          {(u | v) & 1, ((u | v) >> 1) & 1, ((u | v) >> 2) & 1}}});
        const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (const auto& q : perms) {
            std::array<int, 3> a{0, 0, 0}, b{0, 0, 0};
            a[size_t(q[0])] = 1;
            b = a;
            b[size_t(q[1])] = 1;
            tetrahedra.push_back({{a, b, {1, 1, 1}}});
        }
    }
};

// freudenthal_euler_characteristic over the simplices whose lowest vertex lies in the box lo..hi
// (inclusive): all of them when the box holds every voxel of the label.
long euler_in_box(const Volume<uint8_t>& labels, uint8_t label, const std::array<int64_t, 3>& lo,
                  const std::array<int64_t, 3>& hi) {
    // The simplices with lowest vertex p depend only on which corners of the cube p + {0,1}^3 are
    // in the set: their signed count, per configuration of the 8 corners (bit k: corner
    // (k&1, (k>>1)&1, (k>>2)&1); corner 0 is p itself, in the set), from a table of 128.
    static const std::array<int8_t, 256> table = [] {
        const Chains chains;
        std::array<int8_t, 256> t{};
        for (int c = 1; c < 256; c += 2) {
            auto in = [c](const std::array<int, 3>& u) { return (c >> (u[0] + 2 * u[1] + 4 * u[2])) & 1; };
            int n = 1;
            for (const auto& u : chains.edges) n -= in(u);
            for (const auto& tr : chains.triangles) n += in(tr[0]) && in(tr[1]);
            for (const auto& te : chains.tetrahedra) n -= in(te[0]) && in(te[1]) && in(te[2]);
            t[size_t(c)] = int8_t(n);
        }
        return t;
    }();
    const Dims& d = labels.dims();
    const int64_t nx = d[0], ny = d[1], nz = d[2];
    long chi = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : chi)
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y) {
            // The four rows of the cubes at (., y, z); a row beyond the volume holds nothing.
            const uint8_t* r[4];
            for (int k = 0; k < 4; ++k) {
                const int64_t yy = y + (k & 1), zz = z + (k >> 1);
                r[k] = yy < ny && zz < nz ? labels.data() + labels.index(0, yy, zz) : nullptr;
            }
            const uint8_t* r0 = r[0];
            for (int64_t x = lo[0]; x <= hi[0]; ++x) {
                if (r0[x] != label) continue;
                unsigned c = 0;
                for (int k = 0; k < 4; ++k) {  // corners 2k (x) and 2k + 1 (x + 1) of rows k
                    if (!r[k]) continue;
                    c |= unsigned(r[k][x] == label) << (2 * k);
                    if (x + 1 < nx) c |= unsigned(r[k][x + 1] == label) << (2 * k + 1);
                }
                chi += table[c];
            }
        }
    return chi;
}

}  // namespace

long freudenthal_euler_characteristic(const Volume<uint8_t>& labels, uint8_t label) {
    const Dims& d = labels.dims();
    return euler_in_box(labels, label, {0, 0, 0}, {d[0] - 1, d[1] - 1, d[2] - 1});
}

namespace {

// E as the polygonizer meshes it: its largest face-connected piece with its enclosed holes filled
// (marching_cubes.cpp does the same to its mask). Without this a handle can hide in the Euler
// characteristic behind a void (1 - 1 + 1) or a second piece (2 - 1), and come out in the mesh.
// Works in E's box plus a voxel; returns the voxels that changed, and E's box after in `after`.
size_t as_polygonized(Volume<uint8_t>& labels, LabelBox& after) {
    const Dims& d = labels.dims();
    after = label_box(labels, kEndocast);
    if (after.empty()) return 0;
    std::array<int64_t, 3> lo = after.lo, hi = after.hi;
    Geometry g;
    for (size_t a = 0; a < 3; ++a) {
        lo[a] = std::max<int64_t>(0, lo[a] - 1);
        hi[a] = std::min<int64_t>(d[a] - 1, hi[a] + 1);
        g.dims[a] = hi[a] - lo[a] + 1;
    }
    Volume<uint8_t> m(g, 0);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) m(x, y, z) = labels(x + lo[0], y + lo[1], z + lo[2]) == kEndocast;
    // A hole must be enclosed in the whole volume, not only in the box: the box's faces on the
    // volume border are outside the volume, the others have the margin voxel (never E) beyond E.
    keep_largest_component(m, Connectivity::Face6);
    fill_holes(m, Connectivity::Face6);
    // Written back a row at a time, the planes in parallel. E is then exactly m's voxels (none
    // lies outside m's box): its box is m's, moved to the volume's indices.
    size_t changed = 0;
#pragma omp parallel for schedule(static) reduction(+ : changed)
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y) {
            const uint8_t* mr = m.data() + m.index(0, y, z);
            uint8_t* row = labels.data() + labels.index(lo[0], y + lo[1], z + lo[2]);
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                uint8_t& l = row[x];
                if (mr[x] && l != kEndocast) {
                    l = kEndocast;
                    ++changed;
                } else if (!mr[x] && l == kEndocast) {
                    l = kBone;
                    ++changed;
                }
            }
        }
    after = box_of(m, [](uint8_t v) { return v != 0; });
    if (after.empty()) {
        after = LabelBox{};
        after.lo = {d[0], d[1], d[2]};
    } else {
        for (size_t a = 0; a < 3; ++a) after.lo[a] += lo[a], after.hi[a] += lo[a];
    }
    return changed;
}

}  // namespace

HandleClosing close_handles(Volume<uint8_t>& labels, size_t seed, const Volume<float>& distance,
                            const std::array<int64_t, 3>& distance_origin) {
    HandleClosing r;
    LabelBox box;
    r.voxels_matched = as_polygonized(labels, box);
    if (box.empty()) {  // no E: no simplex, characteristic 0
        r.euler_before = r.euler_after = 0;
        return r;
    }
    // Counted over E's box only (every simplex's lowest vertex is an E voxel; the closing below
    // only takes voxels away, so the box still holds E after it).
    r.euler_before = r.euler_after = euler_in_box(labels, kEndocast, box.lo, box.hi);
    if (r.euler_before == 1 || labels[seed] != kEndocast) return r;
    const Geometry& g = labels.geometry();
    const int64_t nx = g.dims[0], ny = g.dims[1];
    // E's box, grown by one voxel beyond the volume too (those voxels stay outside the set), so
    // every E voxel's 14 neighbours lie in the work grid.
    const std::array<int64_t, 3> lo = box.lo, hi = box.hi;
    const int64_t wx = hi[0] - lo[0] + 3, wy = hi[1] - lo[1] + 3, wz = hi[2] - lo[2] + 3;
    Geometry wg;
    wg.dims = {wx, wy, wz};
    Volume<uint8_t> in(wg, 0);            // the grown set
    // 1: E, not met yet; 2: queued; 3: waiting (not simple when last popped); 0: other or added
    std::vector<uint8_t> state(size_t(wx * wy * wz), 0);
    auto work = [&](int64_t x, int64_t y, int64_t z) { return size_t((x - lo[0] + 1) + wx * ((y - lo[1] + 1) + wy * (z - lo[2] + 1))); };
    auto global = [&](size_t w, int64_t& x, int64_t& y, int64_t& z) {
        x = int64_t(w % size_t(wx)) + lo[0] - 1;
        y = int64_t((w / size_t(wx)) % size_t(wy)) + lo[1] - 1;
        z = int64_t(w / size_t(wx * wy)) + lo[2] - 1;
    };
    // Bucket queue by distance to bone, in 1/16 of the smallest spacing (deterministic order:
    // the highest bucket first, last in first out within a bucket).
    const double q = g.smallest_spacing() / 16.0;
    const Dims& dd = distance.dims();
    auto bucket_at = [&](int64_t x, int64_t y, int64_t z) {
        const int64_t a = x - distance_origin[0], b = y - distance_origin[1], c = z - distance_origin[2];
        if (a < 0 || b < 0 || c < 0 || a >= dd[0] || b >= dd[1] || c >= dd[2]) return size_t(0);
        return size_t(std::max(0.0, std::floor(double(distance(a, b, c)) / q)));
    };
    // The E voxels marked, and each one's bucket computed once, rows in parallel (the growth asks
    // for a voxel's bucket each time it is queued); kept as uint16 when every bucket fits, else
    // computed when asked.
    std::vector<uint16_t> bucket(state.size(), 0);
    int fits = 1;
#pragma omp parallel for schedule(static) reduction(& : fits)
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y)
            for (int64_t x = lo[0]; x <= hi[0]; ++x) {
                if (labels(x, y, z) != kEndocast) continue;
                const size_t w = work(x, y, z), b = bucket_at(x, y, z);
                state[w] = 1;
                bucket[w] = uint16_t(b);
                fits &= int(b <= UINT16_MAX);
            }
    if (!fits) std::vector<uint16_t>().swap(bucket);
    auto bucket_of = [&](size_t w) {
        if (!bucket.empty()) return size_t(bucket[w]);  // asked of E voxels only
        int64_t x, y, z;
        global(w, x, y, z);
        return bucket_at(x, y, z);
    };
    std::vector<std::vector<size_t>> buckets;
    int64_t cur = -1;
    const FreudenthalLink link(wx, wy);
    auto push = [&](size_t w) {
        const size_t b = bucket_of(w);
        if (b >= buckets.size()) buckets.resize(b + 1);
        buckets[b].push_back(w);
        state[w] = 2;
        cur = std::max(cur, int64_t(b));
    };
    auto add = [&](size_t w) {
        in[w] = 1;
        state[w] = 0;
        for (int k = 0; k < 14; ++k) {
            const size_t n = size_t(int64_t(w) + link.step(k));
            if (state[n] == 1 || state[n] == 3) push(n);  // met, or waiting: its link changed
        }
    };
    // Start from the seed's part of E deeper than an eighth of the seed's depth when that part is a ball
    // (connected by construction; Euler characteristic 1 without voids): the growth then visits
    // only the shell around it, and a handle that deep would not be a thin defect anyway.
    // Otherwise from the seed alone.
    const int64_t sx = int64_t(seed % size_t(nx)), sy = int64_t((seed / size_t(nx)) % size_t(ny)),
                  sz = int64_t(seed / size_t(nx * ny));
    const size_t ws = work(sx, sy, sz);
    {
        const size_t deep = bucket_of(ws) / 8;
        std::vector<size_t> stack{ws}, part;
        in[ws] = 1;
        while (!stack.empty()) {
            const size_t w = stack.back();
            stack.pop_back();
            part.push_back(w);
            for (int k = 0; k < 14; ++k) {
                const size_t n = size_t(int64_t(w) + link.step(k));
                if (state[n] == 1 && !in[n] && bucket_of(n) > deep) {
                    in[n] = 1;
                    stack.push_back(n);
                }
            }
        }
        if (freudenthal_euler_characteristic(in, 1) != 1) {
            for (const size_t w : part) in[w] = 0;
            part.assign(1, ws);
            in[ws] = 1;
        }
        for (const size_t w : part) state[w] = 0;
        for (const size_t w : part)
            for (int k = 0; k < 14; ++k) {
                const size_t n = size_t(int64_t(w) + link.step(k));
                if (state[n] == 1) push(n);
            }
    }
    while (cur >= 0) {
        std::vector<size_t>& b = buckets[size_t(cur)];
        if (b.empty()) {
            --cur;
            continue;
        }
        const size_t w = b.back();
        b.pop_back();
        if (link.simple(in, w)) add(w);
        else state[w] = 3;
    }
    size_t closed = 0;
#pragma omp parallel for schedule(static) reduction(+ : closed)
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y)
            for (int64_t x = lo[0]; x <= hi[0]; ++x) {
                uint8_t& l = labels(x, y, z);
                if (l == kEndocast && !in[work(x, y, z)]) {
                    l = kBone;
                    ++closed;
                }
            }
    r.voxels_closed = closed;
    r.euler_after = euler_in_box(labels, kEndocast, lo, hi);
    return r;
}

}  // namespace endocast
