#include <gtest/gtest.h>

#include "meshpost/mesh.h"

TEST(TriangleMesh, Counts) {
    meshpost::TriangleMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    m.faces = {{0, 1, 2}};
    EXPECT_EQ(m.vertex_count(), 3u);
    EXPECT_EQ(m.face_count(), 1u);
}
