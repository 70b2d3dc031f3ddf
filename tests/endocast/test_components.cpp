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
