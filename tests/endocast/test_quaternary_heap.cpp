// QuaternaryHeap (kernels/quaternary_heap.h) against std::pop_heap, the binary heap it replaced.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "kernels/quaternary_heap.h"

using endocast::QuaternaryHeap;

namespace {

struct Key {
    uint64_t hi, lo;
};
auto below = [](const Key& a, const Key& c) { return a.hi != c.hi ? a.hi < c.hi : a.lo < c.lo; };

// Interleaved pushes and pops of distinct keys, many equal in `hi` (as the flood's ranks are): the
// same sequence from both heaps, for built and empty starts and every small size.
void expect_same_order(uint32_t seed, size_t initial, size_t operations) {
    std::mt19937_64 rng(seed);
    uint64_t next_lo = 0;
    auto key = [&]() { return Key{rng() % 7, next_lo++}; };
    QuaternaryHeap<Key, decltype(below)> q(below);
    std::vector<Key> ref;
    for (size_t i = 0; i < initial; ++i) {
        const Key k = key();
        q.add(k);
        ref.push_back(k);
    }
    q.heapify();
    std::make_heap(ref.begin(), ref.end(), below);
    for (size_t op = 0; op < operations; ++op) {
        ASSERT_EQ(q.size(), ref.size());
        if (!ref.empty() && rng() % 3 == 0) {
            std::pop_heap(ref.begin(), ref.end(), below);
            const Key want = ref.back();
            ref.pop_back();
            const Key got = q.pop();
            ASSERT_EQ(got.hi, want.hi) << "seed " << seed << " operation " << op;
            ASSERT_EQ(got.lo, want.lo) << "seed " << seed << " operation " << op;
        } else {
            const Key k = key();
            q.push(k);
            ref.push_back(k);
            std::push_heap(ref.begin(), ref.end(), below);
        }
    }
    while (!ref.empty()) {
        std::pop_heap(ref.begin(), ref.end(), below);
        const Key got = q.pop();
        ASSERT_EQ(got.hi, ref.back().hi);
        ASSERT_EQ(got.lo, ref.back().lo);
        ref.pop_back();
    }
    EXPECT_TRUE(q.empty());
}

}  // namespace

TEST(QuaternaryHeap, PopsAsStdHeapDoes) {
    for (size_t initial = 0; initial <= 20; ++initial) expect_same_order(uint32_t(initial), initial, 200);
    expect_same_order(99, 5000, 20000);
}

TEST(QuaternaryHeap, PopsTheLargestFirst) {
    auto less = [](int a, int b) { return a < b; };
    QuaternaryHeap<int, decltype(less)> q(less);
    for (int v : {5, 1, 9, 3, 7, 2, 8}) q.add(v);
    q.heapify();
    q.push(6);
    q.push(10);
    std::vector<int> out;
    while (!q.empty()) out.push_back(q.pop());
    EXPECT_EQ(out, (std::vector<int>{10, 9, 8, 7, 6, 5, 3, 2, 1}));
}
