#pragma once
// Volume<T>: a 3-D image that owns its voxels and carries its geometry.
//
// Layout: a flat buffer, x fastest, then y, then z: index = x + nx*(y + ny*z).
// Geometry follows ITK's physical space (LPS for medical images):
//   world = origin + direction * diag(spacing) * (i, j, k)
// with direction a 3x3 row-major rotation (columns are the axis directions).
// Every length in this library is in millimetres unless its name says otherwise.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "endocast/errors.h"

// ENDOCAST_UNDER_ASAN: defined (1) where this code is built with AddressSanitizer (GCC says so with
// __SANITIZE_ADDRESS__, clang with __has_feature(address_sanitizer)). ASan brings its own heap and
// operator new: glibc's heap is not tuned then (tune_heap_for_volumes) and the CLI keeps ASan's
// operator new.
#if defined(__SANITIZE_ADDRESS__)
#define ENDOCAST_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ENDOCAST_UNDER_ASAN 1
#endif
#endif

namespace endocast {

using Vec3 = std::array<double, 3>;
using Dims = std::array<int64_t, 3>;

/// Neighbourhoods on the voxel grid: face (6), face+edge (18), face+edge+vertex (26).
enum class Connectivity { Face6 = 6, Edge18 = 18, Vertex26 = 26 };

/// Index-to-world transform and grid size.
struct Geometry {
    Dims dims{0, 0, 0};                       ///< voxels along x, y, z
    Vec3 spacing{1.0, 1.0, 1.0};              ///< mm between voxel centres along x, y, z
    Vec3 origin{0.0, 0.0, 0.0};               ///< world mm of voxel (0,0,0)'s centre
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major 3x3

    size_t voxel_count() const {
        return static_cast<size_t>(dims[0]) * static_cast<size_t>(dims[1]) *
               static_cast<size_t>(dims[2]);
    }
    double voxel_volume_mm3() const { return spacing[0] * spacing[1] * spacing[2]; }
    /// The smallest spacing (mm): a length "in voxels" is in voxels of this size.
    double smallest_spacing() const { return std::min({spacing[0], spacing[1], spacing[2]}); }
    /// The largest spacing (mm): a step that reaches the next voxel along every axis.
    double largest_spacing() const { return std::max({spacing[0], spacing[1], spacing[2]}); }

    /// World position (mm) of a continuous index (i, j, k).
    Vec3 index_to_world(double i, double j, double k) const {
        const double a = i * spacing[0], b = j * spacing[1], c = k * spacing[2];
        const auto& d = direction;
        return {origin[0] + d[0] * a + d[1] * b + d[2] * c,
                origin[1] + d[3] * a + d[4] * b + d[5] * c,
                origin[2] + d[6] * a + d[7] * b + d[8] * c};
    }
    /// Continuous index of a world position (inverse of index_to_world; direction is orthonormal).
    Vec3 world_to_index(const Vec3& p) const {
        const double x = p[0] - origin[0], y = p[1] - origin[1], z = p[2] - origin[2];
        const auto& d = direction;
        // direction^T * (p - origin), then divide by spacing.
        return {(d[0] * x + d[3] * y + d[6] * z) / spacing[0],
                (d[1] * x + d[4] * y + d[7] * z) / spacing[1],
                (d[2] * x + d[5] * y + d[8] * z) / spacing[2]};
    }
    /// Determinant of the direction matrix (+1 right-handed, -1 left-handed).
    double direction_determinant() const {
        const auto& d = direction;
        return d[0] * (d[4] * d[8] - d[5] * d[7]) - d[1] * (d[3] * d[8] - d[5] * d[6]) +
               d[2] * (d[3] * d[7] - d[4] * d[6]);
    }
    bool same_grid(const Geometry& o) const { return dims == o.dims; }
};

/// Below this cost of a small (4 KiB) page's first touch, in microseconds, transparent huge pages
/// do not pay (docs/method/defaults.md).
inline constexpr double kHugePagesPayFromUs = 4.0;

/// The rule: huge pages pay unless a small page's first touch was measured (>= 0) and cost less
/// than kHugePagesPayFromUs microseconds.
bool huge_pages_pay(double small_fault_us);

/// Whether this process asks for transparent huge pages (allocate_on_huge_pages, the tuned heap):
/// huge_pages_pay of the first touch of fresh small pages (the least per page of 4 batches of 16,
/// in a mapping of their own; looked at twice where the first look says huge pages), timed once,
/// on first use (~0.1 ms). Advice only: it changes no result, only how memory is faulted in.
bool huge_pages_advised();

/// A block of `bytes` from the heap (malloc), freed with free_voxel_memory (std::free); nullptr when
/// the memory is not there. On Linux, where huge pages pay (huge_pages_advised), the whole 2 MiB
/// pages inside a block of 2 MiB or more are asked for as transparent huge pages (madvise; advice
/// only): a large buffer is then first touched in up to 512 times fewer page faults. The voxel
/// buffers take their memory here, and so does the CLI's operator new (apps/memory.cpp): a queue,
/// a mesh's arrays, a component labelling, a file read whole.
void* allocate_on_huge_pages(size_t bytes) noexcept;

/// Raw memory for voxel buffers: allocate_on_huge_pages, throwing std::bad_alloc when the memory
/// is not there.
void* allocate_voxel_memory(size_t bytes);
/// Frees a block of allocate_on_huge_pages or allocate_voxel_memory (std::free; nullptr: nothing).
void free_voxel_memory(void* p) noexcept;

/// What tune_heap_for_volumes did.
struct HeapTuning {
    bool one_arena = false;         ///< every thread allocates from the main heap
    bool huge_pages = false;        ///< huge_pages_advised(): the heap's growth asked for as huge pages
    const void* heap_advised_at = nullptr;  ///< where the heap's part asked for as huge pages starts
    size_t heap_advised_bytes = 0;          ///< its bytes (0: none; a second call grows no heap)
};

/// For a program that runs extractions (the CLI calls it first thing in main, before any thread
/// starts): glibc's malloc set to one arena for all threads, every block from its heap (none mapped
/// and unmapped on its own), the heap never trimmed and grown 64 MiB at a time, and, where huge
/// pages pay (huge_pages_advised), the heap asked for as transparent huge pages. The many small and
/// medium blocks of a run (a mesh's pieces, queues, per-thread scratch) then come from memory
/// reused instead of faulted in again (and, with huge pages, faulted in 2 MiB at a time).
/// Changes process-wide malloc settings, so the library never calls it itself. Does nothing off
/// Linux/glibc or under AddressSanitizer.
HeapTuning tune_heap_for_volumes();

/// Allocator of voxel buffers: a resize default-initialises the new voxels (no zero fill), so a
/// buffer about to be overwritten is not first written, and its pages first touched, by one
/// thread. Volume's constructor fills its voxels in parallel.
template <class T>
struct VoxelAllocator : std::allocator<T> {
    using value_type = T;
    template <class U>
    struct rebind {
        using other = VoxelAllocator<U>;
    };
    VoxelAllocator() noexcept = default;
    template <class U>
    VoxelAllocator(const VoxelAllocator<U>&) noexcept {}
    T* allocate(size_t n) {
        if (n > size_t(-1) / sizeof(T)) throw std::bad_alloc();
        return static_cast<T*>(allocate_voxel_memory(n * sizeof(T)));
    }
    void deallocate(T* p, size_t) noexcept { free_voxel_memory(p); }
    template <class U>
    void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
        ::new (static_cast<void*>(p)) U;
    }
    template <class U, class... Args>
    void construct(U* p, Args&&... args) {
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
};

/// A volume's voxels: std::vector whose resize leaves new voxels uninitialised.
template <class T>
using VoxelBuffer = std::vector<T, VoxelAllocator<T>>;

/// A 3-D image of T, x fastest, with its geometry.
template <class T>
class Volume {
public:
    Volume() = default;
    explicit Volume(const Geometry& g, T fill = T{}) : geom_(g) {
        for (int a = 0; a < 3; ++a)
            if (g.dims[a] <= 0)
                throw InvalidParameter("volume dimension " + std::to_string(a) + " is " +
                                       std::to_string(g.dims[a]) + ", expected > 0");
        data_.resize(g.voxel_count());
        T* d = data_.data();
        const int64_t n = static_cast<int64_t>(data_.size());
#pragma omp parallel for schedule(static)
        for (int64_t i = 0; i < n; ++i) d[i] = fill;
    }

    const Geometry& geometry() const { return geom_; }
    Geometry& geometry() { return geom_; }
    const Dims& dims() const { return geom_.dims; }
    int64_t nx() const { return geom_.dims[0]; }
    int64_t ny() const { return geom_.dims[1]; }
    int64_t nz() const { return geom_.dims[2]; }
    size_t size() const { return data_.size(); }
    bool empty() const { return data_.empty(); }

    size_t index(int64_t x, int64_t y, int64_t z) const {
        return static_cast<size_t>(x + geom_.dims[0] * (y + geom_.dims[1] * z));
    }
    bool contains(int64_t x, int64_t y, int64_t z) const {
        return x >= 0 && y >= 0 && z >= 0 && x < geom_.dims[0] && y < geom_.dims[1] &&
               z < geom_.dims[2];
    }
    T& operator()(int64_t x, int64_t y, int64_t z) { return data_[index(x, y, z)]; }
    const T& operator()(int64_t x, int64_t y, int64_t z) const { return data_[index(x, y, z)]; }
    T& operator[](size_t i) { return data_[i]; }
    const T& operator[](size_t i) const { return data_[i]; }

    T* data() { return data_.data(); }
    const T* data() const { return data_.data(); }
    VoxelBuffer<T>& buffer() { return data_; }
    const VoxelBuffer<T>& buffer() const { return data_; }

private:
    Geometry geom_;
    VoxelBuffer<T> data_;
};

/// Labels of the segmentation (uint8 voxels).
enum Label : uint8_t {
    kUnlabelled = 0,
    kEndocast = 1,   ///< the braincase cavity
    kOther = 2,      ///< empty space that is not the cavity
    kBone = 3,       ///< bone (after void filling)
};

/// "" when every voxel is finite, else "N voxels are NaN or infinite, the first at voxel (x, y, z)".
std::string describe_non_finite(const Volume<float>& v);

/// The CT types the method runs on: float (any scan), and int16_t for a scan whose samples are all
/// integers in [-32768, 32767] (a CT stored as int16 or uint16 up to 32767: half the memory, and
/// half the bytes every pass over the CT reads). The stages compare each sample as a float, so an
/// int16 CT gives the same result as the same values in float.
template <class T>
inline constexpr bool is_ct_type = std::is_same_v<T, float> || std::is_same_v<T, int16_t>;

/// A mask (0 / non-zero voxels) packed 64 voxels to a word: an eighth of a uint8 volume's memory,
/// for a mask kept across stages that do not read it (the bone before the void fill, kept for the
/// openings stage). unpack() gives 1 for every non-zero voxel. Parallel.
class PackedMask {
public:
    PackedMask() = default;
    explicit PackedMask(const Volume<uint8_t>& mask);
    /// The voxels i of grid g for which in(i) is true (in: size_t -> bool, called once per voxel,
    /// from several threads).
    template <class In>
    static PackedMask where(const Geometry& g, In in) {
        PackedMask m;
        m.geom_ = g;
        const size_t n = g.voxel_count();
        m.bits_.assign((n + 63) / 64, 0);
#pragma omp parallel for schedule(static)
        for (int64_t w = 0; w < int64_t(m.bits_.size()); ++w) {
            const size_t first = size_t(w) * 64, last = std::min(n, first + 64);
            uint64_t word = 0;
            for (size_t i = first; i < last; ++i) word |= uint64_t(in(i) ? 1 : 0) << (i - first);
            m.bits_[size_t(w)] = word;
        }
        return m;
    }
    Volume<uint8_t> unpack() const;
    bool empty() const { return bits_.empty(); }
    const Geometry& geometry() const { return geom_; }
    /// Voxel i (flat index) is set.
    bool test(size_t i) const { return ((bits_[i >> 6] >> (i & 63)) & 1u) != 0; }

private:
    Geometry geom_;
    std::vector<uint64_t> bits_;
};

/// The volume as int16 when every sample is an integer in int16's range (exactly the same values),
/// else an empty volume. Parallel.
Volume<int16_t> exact_int16(const Volume<float>& v);
/// The volume as float (a copy). Parallel.
Volume<float> to_float(const Volume<int16_t>& v);

}  // namespace endocast
