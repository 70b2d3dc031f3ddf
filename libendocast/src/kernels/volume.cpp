// Volume<T> is header-only; this unit anchors the library and instantiates the common types.
#include "endocast/volume.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <new>
#ifdef __linux__
#include <sys/mman.h>
#endif

namespace endocast {

namespace {
constexpr size_t kHuge = size_t(2) << 20;  // a transparent huge page (x86-64, arm64 4K kernels)
}  // namespace

void* allocate_voxel_memory(size_t bytes) {
    void* p = std::malloc(bytes ? bytes : 1);
    if (!p) throw std::bad_alloc();
#ifdef __linux__
    // The whole huge pages inside a large block: advice only (without THP they stay 4 KiB). Pages
    // the heap had touched before stay as they are; those touched first now come 2 MiB at a time.
    if (bytes >= 2 * kHuge) {
        const uintptr_t at = reinterpret_cast<uintptr_t>(p);
        const uintptr_t lo = (at + kHuge - 1) / kHuge * kHuge, hi = (at + bytes) / kHuge * kHuge;
        if (hi > lo) madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
    }
#endif
    return p;
}

void free_voxel_memory(void* p) noexcept { std::free(p); }

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
