#include "endocast/distance.h"

#include <cmath>
#include <limits>
#include <vector>

namespace endocast {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// One line of the Felzenszwalb-Huttenlocher transform with sample spacing w (mm).
// in: f[0..n) (double, may be +inf). out: d[0..n). v, z: scratch of size n and n+1.
void fh_line(const double* f, double* d, int64_t n, double w, int64_t* v, double* z) {
    const double w2 = w * w;
    int64_t k = -1;
    for (int64_t q = 0; q < n; ++q) {
        if (!(f[q] < kInf)) continue;
        const double fq = f[q] + w2 * double(q) * double(q);
        while (k >= 0) {
            const int64_t p = v[k];
            const double fp = f[p] + w2 * double(p) * double(p);
            const double s = (fq - fp) / (2.0 * w2 * double(q - p));
            if (s <= z[k]) {
                --k;
            } else {
                break;
            }
        }
        if (k < 0) {
            k = 0;
            v[0] = q;
            z[0] = -kInf;
        } else {
            const int64_t p = v[k];
            const double fp = f[p] + w2 * double(p) * double(p);
            ++k;
            v[k] = q;
            z[k] = (fq - fp) / (2.0 * w2 * double(q - p));
        }
        z[k + 1] = kInf;
    }
    if (k < 0) {
        for (int64_t q = 0; q < n; ++q) d[q] = kInf;
        return;
    }
    int64_t j = 0;
    for (int64_t q = 0; q < n; ++q) {
        while (z[j + 1] < double(q)) ++j;
        const double dq = double(q - v[j]);
        d[q] = w2 * dq * dq + f[v[j]];
    }
}

// Applies fh_line to every line along `axis` of the buffer.
void pass(std::vector<float>& buf, const Dims& dims, int axis, double w) {
    const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
    const int64_t n = dims[axis];
    const int64_t stride = axis == 0 ? 1 : (axis == 1 ? nx : nx * ny);
    // Lines are enumerated by the two other coordinates.
    const int64_t lines = (nx * ny * nz) / n;
#pragma omp parallel
    {
        std::vector<double> f(n), d(n), z(n + 1);
        std::vector<int64_t> v(n);
#pragma omp for schedule(static)
        for (int64_t line = 0; line < lines; ++line) {
            int64_t base;
            if (axis == 0) {
                base = line * nx;
            } else if (axis == 1) {
                const int64_t x = line % nx, zz = line / nx;
                base = x + nx * ny * zz;
            } else {
                base = line;  // (x, y) of the slice
            }
            bool any_finite = false;
            for (int64_t i = 0; i < n; ++i) {
                f[i] = buf[base + i * stride];
                any_finite = any_finite || f[i] < kInf;
            }
            if (!any_finite) continue;
            fh_line(f.data(), d.data(), n, w, v.data(), z.data());
            for (int64_t i = 0; i < n; ++i) buf[base + i * stride] = static_cast<float>(d[i]);
        }
    }
}

}  // namespace

void generalized_squared_distance(std::vector<float>& f, const Geometry& g) {
    if (f.size() != g.voxel_count())
        throw InvalidParameter("generalized_squared_distance: buffer holds " +
                               std::to_string(f.size()) + " values, geometry needs " +
                               std::to_string(g.voxel_count()));
    for (int axis = 0; axis < 3; ++axis) pass(f, g.dims, axis, g.spacing[axis]);
}

Volume<float> squared_distance_transform(const Volume<uint8_t>& feature) {
    Volume<float> out(feature.geometry());
    const float inf = std::numeric_limits<float>::infinity();
    const size_t n = feature.size();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(n); ++i) out[i] = feature[i] ? 0.0f : inf;
    generalized_squared_distance(out.buffer(), feature.geometry());
    return out;
}

Volume<float> distance_transform(const Volume<uint8_t>& feature) {
    Volume<float> out = squared_distance_transform(feature);
    const size_t n = out.size();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(n); ++i) out[i] = std::sqrt(out[i]);
    return out;
}

}  // namespace endocast
