// The half-maximum-height field: local thresholds on a band around the cavity, voxels re-decided by them (half_max.h).
#include "half_max.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <vector>

#include "endocast/stages/components.h"
#include "endocast/errors.h"
#include "kernels/freudenthal.h"
#include "kernels/max_filter.h"

namespace endocast {
namespace {

// Sorted, duplicate-free concatenation of per-part lists (the same for any thread count).
std::vector<size_t> merge_sorted(std::vector<std::vector<size_t>>& parts) {
    std::vector<size_t> all;
    size_t n = 0;
    for (const auto& v : parts) n += v.size();
    all.reserve(n);
    for (auto& v : parts) {
        all.insert(all.end(), v.begin(), v.end());
        std::vector<size_t>().swap(v);
    }
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    return all;
}

// The box the half-maximum surface is worked out in: the region's box plus a margin, which may
// reach beyond the volume. Voxel w of the box is (x, y, z) = (w % nx, w / nx % ny, w / (nx ny)).
struct WorkBox {
    Geometry geo;
    int64_t nx = 0, ny = 0, nz = 0;
    int64_t off[3] = {0, 0, 0};  // box voxel (0, 0, 0) in volume indices
    const Volume<float>* ct = nullptr;

    void coords(size_t w, int64_t& x, int64_t& y, int64_t& z) const {
        x = int64_t(w % size_t(nx));
        y = int64_t((w / size_t(nx)) % size_t(ny));
        z = int64_t(w / size_t(nx * ny));
    }
    // The volume index of box voxel w; false when it lies outside the volume.
    bool global(size_t w, size_t& gi) const {
        int64_t x, y, z;
        coords(w, x, y, z);
        x += off[0], y += off[1], z += off[2];
        if (!ct->contains(x, y, z)) return false;
        gi = ct->index(x, y, z);
        return true;
    }
    // f(w) for every voxel of the box, slices in parallel.
    template <class F>
    void for_each(F&& f) const {
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < nz; ++z)
            for (size_t w = size_t(nx * ny * z), e = w + size_t(nx * ny); w < e; ++w) f(w);
    }
    // The voxels w (ascending) for which pred(w) holds; the same for any thread count.
    template <class P>
    std::vector<size_t> select(P&& pred) const {
        std::vector<std::vector<size_t>> parts(static_cast<size_t>(nz));
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < nz; ++z)
            for (size_t w = size_t(nx * ny * z), e = w + size_t(nx * ny); w < e; ++w)
                if (pred(w)) parts[size_t(z)].push_back(w);
        return merge_sorted(parts);
    }
    // f(q) for the 26-neighbours q of w inside the box.
    template <class F>
    void neighbours(size_t w, F&& f) const {
        int64_t x, y, z;
        coords(w, x, y, z);
        for (int64_t dz = -1; dz <= 1; ++dz)
            for (int64_t dy = -1; dy <= 1; ++dy)
                for (int64_t dx = -1; dx <= 1; ++dx) {
                    if (!dx && !dy && !dz) continue;
                    const int64_t a = x + dx, b = y + dy, c = z + dz;
                    if (a < 0 || b < 0 || c < 0 || a >= nx || b >= ny || c >= nz) continue;
                    f(size_t(a + nx * (b + ny * c)));
                }
    }
};


double median_of(std::vector<float>& v) {
    if (v.empty()) return 0;
    auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

// Band: K layers of 26-neighbours on each side of E's boundary (layer[w] = 1..K, 0 outside);
// returns the band's voxels, ascending.
std::vector<size_t> boundary_band(const WorkBox& box, const Volume<uint8_t>& region, int K, Volume<uint8_t>& layer) {
    std::vector<size_t> band;
    std::vector<size_t> prev = box.select([&](size_t w) {
        bool edge = false;
        box.neighbours(w, [&](size_t q) { edge = edge || region[q] != region[w]; });
        return edge;
    });
    for (size_t w : prev) layer[w] = 1;
    band = prev;
    constexpr int64_t kParts = 64;
    for (int k = 2; k <= K && !prev.empty(); ++k) {
        std::vector<std::vector<size_t>> next(kParts);
#pragma omp parallel for schedule(static)
        for (int64_t part = 0; part < kParts; ++part) {
            const size_t b = prev.size() * size_t(part) / kParts, e = prev.size() * size_t(part + 1) / kParts;
            for (size_t i = b; i < e; ++i)
                box.neighbours(prev[i], [&](size_t q) {
                    if (!layer[q]) next[size_t(part)].push_back(q);
                });
        }
        prev = merge_sorted(next);
        for (size_t w : prev) layer[w] = uint8_t(k);
        band.insert(band.end(), prev.begin(), prev.end());
    }
    std::sort(band.begin(), band.end());
    return band;
}

// Local bone peak b: the largest CT within peak_radius_voxels (of the smallest spacing, as mm)
// among voxels neither in E nor "other"/unlabelled - the peak of this edge, not of thicker bone
// further away (a thin inner table next to a thick one would leak into the diploe).
Volume<float> bone_peaks(const WorkBox& box, const Volume<float>& ct, const Volume<uint8_t>& labels,
                         const Volume<uint8_t>& region, const PolygonizeParams& p) {
    const Geometry& g = ct.geometry();
    Volume<float> f(box.geo, -std::numeric_limits<float>::infinity());
    box.for_each([&](size_t w) {
        size_t gi;
        if (region[w] || !box.global(w, gi)) return;
        if (labels[gi] != kOther && labels[gi] != kUnlabelled) f[w] = ct[gi];
    });
    const double hmin = g.smallest_spacing();
    for (int a = 0; a < 3; ++a) {
        const int rad = std::max(1, int(std::ceil(p.peak_radius_voxels * hmin / g.spacing[a] - 1e-9)));
        max_filter_axis(f, a, rad);
    }
    return f;
}

// The local thresholds on the band, written into f (which holds the bone peaks on entry): tau =
// (c + b) / 2 where there is a bone edge (b - c >= (T - c) / 2); band voxels further from bone
// take the mean tau of their known neighbours, layer after layer; T where none is known; then
// smoothed. Sets r.half_max's threshold range and median; returns how many fell back to T.
size_t local_thresholds(const WorkBox& box, const std::vector<size_t>& band, double c, double T, float floor_contrast,
                        const PolygonizeParams& p, Volume<float>& f, PolygonizeResult& r) {
    const int K = p.band_voxels;
    const int64_t nb = int64_t(band.size());
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    const double min_edge = std::max(0.5 * (T - c), double(floor_contrast));
    std::vector<float> tau(band.size());
    std::vector<uint8_t> known(band.size());
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < nb; ++i) {
        const double b = f[band[size_t(i)]];
        known[size_t(i)] = b - c >= min_edge;
        tau[size_t(i)] = static_cast<float>(known[size_t(i)] ? 0.5 * (c + b) : T);
    }
    // f holds tau at known band voxels and NaN elsewhere, so a lookup needs no search.
    std::fill(f.data(), f.data() + f.size(), kNaN);
    auto store = [&] {
#pragma omp parallel for schedule(static)
        for (int64_t i = 0; i < nb; ++i) f[band[size_t(i)]] = known[size_t(i)] ? tau[size_t(i)] : kNaN;
    };
    // Mean of the known values around band voxel i (itself included when known); false if none.
    auto neighbourhood_mean = [&](int64_t i, float& out) {
        double sum = known[size_t(i)] ? tau[size_t(i)] : 0.0;
        int n = known[size_t(i)] ? 1 : 0;
        box.neighbours(band[size_t(i)], [&](size_t q) {
            if (std::isnan(f[q])) return;
            sum += f[q];
            ++n;
        });
        if (n) out = static_cast<float>(sum / n);
        return n > 0;
    };
    store();
    for (int pass = 0; pass < 2 * K + 2; ++pass) {
        std::vector<float> next(tau);
        std::vector<uint8_t> now(known);
        size_t grown = 0;
#pragma omp parallel for schedule(static) reduction(+ : grown)
        for (int64_t i = 0; i < nb; ++i) {
            if (known[size_t(i)] || !neighbourhood_mean(i, next[size_t(i)])) continue;
            now[size_t(i)] = 1;
            ++grown;
        }
        if (!grown) break;
        tau.swap(next);
        known.swap(now);
        store();
    }
    size_t fallback = 0;
    for (int64_t i = 0; i < nb; ++i) fallback += !known[size_t(i)];
    // Smoothing: each known voxel takes the mean of the known voxels around it (3x3x3).
    for (int pass = 0; pass < p.smoothing_passes; ++pass) {
        std::vector<float> next(tau);
#pragma omp parallel for schedule(static)
        for (int64_t i = 0; i < nb; ++i)
            if (known[size_t(i)]) neighbourhood_mean(i, next[size_t(i)]);
        tau.swap(next);
        store();
    }
    for (int64_t i = 0; i < nb; ++i) f[band[size_t(i)]] = tau[size_t(i)];  // fallbacks too
    if (!tau.empty()) {
        r.half_max.threshold_min = *std::min_element(tau.begin(), tau.end());
        r.half_max.threshold_max = *std::max_element(tau.begin(), tau.end());
        r.half_max.threshold_median = median_of(tau);  // reorders tau: last use
    } else {
        r.half_max.threshold_min = r.half_max.threshold_max = r.half_max.threshold_median = T;
    }
    return fallback;
}

// Channels: filled voids (bone-labelled below T) joined to "other" space through filled voids -
// foramina, cracks, sutures (channel = 2). The cavity does not grow into them (a sheet grown into
// a crack has holes in it: handles). A filled void that reaches the box's edge is taken as joined
// to "other" beyond it: a foramen's plug whose canal meets the outside below the box (the skull
// base's foramina lacera run 25 mm through the bone), or the diploe, which the cavity must not
// enter either.
Volume<uint8_t> channels(const WorkBox& box, const Volume<float>& ct, const Volume<uint8_t>& labels,
                         const Volume<uint8_t>& region, double T) {
    auto label_at = [&](size_t w) {
        size_t gi;
        return box.global(w, gi) ? labels[gi] : uint8_t(kUnlabelled);
    };
    Volume<uint8_t> channel(box.geo, 0);
    box.for_each([&](size_t w) {
        size_t gi;
        if (!region[w] && box.global(w, gi) && labels[gi] == kBone && ct[gi] < T) channel[w] = 1;
    });
    {
        std::vector<size_t> stack = box.select([&](size_t w) {
            if (!channel[w]) return false;
            int64_t x, y, z;
            box.coords(w, x, y, z);
            if (x == 0 || y == 0 || z == 0 || x == box.nx - 1 || y == box.ny - 1 || z == box.nz - 1) return true;
            bool seed = false;
            box.neighbours(w, [&](size_t q) { seed = seed || label_at(q) == kOther; });
            return seed;
        });
        for (size_t w : stack) channel[w] = 2;
        while (!stack.empty()) {
            const size_t u = stack.back();
            stack.pop_back();
            box.neighbours(u, [&](size_t q) {
                if (channel[q] != 1) return;
                channel[q] = 2;
                stack.push_back(q);
            });
        }
    }

    return channel;
}

// Re-classification: the band by tau, the rest as segmented at T. Inside E a band voxel at or
// above tau leaves the cavity. Outside E a voxel with CT < tau may join (not "other"/unlabelled,
// not next to "other" - bone beyond an opening's cut plane keeps its label and the cavity would
// creep along the canal's wall around the cut -, not a channel); it joins growing uphill, from
// a cavity face-neighbour whose CT is not above its own, so that the cavity stops at the edge's
// peak and never crosses a thin wall into what lies behind it. Both only where the surface's
// topology stays as segmented at T (simple points; without this cthead's surface had ~60
// small handles along the noisy brain-bone edge). Returns the cavity (largest piece, holes filled).
Volume<uint8_t> reclassify(const WorkBox& box, const Volume<float>& ct, const Volume<uint8_t>& labels,
                           const Volume<uint8_t>& region, const Volume<uint8_t>& layer, const Volume<float>& f,
                           Volume<uint8_t> channel, int K) {
    auto label_at = [&](size_t w) {
        size_t gi;
        return box.global(w, gi) ? labels[gi] : uint8_t(kUnlabelled);
    };
    Volume<uint8_t> cav(box.geo, 0);
    std::vector<size_t> cand = box.select([&](size_t w) {
        size_t gi;
        if (!box.global(w, gi)) return false;
        if (!layer[w] || region[w]) {
            cav[w] = region[w];
            return false;
        }
        const uint8_t l = labels[gi];
        if (l == kOther || l == kUnlabelled || channel[w] == 2 || !(ct[gi] < f[w])) return false;
        bool near_other = false;
        box.neighbours(w, [&](size_t q) { near_other = near_other || label_at(q) == kOther; });
        return !near_other;
    });
    channel = Volume<uint8_t>();  // release
    auto ct_at = [&](size_t w) {  // w inside the volume (a candidate or a cavity voxel)
        size_t gi = 0;
        box.global(w, gi);
        return ct[gi];
    };
    const int64_t steps[6] = {1, -1, box.nx, -box.nx, box.nx * box.ny, -box.nx * box.ny};
    const FreudenthalLink link(box.nx, box.ny);
    // Rounds of changes; within a round the voxels go by the parity of (x, y, z): two voxels of one
    // parity class are not neighbours, so each class is decided at once, in parallel, and a voxel
    // changes side only where that keeps the surface's topology (a simple point: no new handle,
    // hole or piece). `ok(w)` is the other condition; `value` the side it moves to.
    auto change = [&](const std::vector<size_t>& list, uint8_t value, auto&& ok) {
        std::array<std::vector<size_t>, 8> classes;  // by parity, once; list order kept in each
        for (const size_t w : list) {
            int64_t x, y, z;
            box.coords(w, x, y, z);
            classes[size_t((x & 1) | ((y & 1) << 1) | ((z & 1) << 2))].push_back(w);
        }
        for (int round = 0; round < 4 * K; ++round) {
            bool changed = false;
            for (std::vector<size_t>& c : classes) {
                std::vector<uint8_t> done(c.size(), 0);
#pragma omp parallel for schedule(static)
                for (int64_t i = 0; i < int64_t(c.size()); ++i)
                    done[size_t(i)] = ok(c[size_t(i)]) && link.simple(cav, c[size_t(i)]);
                std::vector<size_t> rest;
                for (size_t i = 0; i < c.size(); ++i) {
                    if (done[i]) cav[c[i]] = value;
                    else rest.push_back(c[i]);
                }
                changed = changed || rest.size() != c.size();
                c.swap(rest);
            }
            if (!changed) break;
        }
    };
    // Inside E: band voxels at or above tau leave the cavity, from its boundary inward.
    change(box.select([&](size_t w) {
               size_t gi;
               return region[w] && layer[w] && box.global(w, gi) && !(ct[gi] < f[w]);
           }),
           0, [](size_t) { return true; });
    // Outside E: candidates join growing uphill, from a cavity face-neighbour not brighter.
    change(cand, 1, [&](size_t w) {
        const float v = ct_at(w);
        for (int64_t s : steps) {
            const size_t q = size_t(int64_t(w) + s);  // the box's margin keeps q inside it
            if (cav[q] && ct_at(q) <= v) return true;
        }
        return false;
    });
    keep_largest_component(cav, Connectivity::Face6);
    fill_holes(cav, Connectivity::Face6);
    return cav;
}

}  // namespace

Volume<float> half_max_field(const Volume<float>& ct, const Volume<uint8_t>& labels,
                             const PolygonizeParams& p, double region_median,
                             const std::array<int64_t, 3>& lo, const std::array<int64_t, 3>& hi,
                             PolygonizeResult& r) {
    if (p.band_voxels < 1 || p.band_voxels > 100)
        throw InvalidParameter("polygonize: half-max band of " + std::to_string(p.band_voxels) +
                               " voxels, expected 1..100");
    if (p.smoothing_passes < 0 || !(p.peak_radius_voxels > 0))
        throw InvalidParameter("polygonize: half-max smoothing passes >= 0 and peak radius > 0 expected");
    const Geometry& g = ct.geometry();
    const double T = p.isovalue;
    const int K = p.band_voxels;
    const float floor_contrast = static_cast<float>(1e-3 * std::max(1.0, std::fabs(T)));

    // Work box: the region's box plus the band and one layer (the surface closes inside it).
    const int64_t M = K + 1;
    WorkBox box;
    box.geo = g;
    for (int a = 0; a < 3; ++a) {
        box.geo.dims[a] = hi[a] - lo[a] + 1 + 2 * M;
        box.off[a] = lo[a] - M;
    }
    box.geo.origin = g.index_to_world(double(box.off[0]), double(box.off[1]), double(box.off[2]));
    box.nx = box.geo.dims[0], box.ny = box.geo.dims[1], box.nz = box.geo.dims[2];
    box.ct = &ct;
    const Geometry& wg = box.geo;
    Volume<uint8_t> region(wg, 0);  // E
    box.for_each([&](size_t w) {
        size_t gi;
        if (box.global(w, gi)) region[w] = r.mask[gi];
    });

    Volume<uint8_t> layer(wg, 0);
    const std::vector<size_t> band = boundary_band(box, region, K, layer);

    // Cavity level c: median CT of E's core (E beyond the band).
    double c = region_median;
    {
        std::vector<float> core;
        for (size_t w : box.select([&](size_t w) { return region[w] && !layer[w]; })) {
            size_t gi;
            if (box.global(w, gi)) core.push_back(ct[gi]);
        }
        if (core.size() >= 64) c = median_of(core);
    }

    Volume<float> f = bone_peaks(box, ct, labels, region, p);
    const size_t fallback = local_thresholds(box, band, c, T, floor_contrast, p, f, r);
    const double tau_med = r.half_max.threshold_median;
    const Volume<uint8_t> cav = reclassify(box, ct, labels, region, layer, f, channels(box, ct, labels, region, T), K);

    // The field CT - tau (tau = median tau beyond the band); non-cavity voxels below tau, "other"
    // and unlabelled ones are raised to tau - c above it, cavity voxels kept strictly below.
    std::vector<size_t> added(static_cast<size_t>(box.nz), 0), removed(added), kept(added);
    box.for_each([&](size_t w) {
        const float t = layer[w] ? f[w] : static_cast<float>(tau_med);
        const float high = std::max(static_cast<float>(t - c), floor_contrast);
        size_t gi;
        if (!box.global(w, gi)) {
            f[w] = high;
            return;
        }
        const size_t z = w / size_t(box.nx * box.ny);  // one slice per thread at a time
        added[z] += cav[w] && !region[w];
        removed[z] += region[w] && !cav[w];
        const float v = ct[gi];
        if (cav[w]) {
            f[w] = std::min(v - t, -floor_contrast);
            r.mask[gi] = 1;
            ++kept[z];
            return;
        }
        r.mask[gi] = 0;
        const uint8_t l = labels[gi];
        f[w] = (l == kOther || l == kUnlabelled || v < t) ? high : std::max(v - t, floor_contrast);
    });
    auto total = [](const std::vector<size_t>& v) { return std::accumulate(v.begin(), v.end(), size_t(0)); };
    if (total(kept) == 0) throw NoResult("polygonize: no cavity voxel is below the half-maximum thresholds");
    r.mask_voxels = total(kept);
    r.other_value = tau_med + (tau_med - c);
    r.half_max.cavity_level = c;
    r.half_max.band_voxels = band.size();
    r.half_max.fallback_voxels = fallback;
    r.half_max.voxels_added = total(added);
    r.half_max.voxels_removed = total(removed);
    return f;
}

}  // namespace endocast
