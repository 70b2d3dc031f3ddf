#include <gtest/gtest.h>

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
