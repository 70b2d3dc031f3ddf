#pragma once
// Helpers of the anatomical phantoms' tests (skull base, mouse): phantom-frame points in the
// world, the CT between voxels, independent checks of the truth (a stratified Monte Carlo volume,
// a brute-force distance to the surface) and the independence of the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <random>

#include "endocast/phantom.h"

namespace endocast::testing {

/// World point of the phantom-frame point q.
inline Vec3 to_world(const PhantomResult& r, const Vec3& q) {
    const auto& R = r.cavity_rotation;
    const Vec3& c = r.cavity_centre_world;
    return {c[0] + R[0] * q[0] + R[1] * q[1] + R[2] * q[2], c[1] + R[3] * q[0] + R[4] * q[1] + R[5] * q[2],
            c[2] + R[6] * q[0] + R[7] * q[1] + R[8] * q[2]};
}

inline Vec3 along(const Vec3& c, const Vec3& u, double t) { return {c[0] + t * u[0], c[1] + t * u[1], c[2] + t * u[2]}; }

/// Trilinear interpolation of the CT at a world point; -2000 where a neighbour is outside the grid.
inline double trilinear(const PhantomResult& r, const Vec3& w) {
    const Vec3 x = r.ct.geometry().world_to_index(w);
    const int64_t i = static_cast<int64_t>(std::floor(x[0])), j = static_cast<int64_t>(std::floor(x[1])),
                  k = static_cast<int64_t>(std::floor(x[2]));
    if (!r.ct.contains(i, j, k) || !r.ct.contains(i + 1, j + 1, k + 1)) return -2000;
    const double fx = x[0] - i, fy = x[1] - j, fz = x[2] - k;
    double v = 0;
    for (int c = 0; c < 8; ++c) {
        const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
        v += (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz) * r.ct(i + dx, j + dy, k + dz);
    }
    return v;
}

/// Stratified Monte Carlo volume (mL) of {inside}: one uniform point in each cube of side `cell`
/// mm of the phantom-frame box [lo, lo + n cell] covering [lo, hi], in parallel, keyed by seed
/// and the cube's index. Its standard error is about cell^3 sqrt(boundary cubes / 4).
inline double stratified_volume_ml(const Vec3& lo, const Vec3& hi, double cell, uint64_t seed,
                                   const std::function<bool(const Vec3&)>& inside) {
    int64_t n[3];
    for (int a = 0; a < 3; ++a) n[a] = static_cast<int64_t>(std::ceil((hi[a] - lo[a]) / cell));
    const int64_t total = n[0] * n[1] * n[2];
    int64_t count = 0;
#pragma omp parallel for reduction(+ : count) schedule(dynamic, 4096)
    for (int64_t c = 0; c < total; ++c) {
        std::mt19937_64 rng(seed ^ (static_cast<uint64_t>(c) * 0x9E3779B97F4A7C15ULL));
        std::uniform_real_distribution<double> u(0.0, 1.0);
        const int64_t x = c % n[0], y = (c / n[0]) % n[1], z = c / (n[0] * n[1]);
        const Vec3 q{lo[0] + (x + u(rng)) * cell, lo[1] + (y + u(rng)) * cell, lo[2] + (z + u(rng)) * cell};
        if (inside(q)) ++count;
    }
    return static_cast<double>(count) * cell * cell * cell / 1000.0;
}

/// Distance from q to the nearest change of `inside` found by bisection along the edges of a grid
/// of step h over the cube q +- half (the surface's points found lie on it, h apart, so the
/// result exceeds the true distance by about h^2 / (8 radius of curvature)); 1e9 when none.
inline double brute_force_distance(const Vec3& q, double half, double h,
                                   const std::function<bool(const Vec3&)>& inside) {
    const int n = static_cast<int>(std::ceil(2 * half / h));
    double best = 1e9;
    for (int a = 0; a < 3; ++a)
        for (int x = 0; x <= n; ++x)
            for (int y = 0; y <= n; ++y) {
                bool prev = false;
                Vec3 wp{};
                for (int z = 0; z <= n; ++z) {
                    Vec3 w = q;
                    const int idx[3] = {x, y, z};
                    for (int b = 0; b < 3; ++b) w[(a + b) % 3] += -half + idx[b] * h;
                    const bool in = inside(w);
                    if (z > 0 && in != prev) {
                        Vec3 lo = wp, hi = w;
                        for (int it = 0; it < 30; ++it) {
                            const Vec3 m{(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
                            (inside(m) == prev ? lo : hi) = m;
                        }
                        best = std::min(best, std::hypot(lo[0] - q[0], lo[1] - q[1], lo[2] - q[2]));
                    }
                    prev = in;
                    wp = w;
                }
            }
    return best;
}

/// Generates p with 1 and with 2 threads and expects the same CT bytes, truth and description.
inline void expect_same_for_thread_counts(const PhantomParams& p) {
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const PhantomResult a = generate_phantom(p);
    omp_set_num_threads(2);
    const PhantomResult b = generate_phantom(p);
    omp_set_num_threads(threads);
    ASSERT_EQ(a.ct.size(), b.ct.size());
    EXPECT_EQ(std::memcmp(a.ct.data(), b.ct.data(), a.ct.size() * sizeof(int16_t)), 0);
    EXPECT_EQ(a.true_ecv_ml, b.true_ecv_ml);
    EXPECT_EQ(a.true_ecv_error_ml, b.true_ecv_error_ml);
    EXPECT_EQ(a.description, b.description);
}

}  // namespace endocast::testing
