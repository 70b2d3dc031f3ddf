#include <gtest/gtest.h>

#include "endocast/components.h"
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
