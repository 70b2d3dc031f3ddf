// connected_components, keep_*, fill_holes (components.h), against a brute-force reference too.
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <functional>
#include <vector>

#include "endocast/stages/components.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;

TEST(Components, FaceVersusVertexConnectivity) {
    Volume<uint8_t> m(grid(5, 5, 5));
    m(1, 1, 1) = 1;
    m(2, 2, 2) = 1;  // touches (1,1,1) only by a corner
    EXPECT_EQ(connected_components(m, Connectivity::Face6).sizes.size(), 2u);
    EXPECT_EQ(connected_components(m, Connectivity::Edge18).sizes.size(), 2u);
    EXPECT_EQ(connected_components(m, Connectivity::Vertex26).sizes.size(), 1u);
    EXPECT_EQ(neighbour_offsets(Connectivity::Edge18).size(), 18u);
}

TEST(Components, KeepLargestAndBorderFlag) {
    Volume<uint8_t> m(grid(10, 10, 10));
    for (int x = 2; x < 6; ++x) m(x, 5, 5) = 1;  // 4 voxels, interior
    m(0, 0, 0) = 1;                               // 1 voxel, on the border
    const auto c = connected_components(m, Connectivity::Face6);
    ASSERT_EQ(c.sizes.size(), 2u);
    EXPECT_TRUE(c.touches_border[0]);
    EXPECT_FALSE(c.touches_border[1]);
    EXPECT_EQ(keep_largest_component(m, Connectivity::Face6), 1u);
    EXPECT_EQ(m(0, 0, 0), 0);
    EXPECT_EQ(m(3, 5, 5), 1);
}

TEST(Components, FillHolesFillsOnlyEnclosedBackground) {
    auto m = endocast::testing::shell(grid(15, 15, 15), 3.0, 5.0);
    const size_t filled = fill_holes(m, Connectivity::Face6);
    EXPECT_GT(filled, 0u);
    EXPECT_EQ(m(7, 7, 7), 1);  // the centre was enclosed
    EXPECT_EQ(m(0, 0, 0), 0);  // the outside is not
}

TEST(Components, KeepComponentAtMatchesTheLabelledComponent) {
    // Random masks (about half full, many components): keeping the component at a voxel equals
    // selecting that voxel's label from connected_components, for every connectivity.
    uint32_t state = 12345;
    auto next = [&] { return state = state * 1664525u + 1013904223u; };
    for (Connectivity c : {Connectivity::Face6, Connectivity::Edge18, Connectivity::Vertex26}) {
        for (int trial = 0; trial < 20; ++trial) {
            Volume<uint8_t> m(grid(9 + trial % 3, 7, 6 + trial % 4));
            for (size_t i = 0; i < m.size(); ++i) m[i] = (next() >> 16) % 100 < 45 ? uint8_t(1 + trial % 3) : 0;
            const Components ref = connected_components(m, c);
            const size_t at = (next() >> 8) % m.size();
            Volume<uint8_t> kept = m;
            const size_t n = keep_component_at(kept, at, c);
            const uint32_t want = ref.labels[at];
            EXPECT_EQ(n, want ? ref.sizes[want - 1] : 0u);
            for (size_t i = 0; i < m.size(); ++i)
                ASSERT_EQ(kept[i], want && ref.labels[i] == want ? 1 : 0) << "voxel " << i;
        }
    }
    Volume<uint8_t> m(grid(4, 4, 4), 1);
    EXPECT_EQ(keep_component_at(m, m.size(), Connectivity::Face6), 0u);  // outside: all cleared
    EXPECT_EQ(m(1, 1, 1), 0);
}

namespace {

// The brute-force reference: every pair of voxels compared by their coordinates (adjacent when
// they differ by at most 1 per axis, in at most 1 / 2 / 3 axes for 6 / 18 / 26), joined in a
// union-find; components numbered by their first voxel in scan order.
struct Reference {
    std::vector<uint32_t> labels;
    std::vector<size_t> sizes;
    std::vector<bool> touches_border;
};

Reference brute_force(const Volume<uint8_t>& m, Connectivity c, bool of_zeros = false) {
    const Dims& d = m.dims();
    const size_t n = m.size();
    const int max_axes = c == Connectivity::Face6 ? 1 : c == Connectivity::Edge18 ? 2 : 3;
    std::vector<size_t> parent(n);
    for (size_t i = 0; i < n; ++i) parent[i] = i;
    std::function<size_t(size_t)> find = [&](size_t i) { return parent[i] == i ? i : parent[i] = find(parent[i]); };
    auto coords = [&](size_t i) {
        return std::array<int64_t, 3>{int64_t(i % size_t(d[0])), int64_t(i / size_t(d[0]) % size_t(d[1])),
                                      int64_t(i / size_t(d[0] * d[1]))};
    };
    auto member = [&](size_t i) { return of_zeros ? m[i] == 0 : m[i] != 0; };
    for (size_t i = 0; i < n; ++i) {
        if (!member(i)) continue;
        for (size_t j = i + 1; j < n; ++j) {
            if (!member(j)) continue;
            const auto a = coords(i), b = coords(j);
            int axes = 0;
            bool near = true;
            for (int k = 0; k < 3; ++k) {
                const int64_t diff = std::abs(a[k] - b[k]);
                near &= diff <= 1;
                axes += diff == 1;
            }
            if (near && axes <= max_axes) parent[find(j)] = find(i);
        }
    }
    Reference r;
    r.labels.assign(n, 0);
    std::vector<uint32_t> label_of_root(n, 0);
    for (size_t i = 0; i < n; ++i) {
        if (!member(i)) continue;
        uint32_t& l = label_of_root[find(i)];
        if (l == 0) {
            r.sizes.push_back(0);
            r.touches_border.push_back(false);
            l = uint32_t(r.sizes.size());
        }
        r.labels[i] = l;
        ++r.sizes[l - 1];
        const auto a = coords(i);
        for (int k = 0; k < 3; ++k)
            if (a[k] == 0 || a[k] == d[k] - 1) r.touches_border[l - 1] = true;
    }
    return r;
}

}  // namespace

TEST(Components, MatchTheBruteForceReferenceOnRandomMasks) {
    uint32_t state = 2024;
    auto next = [&] { return state = state * 1664525u + 1013904223u; };
    for (Connectivity c : {Connectivity::Face6, Connectivity::Edge18, Connectivity::Vertex26}) {
        for (int trial = 0; trial < 12; ++trial) {
            Volume<uint8_t> m(grid(5 + trial % 4, 6, 4 + trial % 3));
            const uint32_t fill = 25 + 5 * uint32_t(trial);  // sparse to dense
            for (size_t i = 0; i < m.size(); ++i) m[i] = (next() >> 16) % 100 < fill ? 1 : 0;
            const Components got = connected_components(m, c);
            const Reference want = brute_force(m, c);
            ASSERT_EQ(got.labels, want.labels) << "trial " << trial;
            EXPECT_EQ(got.sizes, want.sizes);
            EXPECT_EQ(got.touches_border, want.touches_border);
            // fill_holes: exactly the zero voxels whose zero component touches no face.
            const Reference zeros = brute_force(m, c, true);
            Volume<uint8_t> filled = m;
            const size_t n = fill_holes(filled, c);
            size_t expect_n = 0;
            for (size_t i = 0; i < m.size(); ++i) {
                const bool enclosed = m[i] == 0 && !zeros.touches_border[zeros.labels[i] - 1];
                expect_n += enclosed;
                ASSERT_EQ(filled[i], m[i] || enclosed ? 1 : 0) << "voxel " << i;
            }
            EXPECT_EQ(n, expect_n);
        }
    }
}
