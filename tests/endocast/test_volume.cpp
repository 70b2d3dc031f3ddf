#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "endocast/volume.h"

using namespace endocast;

TEST(Volume, IndexIsXFastest) {
    Geometry g;
    g.dims = {4, 3, 2};
    Volume<uint8_t> v(g);
    EXPECT_EQ(v.size(), 24u);
    EXPECT_EQ(v.index(1, 0, 0), 1u);
    EXPECT_EQ(v.index(0, 1, 0), 4u);
    EXPECT_EQ(v.index(0, 0, 1), 12u);
    v(3, 2, 1) = 7;
    EXPECT_EQ(v[23], 7);
}

TEST(Volume, RejectsNonPositiveDims) {
    Geometry g;
    g.dims = {4, 0, 2};
    EXPECT_THROW(Volume<uint8_t>{g}, InvalidParameter);
}

TEST(Geometry, IndexWorldRoundTripWithDirectionAndSpacing) {
    Geometry g;
    g.dims = {10, 10, 10};
    g.spacing = {0.5, 0.75, 2.0};
    g.origin = {-10, 20, 5};
    // 90 degrees about z: x axis -> +y, y axis -> -x.
    g.direction = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    const Vec3 w = g.index_to_world(2, 4, 1);
    EXPECT_DOUBLE_EQ(w[0], -10 - 3.0);
    EXPECT_DOUBLE_EQ(w[1], 20 + 1.0);
    EXPECT_DOUBLE_EQ(w[2], 5 + 2.0);
    const Vec3 i = g.world_to_index(w);
    EXPECT_NEAR(i[0], 2, 1e-12);
    EXPECT_NEAR(i[1], 4, 1e-12);
    EXPECT_NEAR(i[2], 1, 1e-12);
    EXPECT_DOUBLE_EQ(g.direction_determinant(), 1.0);
}

// An integer-valued CT is kept as int16 with exactly its values; any other comes back empty.
TEST(Volume, ExactInt16KeepsIntegerValuedScansOnly) {
    Geometry g;
    g.dims = {5, 4, 3};
    g.spacing = {0.5, 0.6, 1.2};
    g.origin = {-3, 4, 7};
    Volume<float> v(g);
    for (size_t i = 0; i < v.size(); ++i) v[i] = float(int(i * 977 % 65536) - 32768);
    v[0] = -32768.0f;
    v[1] = 32767.0f;
    const Volume<int16_t> s = exact_int16(v);
    ASSERT_EQ(s.size(), v.size());
    EXPECT_EQ(s.geometry().spacing, g.spacing);
    EXPECT_EQ(s.geometry().origin, g.origin);
    for (size_t i = 0; i < v.size(); ++i) EXPECT_EQ(float(s[i]), v[i]) << i;
    EXPECT_EQ(to_float(s).buffer(), v.buffer());
    Volume<float> fraction = v;
    fraction[7] = 12.5f;
    EXPECT_TRUE(exact_int16(fraction).empty());
    Volume<float> beyond = v;
    beyond[3] = 32768.0f;
    EXPECT_TRUE(exact_int16(beyond).empty());
    beyond[3] = -32769.0f;
    EXPECT_TRUE(exact_int16(beyond).empty());
    Volume<float> nan = v;
    nan[2] = std::nanf("");
    EXPECT_TRUE(exact_int16(nan).empty());
    for (const float odd : {std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(), 0.5f,
                            -0.25f, 32766.5f, -32767.5f}) {
        Volume<float> w = v;
        w[w.size() - 1] = odd;  // the last voxel (a vector loop's tail)
        EXPECT_TRUE(exact_int16(w).empty()) << odd;
    }
}

// A mask packed from a predicate: test() reads the bit of each voxel; the same as packing the
// mask.
TEST(Volume, PackedMaskFromAPredicate) {
    for (const Dims d : {Dims{1, 1, 1}, Dims{7, 5, 3}, Dims{64, 2, 1}, Dims{13, 11, 9}}) {
        Geometry g;
        g.dims = d;
        auto in = [](size_t i) { return (i * 37 + i / 3) % 5 == 0; };
        const PackedMask p = PackedMask::where(g, in);
        EXPECT_EQ(p.geometry().dims, d);
        Volume<uint8_t> m(g);
        for (size_t i = 0; i < m.size(); ++i) {
            m[i] = in(i);
            EXPECT_EQ(p.test(i), in(i)) << i;
        }
        EXPECT_EQ(p.unpack().buffer(), PackedMask(m).unpack().buffer());
    }
}

// A packed mask unpacks to 1 where the mask was non-zero, 0 elsewhere, with its geometry (sizes
// that are not a multiple of 64 included).
TEST(Volume, PackedMaskRoundTrip) {
    for (const Dims d : {Dims{1, 1, 1}, Dims{7, 5, 3}, Dims{64, 2, 1}, Dims{13, 11, 9}}) {
        Geometry g;
        g.dims = d;
        g.spacing = {0.4, 0.5, 0.6};
        Volume<uint8_t> m(g);
        for (size_t i = 0; i < m.size(); ++i) m[i] = uint8_t((i * 37 + i / 3) % 5 == 0 ? (i % 3) + 1 : 0);
        const PackedMask p(m);
        EXPECT_FALSE(p.empty());
        const Volume<uint8_t> u = p.unpack();
        ASSERT_EQ(u.size(), m.size());
        EXPECT_EQ(u.geometry().spacing, g.spacing);
        for (size_t i = 0; i < m.size(); ++i) EXPECT_EQ(u[i], m[i] ? 1 : 0) << i;
    }
    EXPECT_TRUE(PackedMask().empty());
    EXPECT_TRUE(PackedMask().unpack().empty());
}

#ifdef __linux__
namespace {
// The VmFlags line of the mapping that holds `p` (/proc/self/smaps), or "" when none does.
std::string vm_flags_at(const void* p) {
    std::ifstream in("/proc/self/smaps");
    const uintptr_t at = reinterpret_cast<uintptr_t>(p);
    bool inside = false;
    for (std::string line; std::getline(in, line);) {
        unsigned long lo = 0, hi = 0;
        char dash = 0;
        std::istringstream head(line);
        if (head >> std::hex >> lo >> dash >> hi && dash == '-' && line.find(':') > line.find(' ')) {
            inside = at >= lo && at < hi;
            continue;
        }
        if (inside && line.rfind("VmFlags:", 0) == 0) return line;
    }
    return "";
}
}  // namespace
#endif

TEST(Volume, LargeBlocksAskForHugePages) {
    constexpr size_t kHuge = size_t(2) << 20;
#ifdef __linux__
    const bool thp = std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled").good();
    if (!thp) std::cout << "no transparent huge pages in this kernel: the advice is not checked\n";
#endif
    for (size_t bytes : {kHuge, 3 * kHuge + 5, 9 * kHuge - 1}) {
        unsigned char* p = static_cast<unsigned char*>(allocate_on_huge_pages(bytes));
        ASSERT_NE(p, nullptr) << bytes;
        std::memset(p, 7, bytes);  // the whole block is there
        EXPECT_EQ(p[bytes - 1], 7);
#ifdef __linux__
        // The whole huge pages inside the block are advised as such: "hg" among the flags of the
        // mapping that holds the first of them (a kernel built without THP refuses the advice).
        const uintptr_t first = (reinterpret_cast<uintptr_t>(p) + kHuge - 1) / kHuge * kHuge;
        // Where huge pages do not pay (huge_pages_advised), nothing is advised.
        if (thp && first + kHuge <= reinterpret_cast<uintptr_t>(p) + bytes) {
            const std::string flags = vm_flags_at(reinterpret_cast<const void*>(first));
            if (huge_pages_advised()) EXPECT_NE(flags.find(" hg"), std::string::npos) << bytes << ": " << flags;
            else EXPECT_EQ(flags.find(" hg"), std::string::npos) << bytes << ": " << flags;
        }
#endif
        free_voxel_memory(p);
    }
    void* small = allocate_on_huge_pages(100);
    ASSERT_NE(small, nullptr);
    free_voxel_memory(small);
    void* none = allocate_on_huge_pages(0);  // a block all the same, as malloc(1)
    ASSERT_NE(none, nullptr);
    free_voxel_memory(none);
    free_voxel_memory(nullptr);
    // Blocks of every size freed and taken again, interleaved.
    std::vector<void*> blocks;
    for (size_t i = 0; i < 64; ++i) {
        const size_t bytes = (i % 3 == 0) ? kHuge * (1 + i % 5) + 17 * i : 1000 * i + 1;
        blocks.push_back(allocate_voxel_memory(bytes));
        std::memset(blocks.back(), int(i), bytes);
        if (i % 4 == 3) {
            free_voxel_memory(blocks[i / 2]);
            blocks[i / 2] = nullptr;
        }
    }
    for (void* b : blocks) free_voxel_memory(b);
    EXPECT_EQ(allocate_on_huge_pages(std::numeric_limits<size_t>::max() - 10), nullptr);
    EXPECT_THROW(allocate_voxel_memory(std::numeric_limits<size_t>::max() - 10), std::bad_alloc);
}

TEST(Volume, HugePagesPayOnlyWhereSmallPagesFaultSlowly) {
    EXPECT_FALSE(huge_pages_pay(0.0));
    EXPECT_FALSE(huge_pages_pay(1.2));  // this project's VM in December 2026
    EXPECT_FALSE(huge_pages_pay(std::nextafter(kHugePagesPayFromUs, 0.0)));
    EXPECT_TRUE(huge_pages_pay(kHugePagesPayFromUs));
    EXPECT_TRUE(huge_pages_pay(12.0));  // an earlier VM
    EXPECT_TRUE(huge_pages_pay(-1.0));  // not measured: huge pages, as before the rule
    // Decided once per process.
    const bool advised = huge_pages_advised();
    EXPECT_EQ(huge_pages_advised(), advised);
    std::cout << "huge pages " << (advised ? "" : "not ") << "advised in this process\n";
}

TEST(Volume, TunedHeapIsOnHugePages) {
    const HeapTuning t = tune_heap_for_volumes();
#if defined(__linux__) && defined(__GLIBC__) && !defined(ENDOCAST_UNDER_ASAN)
    EXPECT_TRUE(t.one_arena);
    EXPECT_EQ(t.huge_pages, huge_pages_advised());
    // malloc still works from every thread (one arena).
    std::vector<void*> small(100);
#pragma omp parallel for
    for (int i = 0; i < 100; ++i) small[size_t(i)] = std::malloc(size_t(1000 + 4096 * i));
    for (void* p : small) {
        EXPECT_NE(p, nullptr);
        std::free(p);
    }
    // The heap grown by the call (unless an earlier call in this process grew it) is advised as
    // huge pages where they pay: "hg" among the flags of the mapping there.
    if (!t.huge_pages) {
        EXPECT_EQ(t.heap_advised_bytes, 0u);
        std::cout << "huge pages do not pay in this process: the heap is not advised\n";
        return;
    }
    if (t.heap_advised_bytes == 0) {
        std::cout << "the heap was not grown by this call: its advice is not checked\n";
        return;
    }
    EXPECT_EQ(reinterpret_cast<uintptr_t>(t.heap_advised_at) % (size_t(2) << 20), 0u);
    EXPECT_GE(t.heap_advised_bytes, size_t(32) << 20);
    if (std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled").good()) {
        const std::string flags = vm_flags_at(t.heap_advised_at);
        EXPECT_NE(flags.find(" hg"), std::string::npos) << flags;
    }
#else
    EXPECT_EQ(t.heap_advised_bytes, 0u);
#endif
}
