// Exact Euclidean distance transforms (Felzenszwalb & Huttenlocher 2012), separable in x, y, z.
//
// Performance notes. The x pass of a binary feature map is a 1-D nearest-feature scan (two sweeps
// per row), equal to the parabola envelope of 0/inf samples. The y and z passes gather a block of
// kBlock neighbouring lines at once (kBlock consecutive x), so every memory access reads or writes
// kBlock contiguous floats instead of one float per cache line (gathered as float: converting to
// double while gathering took a third of the pass; 32 or 64 lines per block were slower); the
// lines are then transformed one by one in double. Lines without any finite sample (nothing to
// propagate) and lines whose samples are all zero (nothing can decrease) are skipped. A "clamp"
// turns values above a bound into +inf after each pass: for thresholded transforms (ball
// morphology) this does not change which voxels are <= the bound (a parabola whose apex is above
// the bound is above it everywhere) and it lets whole lines be skipped far from the features. Every line is independent, so the result does not
// depend on the thread count.
#include "endocast/distance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace endocast {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();
constexpr int64_t kBlock = 16;  // lines gathered together in the y and z passes

// One line of the Felzenszwalb-Huttenlocher transform with sample spacing w (mm).
// in: f[0..n) (may be +inf; computed in double). out: d[0..n). v, z: scratch of size n and n+1;
// h: scratch of size n (the envelope's parabolas' values f[p] + w^2 p^2, kept so that they are
// computed once; the arithmetic is the textbook one, operation for operation).
void fh_line(const float* f, double* d, int64_t n, double w, int64_t* v, double* z, double* h) {
    const double w2 = w * w;
    const double w2x2 = 2.0 * w2;
    int64_t k = -1;
    for (int64_t q = 0; q < n; ++q) {
        if (!(double(f[q]) < kInf)) continue;
        const double fq = double(f[q]) + w2 * double(q) * double(q);
        double s = 0;
        while (k >= 0) {
            s = (fq - h[k]) / (w2x2 * double(q - v[k]));
            if (s <= z[k]) {
                --k;
            } else {
                break;
            }
        }
        if (k < 0) {
            k = 0;
            v[0] = q;
            h[0] = fq;
            z[0] = -kInf;
        } else {
            ++k;
            v[k] = q;
            h[k] = fq;
            z[k] = s;
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
        d[q] = w2 * dq * dq + double(f[v[j]]);
    }
}

// How a pass stores its results.
struct Store {
    float clamp = kInfF;  ///< values > clamp are stored as +inf
    bool sqrt = false;    ///< store sqrt(float(value)) (last pass of distance_transform)
    float operator()(double d) const {
        float v = static_cast<float>(d);
        if (v > clamp) v = kInfF;
        return sqrt ? std::sqrt(v) : v;
    }
};

// Generic x pass (lines are contiguous).
void pass_x(std::vector<float>& buf, const Dims& dims, double w, const Store& st) {
    const int64_t n = dims[0];
    const int64_t lines = dims[1] * dims[2];
#pragma omp parallel
    {
        std::vector<double> d(n), z(n + 1), h(n);
        std::vector<int64_t> v(n);
#pragma omp for schedule(static)
        for (int64_t line = 0; line < lines; ++line) {
            float* p = buf.data() + line * n;
            bool any_finite = false, any_nonzero = false;
            for (int64_t i = 0; i < n; ++i) {
                any_finite = any_finite || p[i] < kInfF;
                any_nonzero = any_nonzero || p[i] != 0.0f;
            }
            if (!any_finite || !any_nonzero) continue;  // all +inf or all 0: unchanged
            fh_line(p, d.data(), n, w, v.data(), z.data(), h.data());  // reads all of p before we write it
            for (int64_t i = 0; i < n; ++i) p[i] = st(d[i]);
        }
    }
}

// y (axis 1) or z (axis 2) pass, kBlock lines at a time.
void pass_yz(std::vector<float>& buf, const Dims& dims, int axis, double w, const Store& st) {
    const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
    const int64_t n = dims[axis];
    const int64_t stride = axis == 1 ? nx : nx * ny;
    // Blocks: axis 1 -> (z, x-block) with base x0 + nx*ny*z; axis 2 -> a range of the xy plane.
    const int64_t per_row = (nx + kBlock - 1) / kBlock;
    const int64_t blocks = axis == 1 ? per_row * nz : (nx * ny + kBlock - 1) / kBlock;
#pragma omp parallel
    {
        std::vector<float> lines(size_t(n * kBlock));
        std::vector<double> d(size_t(n * kBlock)), z(n + 1), h(n);
        std::vector<int64_t> v(n);
#pragma omp for schedule(static)
        for (int64_t blk = 0; blk < blocks; ++blk) {
            int64_t base, width;
            if (axis == 1) {
                const int64_t zz = blk / per_row, x0 = (blk % per_row) * kBlock;
                base = x0 + nx * ny * zz;
                width = std::min(kBlock, nx - x0);
            } else {
                base = blk * kBlock;
                width = std::min(kBlock, nx * ny - base);
            }
            for (int64_t i = 0; i < n; ++i) {
                const float* p = buf.data() + base + i * stride;
                for (int64_t b = 0; b < width; ++b) lines[size_t(b * n + i)] = p[b];
            }
            bool done[kBlock] = {};  // all +inf or all 0: unchanged
            bool any = false;
            for (int64_t b = 0; b < width; ++b) {
                const float* l = lines.data() + b * n;
                bool finite = false, nonzero = false;
                for (int64_t i = 0; i < n; ++i) {
                    finite = finite || l[i] < kInfF;
                    nonzero = nonzero || l[i] != 0.0f;
                }
                done[b] = !finite || !nonzero;
                if (done[b]) continue;
                any = true;
                fh_line(l, d.data() + b * n, n, w, v.data(), z.data(), h.data());
            }
            if (!any) continue;
            for (int64_t i = 0; i < n; ++i) {
                float* p = buf.data() + base + i * stride;
                for (int64_t b = 0; b < width; ++b) {
                    if (done[b]) continue;
                    p[b] = st(d[size_t(b * n + i)]);
                }
            }
        }
    }
}

void pass(std::vector<float>& buf, const Dims& dims, int axis, double w, const Store& st) {
    if (axis == 0) pass_x(buf, dims, w, st);
    else pass_yz(buf, dims, axis, w, st);
}

// The x pass of a binary feature map, written to out: squared distance along the row to the
// nearest feature (feature = (mask != 0) != invert). Equals fh_line on 0/inf samples.
void binary_pass_x(const Volume<uint8_t>& mask, bool invert, std::vector<float>& out, double w,
                   const Store& st) {
    const int64_t n = mask.nx();
    const int64_t lines = mask.ny() * mask.nz();
    const double w2 = w * w;
#pragma omp parallel
    {
        std::vector<int64_t> left(n);
#pragma omp for schedule(static)
        for (int64_t line = 0; line < lines; ++line) {
            const uint8_t* m = mask.data() + line * n;
            float* o = out.data() + line * n;
            int64_t last = -1;
            for (int64_t i = 0; i < n; ++i) {
                if ((m[i] != 0) != invert) last = i;
                left[i] = last;
            }
            if (last < 0) {
                std::fill(o, o + n, kInfF);
                continue;
            }
            int64_t next = -1;
            for (int64_t i = n - 1; i >= 0; --i) {
                if ((m[i] != 0) != invert) next = i;
                int64_t dist = -1;
                if (left[i] >= 0) dist = i - left[i];
                if (next >= 0 && (dist < 0 || next - i < dist)) dist = next - i;
                if (dist == 0) {
                    o[i] = 0.0f;
                } else {
                    const double dq = double(dist);
                    o[i] = st(w2 * dq * dq);
                }
            }
        }
    }
}

}  // namespace

void generalized_squared_distance(std::vector<float>& f, const Geometry& g) {
    if (f.size() != g.voxel_count())
        throw InvalidParameter("generalized_squared_distance: buffer holds " +
                               std::to_string(f.size()) + " values, geometry needs " +
                               std::to_string(g.voxel_count()));
    for (int axis = 0; axis < 3; ++axis) pass(f, g.dims, axis, g.spacing[axis], Store{});
}

namespace {

// Squared distance transform of a binary feature map with optional clamp and sqrt (see above).
Volume<float> binary_edt(const Volume<uint8_t>& mask, bool invert, float clamp, bool take_sqrt) {
    Volume<float> out;
    out.geometry() = mask.geometry();
    out.buffer().resize(mask.size());
    const Geometry& g = mask.geometry();
    Store st;
    st.clamp = clamp;
    binary_pass_x(mask, invert, out.buffer(), g.spacing[0], st);
    pass(out.buffer(), g.dims, 1, g.spacing[1], st);
    st.sqrt = take_sqrt;
    pass(out.buffer(), g.dims, 2, g.spacing[2], st);
    return out;
}

}  // namespace

Volume<float> squared_distance_transform_clamped(const Volume<uint8_t>& mask, bool invert,
                                                 float clamp_mm2) {
    return binary_edt(mask, invert, clamp_mm2, false);
}

Volume<float> squared_distance_transform(const Volume<uint8_t>& feature) {
    return binary_edt(feature, false, kInfF, false);
}

Volume<float> distance_transform(const Volume<uint8_t>& feature) {
    return binary_edt(feature, false, kInfF, true);
}

}  // namespace endocast
