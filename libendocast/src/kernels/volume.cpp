// Volume<T> is header-only; this unit anchors the library and instantiates the common types.
#include "endocast/volume.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace endocast {
template class Volume<uint8_t>;
template class Volume<int16_t>;
template class Volume<float>;

std::string describe_non_finite(const Volume<float>& v) {
    size_t bad = 0, first = SIZE_MAX;
    const float* d = v.data();
#pragma omp parallel for schedule(static) reduction(+ : bad) reduction(min : first)
    for (int64_t i = 0; i < int64_t(v.size()); ++i)
        if (!std::isfinite(d[i])) {
            ++bad;
            first = std::min(first, size_t(i));
        }
    if (bad == 0) return {};
    const size_t nx = static_cast<size_t>(v.nx()), ny = static_cast<size_t>(v.ny());
    return std::to_string(bad) + " voxels are NaN or infinite, the first at voxel (" +
           std::to_string(first % nx) + ", " + std::to_string(first / nx % ny) + ", " +
           std::to_string(first / (nx * ny)) + ")";
}
}  // namespace endocast
