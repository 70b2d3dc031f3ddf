// Crop and block-average downsampling (resample.h). Both are plain loops over the output grid,
// x fastest; the geometry is derived from Geometry::index_to_world so rotated and flipped
// directions are handled by the same arithmetic as everywhere else.
#include "endocast/stages/resample.h"

#include <algorithm>
#include <limits>

namespace endocast {

std::string to_string(const CropBox& b) {
    std::string s;
    for (int a = 0; a < 3; ++a) s += std::to_string(b.lo[a]) + " ";
    for (int a = 0; a < 3; ++a) s += std::to_string(b.hi[a]) + (a < 2 ? " " : "");
    return s;
}

void check_crop_box(const CropBox& box, const Dims& dims) {
    for (int a = 0; a < 3; ++a)
        if (box.lo[a] < 0 || box.lo[a] >= box.hi[a] || box.hi[a] > dims[a])
            throw InvalidParameter(
                "crop box " + to_string(box) + " (X0 Y0 Z0 X1 Y1 Z1, voxels, X1 exclusive) does not "
                "fit a volume of " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
                " x " + std::to_string(dims[2]) + " voxels, expected 0 <= X0 < X1 <= " +
                std::to_string(dims[0]) + " (likewise Y, Z)");
}

Geometry cropped_geometry(const Geometry& g, const CropBox& box) {
    check_crop_box(box, g.dims);
    Geometry out = g;
    out.dims = box.size();
    out.origin = g.index_to_world(double(box.lo[0]), double(box.lo[1]), double(box.lo[2]));
    return out;
}

Geometry downsampled_geometry(const Geometry& g, int factor) {
    if (factor < 1)
        throw InvalidParameter("downsample factor " + std::to_string(factor) +
                               ", expected an integer >= 1");
    Geometry out = g;
    const double c = 0.5 * double(factor - 1);
    out.origin = g.index_to_world(c, c, c);
    for (int a = 0; a < 3; ++a) {
        out.dims[a] = (g.dims[a] + factor - 1) / factor;
        out.spacing[a] = g.spacing[a] * factor;
    }
    return out;
}

template <class T>
Volume<T> crop(const Volume<T>& v, const CropBox& box) {
    Volume<T> out(cropped_geometry(v.geometry(), box));
    const Dims d = out.dims();
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y) {
            const T* src = &v(box.lo[0], box.lo[1] + y, box.lo[2] + z);
            std::copy(src, src + d[0], &out(0, y, z));
        }
    return out;
}
template Volume<float> crop<float>(const Volume<float>&, const CropBox&);
template Volume<uint8_t> crop<uint8_t>(const Volume<uint8_t>&, const CropBox&);
template Volume<int16_t> crop<int16_t>(const Volume<int16_t>&, const CropBox&);

Volume<uint8_t> uncrop(const Volume<uint8_t>& part, const Geometry& whole, const CropBox& box, uint8_t fill) {
    check_crop_box(box, whole.dims);
    const Dims d = box.size();
    if (part.dims() != d)
        throw InvalidParameter("uncrop: a part of " + std::to_string(part.dims()[0]) + " x " +
                               std::to_string(part.dims()[1]) + " x " + std::to_string(part.dims()[2]) +
                               " voxels for the box " + to_string(box) + ", expected its size");
    Volume<uint8_t> out(whole, fill);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y) {
            const uint8_t* src = &part(0, y, z);
            std::copy(src, src + d[0], &out(box.lo[0], box.lo[1] + y, box.lo[2] + z));
        }
    return out;
}

Volume<float> downsample(const Volume<float>& v, int factor) {
    Volume<float> out(downsampled_geometry(v.geometry(), factor));
    const Dims in = v.dims(), d = out.dims();
    const int64_t f = factor;
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x) {
                double sum = 0;
                int64_t n = 0;
                const int64_t z1 = std::min(in[2], (z + 1) * f), y1 = std::min(in[1], (y + 1) * f),
                              x1 = std::min(in[0], (x + 1) * f);
                for (int64_t k = z * f; k < z1; ++k)
                    for (int64_t j = y * f; j < y1; ++j)
                        for (int64_t i = x * f; i < x1; ++i, ++n) sum += v(i, j, k);
                out(x, y, z) = static_cast<float>(sum / double(n));
            }
    return out;
}

Geometry shrunk_geometry(const Geometry& input, const ShrinkParams& s) {
    Geometry g = s.crop ? cropped_geometry(input, *s.crop) : input;
    return s.downsample == 1 ? g : downsampled_geometry(g, s.downsample);
}

Volume<float> shrink(Volume<float> v, const ShrinkParams& s) {
    shrunk_geometry(v.geometry(), s);  // checks the box and factor before any copy
    if (s.crop) v = crop(v, *s.crop);
    if (s.downsample != 1) v = downsample(v, s.downsample);
    return v;
}

CropBox bounding_box_above(const Volume<float>& v, double threshold, int64_t margin) {
    const Dims d = v.dims();
    CropBox b;
    b.lo = {std::numeric_limits<int64_t>::max(), std::numeric_limits<int64_t>::max(),
            std::numeric_limits<int64_t>::max()};
    b.hi = {-1, -1, -1};
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x) {
                if (!(v(x, y, z) > threshold)) continue;
                const int64_t p[3] = {x, y, z};
                for (int a = 0; a < 3; ++a) {
                    b.lo[a] = std::min(b.lo[a], p[a]);
                    b.hi[a] = std::max(b.hi[a], p[a] + 1);
                }
            }
    if (b.hi[0] < 0)
        throw NoResult("no voxel is above " + std::to_string(threshold) +
                       ", so there is no object to crop to");
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::max<int64_t>(0, b.lo[a] - margin);
        b.hi[a] = std::min<int64_t>(d[a], b.hi[a] + margin);
    }
    return b;
}

}  // namespace endocast
