// The plug flood's queues (method/plug_queue.h): SideHeaps pops what RankHeap, the single heap of
// (rank, side, id) that defines the order, pops, wherever SideHeaps::fits says it may be used.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "method/plug_queue.h"

using endocast::plug_queue::kIn;
using endocast::plug_queue::kOut;
using endocast::plug_queue::RankHeap;
using endocast::plug_queue::SideHeaps;

namespace {

// Distances as a grid gives them (square roots of sums of squared steps, many equal), some +inf.
std::vector<float> grid_distances(std::mt19937_64& rng, size_t n, double step) {
    std::vector<float> d(n);
    for (float& v : d) {
        const double a = double(rng() % 5), b = double(rng() % 4), c = double(rng() % 3);
        v = rng() % 50 == 0 ? std::numeric_limits<float>::infinity()
                            : std::sqrt(float(step * step * (1 + a * a + b * b + c * c)));
    }
    return d;
}

// Random adds, then interleaved pushes and pops, every (id, side) at most once: the same pops.
void expect_same_pops(uint32_t seed, size_t n, double step, double lead) {
    std::mt19937_64 rng(seed);
    const std::vector<float> d = grid_distances(rng, n, step);
    ASSERT_TRUE(SideHeaps::fits(d, lead));
    SideHeaps fast(d, lead);
    RankHeap ref(d, lead);
    std::vector<uint8_t> used(n, 0);
    auto pick = [&](uint32_t& c, uint8_t& s) {
        for (int tries = 0; tries < 20; ++tries) {
            c = uint32_t(rng() % n);
            s = rng() % 2 ? kOut : kIn;
            if (!(used[c] & s)) {
                used[c] |= s;
                return true;
            }
        }
        return false;
    };
    uint32_t c = 0;
    uint8_t s = 0;
    for (size_t k = 0; k < n / 3; ++k)
        if (pick(c, s)) {
            fast.add(c, s);
            ref.add(c, s);
        }
    fast.heapify();
    ref.heapify();
    for (size_t op = 0; op < 4 * n; ++op) {
        ASSERT_EQ(fast.empty(), ref.empty());
        if (!ref.empty() && rng() % 2 == 0) {
            const auto want = ref.pop();
            const auto got = fast.pop();
            ASSERT_EQ(got, want) << "seed " << seed << " operation " << op;
        } else if (pick(c, s)) {
            fast.push(c, s);
            ref.push(c, s);
        }
    }
    while (!ref.empty()) {
        ASSERT_FALSE(fast.empty());
        ASSERT_EQ(fast.pop(), ref.pop());
    }
    EXPECT_TRUE(fast.empty());
}

}  // namespace

TEST(PlugQueue, SideHeapsPopAsTheRankHeap) {
    // Leads that tie other space's ranks with the endocast's exactly (1 and 2 mm steps with a lead
    // of a step), that do not, none, and a spacing that is no binary fraction.
    const double steps[] = {1.0, 0.5, 0.488281, 0.3};
    const double leads[] = {0.0, 0.5, 1.0, 2.0, 0.3, 0.7071};
    uint32_t seed = 1;
    for (double step : steps)
        for (double lead : leads)
            for (size_t n : {1, 2, 7, 60, 2000}) expect_same_pops(seed++, n, step, lead);
}

TEST(PlugQueue, SideHeapsFitOnlyWhereTheyKeepTheOrder) {
    const float inf = std::numeric_limits<float>::infinity();
    EXPECT_TRUE(SideHeaps::fits({1.0f, 2.0f, inf}, 1.0));
    EXPECT_TRUE(SideHeaps::fits({}, 1.0));
    EXPECT_FALSE(SideHeaps::fits({0.0f, 1.0f}, 1.0));   // a distance of 0
    EXPECT_FALSE(SideHeaps::fits({-0.0f, 1.0f}, 1.0));
    EXPECT_FALSE(SideHeaps::fits({std::nanf(""), 1.0f}, 1.0));
    EXPECT_FALSE(SideHeaps::fits({1.0f, 2.0f}, -1.0));  // a negative or unbounded lead
    EXPECT_FALSE(SideHeaps::fits({1.0f, 2.0f}, std::numeric_limits<double>::infinity()));
    // A lead so large that distinct distances could round to one rank: 1 and its next float.
    const float a = 1.0f, b = std::nextafter(1.0f, 2.0f);
    EXPECT_FALSE(SideHeaps::fits({a, b}, 0x1p31));
    EXPECT_EQ(double(a) + 0x1p31, double(b) + 0x1p31);  // they do round to one rank
    EXPECT_TRUE(SideHeaps::fits({a, b}, 0x1p20));
}
