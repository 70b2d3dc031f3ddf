// Volume<T> is header-only; this unit anchors the library and instantiates the common types.
#include "endocast/volume.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <utility>
#ifdef __linux__
#include <malloc.h>
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace endocast {

namespace {

constexpr size_t kHuge = size_t(2) << 20;  // a transparent huge page (x86-64, arm64 4K kernels)

// AddressSanitizer keeps its own heap: glibc's is not tuned there.
#if !defined(__linux__) || !defined(__GLIBC__) || defined(ENDOCAST_UNDER_ASAN)
#define ENDOCAST_PLAIN_MALLOC 1
#endif

#ifdef __linux__
// The first touch of a fresh small page, in microseconds: the least per page of kBatches batches of
// kPages pages of a mapping of its own, advised not to be huge pages (the least: a batch the
// scheduler interrupted does not count); -1 where nothing could be mapped. About 0.1 ms in all.
double small_page_fault_us() {
    constexpr int kPages = 16, kBatches = 4;
    const long page = sysconf(_SC_PAGESIZE);
    if (page <= 0) return -1;
    const size_t bytes = size_t(page) * kPages * kBatches;
    void* m = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (m == MAP_FAILED) return -1;
    madvise(m, bytes, MADV_NOHUGEPAGE);
    volatile char* c = static_cast<char*>(m);
    double best = -1;
    for (int b = 0; b < kBatches; ++b) {
        const auto t0 = std::chrono::steady_clock::now();
        for (int i = 0; i < kPages; ++i) c[size_t(b * kPages + i) * size_t(page)] = 1;
        const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / kPages;
        if (best < 0 || us < best) best = us;
    }
    munmap(m, bytes);
    return best;
}

// Asks for the whole 2 MiB pages inside [begin, end) as transparent huge pages where they pay
// (huge_pages_advised; advice only: without THP they stay 4 KiB); returns the start of the range
// advised and its bytes ({0, 0}: none).
std::pair<uintptr_t, size_t> advise_huge_pages(uintptr_t begin, uintptr_t end) {
    if (!huge_pages_advised()) return {0, 0};
    const uintptr_t lo = (begin + kHuge - 1) / kHuge * kHuge, hi = end / kHuge * kHuge;
    if (hi > lo && madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE) == 0) return {lo, hi - lo};
    return {0, 0};
}
#endif

}  // namespace

bool huge_pages_pay(double small_fault_us) { return !(small_fault_us >= 0 && small_fault_us < kHugePagesPayFromUs); }

bool huge_pages_advised() {
#ifdef __linux__
    static const bool pay = [] {
        double small = small_page_fault_us();
        if (small >= 0 && huge_pages_pay(small)) {  // a slow first look (a process just started) is taken again
            const double again = small_page_fault_us();
            if (again >= 0) small = std::min(small, again);
        }
        return huge_pages_pay(small);
    }();
    return pay;
#else
    return false;
#endif
}

void* allocate_on_huge_pages(size_t bytes) noexcept {
    // No object is larger than PTRDIFF_MAX bytes: such a size is refused here, not left to malloc
    // (AddressSanitizer's aborts instead of returning null).
    if (bytes > size_t(PTRDIFF_MAX)) return nullptr;
    void* p = std::malloc(bytes ? bytes : 1);
#ifdef __linux__
    // The whole huge pages inside the block: advice only (without THP they stay 4 KiB). Pages the
    // heap had touched before stay as they are; those touched first now come 2 MiB at a time.
    if (p && bytes >= kHuge) advise_huge_pages(reinterpret_cast<uintptr_t>(p), reinterpret_cast<uintptr_t>(p) + bytes);
#endif
    return p;
}

void* allocate_voxel_memory(size_t bytes) {
    void* p = allocate_on_huge_pages(bytes);
    if (!p) throw std::bad_alloc();
    return p;
}

void free_voxel_memory(void* p) noexcept { std::free(p); }

HeapTuning tune_heap_for_volumes() {
    HeapTuning t;
#ifndef ENDOCAST_PLAIN_MALLOC
    // One arena: the threads' small blocks come from the main heap, which is advised below (a
    // thread's own arena is mapped apart, in 4 KiB pages).
    t.one_arena = mallopt(M_ARENA_MAX, 1) == 1;
    // Every block from the heap, and the heap kept: glibc otherwise maps a large block on its own
    // and unmaps it when freed, so that the next one is faulted in and cleared by the kernel again.
    // The heap is grown kHeapPad at a time: one growth now, asked for as huge pages where they pay.
    mallopt(M_MMAP_MAX, 0);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    constexpr size_t kHeapPad = size_t(64) << 20;
    mallopt(M_TOP_PAD, int(kHeapPad));
    const uintptr_t before = reinterpret_cast<uintptr_t>(sbrk(0));
    void* volatile grow = std::malloc(size_t(1) << 20);  // volatile: not elided with its free
    std::free(grow);
    const uintptr_t after = reinterpret_cast<uintptr_t>(sbrk(0));
    const auto [at, advised] = advise_huge_pages(before, after);
    t.huge_pages = huge_pages_advised();
    if (advised > 0) {
        t.heap_advised_at = reinterpret_cast<const void*>(at);
        t.heap_advised_bytes = advised;
    }
#endif
    return t;
}

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

Volume<int16_t> exact_int16(const Volume<float>& v) {
    const int64_t n = int64_t(v.size());
    const float* d = v.data();
    // In range, a value is an integer when truncating it changes nothing (NaN fails the range
    // test); `&` over all voxels, not `&&`, so that the loop vectorizes.
    int exact = n > 0;
#pragma omp parallel for schedule(static) reduction(& : exact)
    for (int64_t i = 0; i < n; ++i) {
        const float x = d[i];
        const bool in_range = x >= -32768.0f && x <= 32767.0f;
        const float t = in_range ? x : 0.0f;
        exact &= int(in_range & (t == float(int32_t(t))));
    }
    if (!exact) return {};
    Volume<int16_t> out;
    out.geometry() = v.geometry();
    out.buffer().resize(v.size());
    int16_t* o = out.data();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < n; ++i) o[i] = int16_t(d[i]);
    return out;
}

Volume<float> to_float(const Volume<int16_t>& v) {
    Volume<float> out;
    out.geometry() = v.geometry();
    out.buffer().resize(v.size());
    const int16_t* d = v.data();
    float* o = out.data();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(v.size()); ++i) o[i] = float(d[i]);
    return out;
}

PackedMask::PackedMask(const Volume<uint8_t>& mask) {
    const uint8_t* m = mask.data();
    *this = where(mask.geometry(), [m](size_t i) { return m[i] != 0; });
}

Volume<uint8_t> PackedMask::unpack() const {
    Volume<uint8_t> out;
    if (bits_.empty()) return out;
    out.geometry() = geom_;
    out.buffer().resize(geom_.voxel_count());
    const size_t n = out.size();
    uint8_t* m = out.data();
#pragma omp parallel for schedule(static)
    for (int64_t w = 0; w < int64_t(bits_.size()); ++w) {
        const size_t first = size_t(w) * 64, last = std::min(n, first + 64);
        const uint64_t word = bits_[size_t(w)];
        for (size_t i = first; i < last; ++i) m[i] = uint8_t((word >> (i - first)) & 1u);
    }
    return out;
}
}  // namespace endocast
