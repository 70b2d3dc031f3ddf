#pragma once
// Running maximum along one axis of a volume (a separable box filter): three passes, one per axis,
// give the maximum over a box of (2 rad_x + 1) x (2 rad_y + 1) x (2 rad_z + 1) voxels, and on a 0/1
// mask the dilation by that box. Parallel over lines; the result does not depend on the thread count.
#include <algorithm>
#include <cstdint>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

/// In place: each voxel of `v` becomes the maximum of the voxels within `rad` of it along `axis`
/// (clamped to the volume).
template <class T>
void max_filter_axis(Volume<T>& v, int axis, int rad) {
    const Dims& d = v.dims();
    const int64_t n = d[axis];
    const int a1 = axis == 0 ? 1 : 0, a2 = axis == 2 ? 1 : 2;
    const int64_t stride = axis == 0 ? 1 : axis == 1 ? d[0] : d[0] * d[1];
    const int64_t lines = d[a1] * d[a2];
#pragma omp parallel
    {
        std::vector<T> buf(static_cast<size_t>(n));
#pragma omp for schedule(static)
        for (int64_t l = 0; l < lines; ++l) {
            int64_t c[3] = {0, 0, 0};
            c[a1] = l % d[a1];
            c[a2] = l / d[a1];
            T* base = &v(c[0], c[1], c[2]);
            for (int64_t i = 0; i < n; ++i) buf[size_t(i)] = base[i * stride];
            for (int64_t i = 0; i < n; ++i) {
                const int64_t j0 = std::max<int64_t>(0, i - rad), j1 = std::min<int64_t>(n - 1, i + rad);
                T m = buf[size_t(j0)];  // the window holds voxel i at least
                for (int64_t j = j0 + 1; j <= j1; ++j) m = std::max(m, buf[size_t(j)]);
                base[i * stride] = m;
            }
        }
    }
}

}  // namespace endocast
