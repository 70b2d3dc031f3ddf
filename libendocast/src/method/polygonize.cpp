// Stage 6, the paper's masked marching cubes (polygonize.h): the field meshed from the CT and the
// endocast region, at T or by the half-maximum rule (half_max.h).
#include "endocast/stages/polygonize.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "endocast/stages/components.h"
#include "endocast/errors.h"
#include "endocast/stages/marching_cubes.h"
#include "method/half_max.h"

namespace endocast {

const char* to_string(SurfaceMode m) { return m == SurfaceMode::HalfMax ? "half-max" : "iso"; }

template <class Sample>
PolygonizeResult polygonize(const Volume<Sample>& ct, const Volume<uint8_t>& labels,
                            const PolygonizeParams& p) {
    if (ct.size() != labels.size())
        throw InvalidParameter("polygonize: CT and label volumes differ in size");
    const double T = p.isovalue;
    if (!std::isfinite(T))
        throw InvalidParameter("polygonize: isovalue " + std::to_string(T) + ", expected finite");
    PolygonizeResult r;
    r.mask = Volume<uint8_t>(ct.geometry());
    {
        const uint8_t* __restrict l = labels.data();
        uint8_t* __restrict m = r.mask.data();
#pragma omp parallel for schedule(static)
        for (int64_t i = 0; i < int64_t(ct.size()); ++i) m[i] = l[i] == kEndocast ? 1 : 0;
    }
    r.fragments_removed = keep_largest_component(r.mask, Connectivity::Face6);
    r.holes_filled = fill_holes(r.mask, Connectivity::Face6);

    // Bounding box of the region, and every 8th region voxel in scan order for the median (per
    // slice in parallel: counts, prefix sums, then the samples; the same for any thread count).
    const Geometry& g = ct.geometry();
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    std::vector<size_t> slice_count(size_t(nz) + 1, 0);
    std::vector<std::array<int64_t, 6>> slice_box(static_cast<size_t>(nz));
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < nz; ++z) {
        std::array<int64_t, 6> b{nx, ny, nz, -1, -1, -1};
        size_t count = 0;
        for (int64_t y = 0; y < ny; ++y) {  // a row: its count (vectorized), then its first and last voxel
            const uint8_t* __restrict m = r.mask.data() + size_t(nx * (y + ny * z));
            size_t row = 0;
            for (int64_t x = 0; x < nx; ++x) row += m[x];
            if (!row) continue;
            count += row;
            int64_t a = 0, e = nx - 1;
            while (!m[a]) ++a;
            while (!m[e]) --e;
            b = {std::min(b[0], a), std::min(b[1], y), z, std::max(b[3], e), std::max(b[4], y), z};
        }
        slice_count[size_t(z) + 1] = count;
        slice_box[size_t(z)] = b;
    }
    std::array<int64_t, 3> lo{g.dims[0], g.dims[1], g.dims[2]}, hi{-1, -1, -1};
    for (int64_t z = 0; z < nz; ++z) {
        slice_count[size_t(z) + 1] += slice_count[size_t(z)];
        const auto& b = slice_box[size_t(z)];
        if (b[3] < 0) continue;
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], b[a]);
            hi[a] = std::max(hi[a], b[3 + a]);
        }
    }
    r.mask_voxels = slice_count[size_t(nz)];
    std::vector<float> inside_values((r.mask_voxels + 7) / 8);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < nz; ++z) {
        size_t rank = slice_count[size_t(z)];  // region voxels before this slice
        if (slice_count[size_t(z) + 1] == rank) continue;  // none in this slice
        const uint8_t* m = r.mask.data() + size_t(nx * ny * z);
        const Sample* c = ct.data() + size_t(nx * ny * z);
        for (int64_t k = 0; k < nx * ny; ++k) {
            if (!m[k]) continue;
            if ((rank & 7) == 0) inside_values[rank / 8] = c[k];
            ++rank;
        }
    }
    if (r.mask_voxels == 0) throw NoResult("polygonize: no voxel is labelled endocast");

    auto mid = inside_values.begin() + inside_values.size() / 2;
    std::nth_element(inside_values.begin(), mid, inside_values.end());
    const double median = *mid;
    if (p.surface == SurfaceMode::HalfMax) {
        Volume<float> field;
        if constexpr (std::is_same_v<Sample, float>) field = half_max_field(ct, labels, p, median, lo, hi, r);
        else field = half_max_field(to_float(ct), labels, p, median, lo, hi, r);
        r.mesh = isosurface(field, 0.0);
        return r;
    }
    const double floor_contrast = 1e-3 * std::max(1.0, std::fabs(T));
    const double contrast = std::max(T - median, floor_contrast);
    r.other_value = T + contrast;
    const float high = static_cast<float>(r.other_value);
    // Inside values must be strictly below T; a voxel of E at or above T (a detached bone fragment
    // in the cavity) is lowered just below it.
    const float low = static_cast<float>(T - floor_contrast);
    const float just_above = static_cast<float>(T + floor_contrast);

    // Sub-volume: bounding box plus one voxel on every side (outside samples are "outside").
    Geometry sg = g;
    for (int a = 0; a < 3; ++a) sg.dims[a] = hi[a] - lo[a] + 3;
    sg.origin = g.index_to_world(double(lo[0] - 1), double(lo[1] - 1), double(lo[2] - 1));
    Volume<float> field(sg, high);
    // A row at a time, over the part of it inside the CT (x0..x1 of the sub-volume): contiguous
    // reads and writes without a bounds test per voxel, which the compiler vectorizes.
    const int64_t x0 = std::max<int64_t>(0, 1 - lo[0]), x1 = std::min<int64_t>(sg.dims[0], nx - lo[0] + 1);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < sg.dims[2]; ++z)
        for (int64_t y = 0; y < sg.dims[1]; ++y) {
            const int64_t gy = y + lo[1] - 1, gz = z + lo[2] - 1;
            if (gy < 0 || gz < 0 || gy >= ny || gz >= nz || x1 <= x0) continue;
            const size_t i0 = ct.index(x0 + lo[0] - 1, gy, gz);
            const Sample* __restrict c = ct.data() + i0;
            const uint8_t* __restrict m = r.mask.data() + i0;
            float* __restrict f = field.data() + field.index(x0, y, z);
            for (int64_t k = 0; k < x1 - x0; ++k) {
                const float v = c[k];
                // Outside E: true bone (CT >= T) keeps its value, nudged strictly above T;
                // filled voids and "other" space (CT < T) are raised to T + contrast.
                f[k] = m[k] ? std::min(v, low) : (v >= T ? std::max(v, just_above) : high);
            }
        }
    r.mesh = isosurface(field, T);
    return r;
}

template PolygonizeResult polygonize<float>(const Volume<float>&, const Volume<uint8_t>&, const PolygonizeParams&);
template PolygonizeResult polygonize<int16_t>(const Volume<int16_t>&, const Volume<uint8_t>&, const PolygonizeParams&);

}  // namespace endocast
