// Exact Euclidean distance transforms (Felzenszwalb & Huttenlocher 2012), separable in x, y, z.
//
// Performance notes. The x pass of a binary feature map is a 1-D nearest-feature scan, equal to
// the parabola envelope of 0/inf samples. The y and z passes copy a block of kBlock neighbouring
// lines at once (kBlock consecutive x, kept interleaved as in memory), so every memory access reads
// or writes kBlock contiguous floats instead of one float per cache line; the lines are then
// transformed one by one in double (8, 32 or 64 lines per block were no faster). Lines without any
// finite sample (nothing to propagate) and lines whose samples are all zero (nothing can decrease)
// are skipped. A "clamp"
// turns values above a bound into +inf after each pass: for thresholded transforms (ball
// morphology) this does not change which voxels are <= the bound (a parabola whose apex is above
// the bound is above it everywhere) and it lets whole lines be skipped far from the features.
// A clamped y/z pass whose window (the samples within the clamp's reach, at most kMaxWindowHalf each
// side) is small, as in the void-fill closing, runs as a windowed minimum over whole rows in SIMD
// instead (pass_yz_window); the x pass of a binary map fills the gaps between features with copies
// of a table of the stored values. Every line is independent, so the result does not depend on the
// thread count; lines are handed out dynamically (lines skipped far from the features cost
// nothing, so equal halves were uneven: up to 0.2 s of one idle thread on the 512 phantom).
#include "endocast/stages/distance.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace endocast {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr float kInfF = std::numeric_limits<float>::infinity();
typedef float V4 __attribute__((vector_size(16)));  // four floats, one SSE register
constexpr uint32_t kInfBits = 0x7f800000u;  // the bit pattern of +inf (float)
constexpr int64_t kBlock = 16;  // lines gathered together in the y and z passes
// Widest window (samples each side) of the windowed pass: up to 32 it took 9-17 % less time than
// the envelope on cthead's bone (clamps of 180-1,000 mm^2 at 1 and 0.49 mm; 16 before).
constexpr int64_t kMaxWindowHalf = 32;
constexpr int64_t kStrip = 1024;        // xy-plane floats per strip of the windowed z pass

// One line of the Felzenszwalb-Huttenlocher transform with sample spacing w (mm).
// in: f[0..n) (may be +inf; computed in double). out: d[0..n). v, z: scratch of size n and n+1;
// h: scratch of size n (the envelope's parabolas' values f[p] + w^2 p^2, kept so that they are
// computed once; the arithmetic is the textbook one, operation for operation).
void fh_line(const float* f, int64_t fs, double* d, int64_t ds, int64_t n, double w, int64_t* v,
             double* z, double* h) {
    const double w2 = w * w;
    const double w2x2 = 2.0 * w2;
    int64_t k = -1;
    for (int64_t q = 0; q < n; ++q) {
        if (!(double(f[q * fs]) < kInf)) continue;
        const double fq = double(f[q * fs]) + w2 * double(q) * double(q);
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
        for (int64_t q = 0; q < n; ++q) d[q * ds] = kInf;
        return;
    }
    // Parabola j of the envelope is the lowest at the q with z[j] < q <= z[j + 1] (the textbook
    // loop advances j while z[j + 1] < q): a run of q per parabola, each value computed as there,
    // without a test of z per sample.
    int64_t q = 0;
    for (int64_t j = 0; j <= k && q < n; ++j) {
        const double zj = z[j + 1];  // the run's last q: floor(zj), within [q - 1, n - 1]
        const int64_t last = zj >= double(n - 1) ? n - 1 : zj < double(q) ? q - 1 : int64_t(std::floor(zj));
        const double fv = double(f[v[j] * fs]);
        const int64_t vj = v[j];
        for (; q <= last; ++q) {
            const double dq = double(q - vj);
            d[q * ds] = w2 * dq * dq + fv;
        }
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
void pass_x(float* buf, const Dims& dims, double w, const Store& st) {
    const int64_t n = dims[0];
    const int64_t lines = dims[1] * dims[2];
#pragma omp parallel
    {
        std::vector<double> d(n), z(n + 1), h(n);
        std::vector<int64_t> v(n);
#pragma omp for schedule(dynamic, 64)
        for (int64_t line = 0; line < lines; ++line) {
            float* p = buf + line * n;
            bool any_finite = false, any_nonzero = false;
            for (int64_t i = 0; i < n; ++i) {
                any_finite = any_finite || p[i] < kInfF;
                any_nonzero = any_nonzero || p[i] != 0.0f;
            }
            if (!any_finite || !any_nonzero) continue;  // all +inf or all 0: unchanged
            fh_line(p, 1, d.data(), 1, n, w, v.data(), z.data(), h.data());  // reads all of p before we write it
            for (int64_t i = 0; i < n; ++i) p[i] = st(d[i]);
        }
    }
}

// Half-width (samples) of the window that can hold a value <= clamp: w^2 k^2 > clamp beyond it.
// 0 when the pass is not clamped or the window is too wide for the windowed pass to pay off.
int64_t window_half_width(const Store& st, double w, int64_t n) {
    if (!(st.clamp < kInfF) || st.sqrt) return 0;
    const double k = std::floor(std::sqrt(double(st.clamp)) / w) + 1;  // +1: rounding margin
    return k >= 1 && k <= double(kMaxWindowHalf) && k < double(n) ? int64_t(k) : 0;
}

// The windowed y/z pass of a clamped transform: out = min over |k| <= K of f[i+k] + w^2 k^2, in
// float (every parabola whose apex is farther than K samples gives more than the clamp there, so
// the thresholds asked of a clamped transform come out as with the envelope, up to float rounding
// far inside the 1e-6 slack of the ball radius). It runs on whole rows: axis 1 a z slice at a
// time (ny rows of nx floats), axis 2 a strip of kStrip xy-plane floats across all z. The strip
// is copied, then each output row is the minimum of its 2K+1 neighbour rows, contiguous and in
// SIMD registers; no strided gathers (the z pass of the envelope reads 64 bytes per page).
void pass_yz_window(float* buf, const Dims& dims, int axis, double w, const Store& st,
                    int64_t K) {
    const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
    const int64_t n = dims[axis];
    const int64_t stride = axis == 1 ? nx : nx * ny;
    const int64_t width = axis == 1 ? nx : std::min<int64_t>(kStrip, nx * ny);
    const int64_t units = axis == 1 ? nz : (nx * ny + width - 1) / width;
    std::vector<float> cost(size_t(K + 1));
    for (int64_t k = 0; k <= K; ++k) cost[size_t(k)] = float(w * w * double(k) * double(k));
    const float clamp = st.clamp;
#pragma omp parallel
    {
        std::vector<float> rows(size_t(n * width));
#pragma omp for schedule(dynamic, 2)
        for (int64_t u = 0; u < units; ++u) {
            const int64_t base = axis == 1 ? u * nx * ny : u * width;
            const int64_t wd = axis == 1 ? nx : std::min(width, nx * ny - base);
            // All +inf or all 0: unchanged. The values are >= 0 or +inf, so on their bit patterns
            // "all zero" is an OR of 0 and "all +inf" an AND equal to +inf's exponent bits.
            uint32_t any_bits = 0, all_bits = ~uint32_t(0);
            for (int64_t i = 0; i < n; ++i) {
                float* r = rows.data() + i * wd;
                std::memcpy(r, buf + base + i * stride, size_t(wd) * sizeof(float));
                for (int64_t b = 0; b < wd; ++b) {
                    uint32_t bits;
                    std::memcpy(&bits, r + b, sizeof bits);
                    any_bits |= bits;
                    all_bits &= bits;
                }
            }
            if (any_bits == 0 || all_bits == kInfBits) continue;
            for (int64_t i = 0; i < n; ++i) {
                const int64_t k0 = std::max<int64_t>(-K, -i), k1 = std::min<int64_t>(K, n - 1 - i);
                const float* c = rows.data() + i * wd;
                float* p = buf + base + i * stride;
                // 16 floats at a time in four 4-float vectors (GCC/Clang vector extensions: plain
                // SSE2, no -march), kept in registers across the window (k = 0 is c itself).
                int64_t b = 0;
                for (; b + 16 <= wd; b += 16) {
                    V4 acc[4];
                    for (int j = 0; j < 4; ++j) std::memcpy(&acc[j], c + b + 4 * j, sizeof(V4));
                    for (int64_t k = k0; k <= k1; ++k) {
                        const float ckf = cost[size_t(k < 0 ? -k : k)];
                        const V4 ck = {ckf, ckf, ckf, ckf};
                        const float* l = rows.data() + (i + k) * wd + b;
                        for (int j = 0; j < 4; ++j) {
                            V4 v;
                            std::memcpy(&v, l + 4 * j, sizeof(V4));
                            v += ck;
                            acc[j] = v < acc[j] ? v : acc[j];
                        }
                    }
                    const V4 cl = {clamp, clamp, clamp, clamp}, inf = {kInfF, kInfF, kInfF, kInfF};
                    for (int j = 0; j < 4; ++j) {
                        const V4 out = acc[j] > cl ? inf : acc[j];
                        std::memcpy(p + b + 4 * j, &out, sizeof(V4));
                    }
                }
                for (; b < wd; ++b) {
                    float acc = c[b];
                    for (int64_t k = k0; k <= k1; ++k) {
                        const float v = rows[size_t((i + k) * wd + b)] + cost[size_t(k < 0 ? -k : k)];
                        acc = v < acc ? v : acc;
                    }
                    p[b] = acc > clamp ? kInfF : acc;
                }
            }
        }
    }
}

// y (axis 1) or z (axis 2) pass, kBlock lines at a time.
void pass_yz(float* buf, const Dims& dims, int axis, double w, const Store& st) {
    const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
    const int64_t n = dims[axis];
    if (const int64_t K = window_half_width(st, w, n)) {
        pass_yz_window(buf, dims, axis, w, st, K);
        return;
    }
    const int64_t stride = axis == 1 ? nx : nx * ny;
    // Blocks: axis 1 -> (z, x-block) with base x0 + nx*ny*z; axis 2 -> a range of the xy plane.
    const int64_t per_row = (nx + kBlock - 1) / kBlock;
    const int64_t blocks = axis == 1 ? per_row * nz : (nx * ny + kBlock - 1) / kBlock;
#pragma omp parallel
    {
        std::vector<float> lines(size_t(n * kBlock));
        std::vector<double> d(size_t(n * kBlock)), z(n + 1), h(n);
        std::vector<int64_t> v(n);
#pragma omp for schedule(dynamic, 8)
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
            // Rows copied as they lie (sample i of line b at i*kBlock + b): contiguous copies, of
            // a constant size for a full block (inlined, not a library call per row).
            if (width == kBlock) {
                for (int64_t i = 0; i < n; ++i)
                    std::memcpy(lines.data() + i * kBlock, buf + base + i * stride, kBlock * sizeof(float));
            } else {
                for (int64_t i = 0; i < n; ++i)
                    std::memcpy(lines.data() + i * kBlock, buf + base + i * stride, size_t(width) * sizeof(float));
            }
            bool done[kBlock] = {};  // all +inf or all 0: unchanged
            bool any = false;
            for (int64_t b = 0; b < width; ++b) {
                const float* l = lines.data() + b;
                bool finite = false, nonzero = false;
                for (int64_t i = 0; i < n; ++i) {
                    finite = finite || l[i * kBlock] < kInfF;
                    nonzero = nonzero || l[i * kBlock] != 0.0f;
                }
                done[b] = !finite || !nonzero;
                if (done[b]) continue;
                any = true;
                fh_line(l, kBlock, d.data() + b, kBlock, n, w, v.data(), z.data(), h.data());
            }
            if (!any) continue;
            for (int64_t i = 0; i < n; ++i) {
                float* p = buf + base + i * stride;
                const double* di = d.data() + i * kBlock;
                for (int64_t b = 0; b < width; ++b)
                    if (!done[b]) p[b] = st(di[b]);
            }
        }
    }
}

void pass(float* buf, const Dims& dims, int axis, double w, const Store& st) {
    if (axis == 0) pass_x(buf, dims, w, st);
    else pass_yz(buf, dims, axis, w, st);
}

// The x pass of a binary feature map, written to out: squared distance along the row to the
// nearest feature (feature = (mask != 0) != invert). Equals fh_line on 0/inf samples.
void binary_pass_x(const Volume<uint8_t>& mask, bool invert, float* out, double w,
                   const Store& st) {
    const int64_t n = mask.nx();
    const int64_t lines = mask.ny() * mask.nz();
    // value[d]: the stored value at distance d = 0..n samples (n + 1: +inf, no feature); reversed
    // copy rv[k] = value[n - k], so that runs of decreasing distance are copies too.
    std::vector<float> value(size_t(n + 2), kInfF), rv(size_t(n + 1));
    value[0] = 0.0f;
    for (int64_t d = 1; d <= n; ++d) value[size_t(d)] = st(w * w * double(d) * double(d));
    for (int64_t k = 0; k <= n; ++k) rv[size_t(k)] = value[size_t(n - k)];
    const bool want_nonzero = !invert;
    auto copy = [](float* to, const float* from, int64_t count) {
        if (count > 0) std::memcpy(to, from, size_t(count) * sizeof(float));
    };
#pragma omp parallel for schedule(dynamic, 64)
    for (int64_t line = 0; line < lines; ++line) {
        const uint8_t* m = mask.data() + line * n;
        float* o = out + line * n;
        // Walk from feature to feature; the gap between two is filled by two table copies (rising
        // from the left one up to the middle, falling to the right one).
        int64_t prev = -1;  // the last feature, -1 before the first
        int64_t i = 0;
        while (true) {
            int64_t f = i;
            while (f < n && (m[f] != 0) != want_nonzero) ++f;
            if (f == n) {
                if (prev < 0) std::fill(o, o + n, kInfF);        // no feature on the line
                else copy(o + prev + 1, value.data() + 1, n - prev - 1);  // trailing gap
                break;
            }
            if (prev < 0) {
                copy(o, rv.data() + n - f, f);  // leading gap: distance f - j
            } else {
                const int64_t mid = prev + (f - prev) / 2;  // ties go to the left feature: same value
                copy(o + prev + 1, value.data() + 1, mid - prev);
                copy(o + mid + 1, rv.data() + n - f + mid + 1, f - mid - 1);
            }
            o[f] = 0.0f;
            prev = f;
            i = f + 1;
        }
    }
}

}  // namespace

void generalized_squared_distance(std::vector<float>& f, const Geometry& g) {
    if (f.size() != g.voxel_count())
        throw InvalidParameter("generalized_squared_distance: buffer holds " +
                               std::to_string(f.size()) + " values, geometry needs " +
                               std::to_string(g.voxel_count()));
    for (int axis = 0; axis < 3; ++axis) pass(f.data(), g.dims, axis, g.spacing[axis], Store{});
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
    binary_pass_x(mask, invert, out.data(), g.spacing[0], st);
    pass(out.data(), g.dims, 1, g.spacing[1], st);
    st.sqrt = take_sqrt;
    pass(out.data(), g.dims, 2, g.spacing[2], st);
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
