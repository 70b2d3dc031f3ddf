#include <gtest/gtest.h>

#include "meshpost/mesh.h"

TEST(TriangleMesh, Counts) {
    meshpost::TriangleMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    m.faces = {{0, 1, 2}};
    EXPECT_EQ(m.vertex_count(), 3u);
    EXPECT_EQ(m.face_count(), 1u);
}

// The first face with an index beyond the vertices, among many faces (checked on all threads), or
// the face count when there is none.
TEST(TriangleMesh, FirstFaceWithBadIndex) {
    meshpost::TriangleMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    m.faces.assign(100000, {0, 1, 2});
    EXPECT_EQ(meshpost::first_face_with_bad_index(m), m.faces.size());
    m.faces[77777] = {0, 3, 2};
    m.faces[99999] = {5, 1, 2};
    EXPECT_EQ(meshpost::first_face_with_bad_index(m), 77777u);
    m.faces[123] = {0, 1, 4000000000u};
    EXPECT_EQ(meshpost::first_face_with_bad_index(m), 123u);
    EXPECT_EQ(meshpost::first_face_with_bad_index(meshpost::TriangleMesh{}), 0u);
}
