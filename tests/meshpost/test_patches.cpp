// face_neighbours and face_patches (patches.h) against brute-force references.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "meshpost/patches.h"
#include "test_meshes.h"

using namespace meshpost;
using namespace meshpost::test;

namespace {

// Whether faces f and g share the edge from corner a of f to corner a+1 (either direction).
bool shares_edge(const TriangleMesh& m, uint32_t f, int a, uint32_t g) {
    const uint32_t u = m.faces[f][size_t(a)], w = m.faces[f][size_t((a + 1) % 3)];
    const Face& o = m.faces[g];
    auto has = [&](uint32_t v) { return o[0] == v || o[1] == v || o[2] == v; };
    return g != f && has(u) && has(w);
}

// Patch labels by repeated relaxation (each face takes the smallest label among its members'
// edge neighbours, found by comparing every pair of faces) until nothing changes.
std::vector<int64_t> brute_labels(const TriangleMesh& m, const std::vector<uint8_t>& member) {
    std::vector<int64_t> l(m.faces.size(), -1);
    for (uint32_t f = 0; f < m.faces.size(); ++f)
        if (member[f]) l[f] = f;
    for (bool changed = true; changed;) {
        changed = false;
        for (uint32_t f = 0; f < m.faces.size(); ++f)
            for (uint32_t g = 0; g < m.faces.size(); ++g) {
                if (!member[f] || !member[g]) continue;
                bool adjacent = false;
                for (int a = 0; a < 3; ++a) adjacent |= shares_edge(m, f, a, g);
                if (adjacent && l[g] < l[f]) l[f] = l[g], changed = true;
            }
    }
    return l;
}

}  // namespace

TEST(Patches, FaceNeighboursAreTheFacesAcrossEachEdge) {
    for (const TriangleMesh& m : {icosphere(1.0, 2), torus(2.0, 0.5, 12, 8), cube()}) {
        const auto nb = face_neighbours(m);
        ASSERT_EQ(nb.size(), m.faces.size());
        for (uint32_t f = 0; f < m.faces.size(); ++f)
            for (int a = 0; a < 3; ++a) {
                uint32_t expected = kNoFace;
                for (uint32_t g = 0; g < m.faces.size() && expected == kNoFace; ++g)
                    if (shares_edge(m, f, a, g)) expected = g;
                EXPECT_EQ(nb[f][size_t(a)], expected) << "face " << f << " edge " << a;
            }
    }
}

// A soup of random faces on few vertices (edges shared by many faces): the neighbour across an edge
// is the first other face in face order that has it, with 1, 2 or 3 threads (the faces around a
// vertex are sorted on several threads).
TEST(Patches, FaceNeighboursOfASoupAreTheFirstInFaceOrderForAnyThreadCount) {
    TriangleMesh m;
    for (int v = 0; v < 9; ++v) m.vertices.push_back({double(v), double(v * v % 7), 0.0});
    std::mt19937 rng(5);
    for (int f = 0; f < 3001; ++f) {
        const uint32_t a = rng() % 9, b = (a + 1 + rng() % 8) % 9;
        uint32_t c = rng() % 9;
        while (c == a || c == b) c = rng() % 9;
        m.faces.push_back({a, b, c});
    }
    const int threads = omp_get_max_threads();
    for (int t : {1, 2, 3}) {
        omp_set_num_threads(t);
        const auto nb = face_neighbours(m);
        for (uint32_t f = 0; f < m.faces.size(); f += 7)
            for (int a = 0; a < 3; ++a) {
                uint32_t expected = kNoFace;
                for (uint32_t g = 0; g < m.faces.size() && expected == kNoFace; ++g)
                    if (shares_edge(m, f, a, g)) expected = g;
                ASSERT_EQ(nb[f][size_t(a)], expected) << "face " << f << " edge " << a << ", " << t << " threads";
            }
    }
    omp_set_num_threads(threads);
}

TEST(Patches, AnOpenMeshHasNoFaceAcrossItsBoundaryEdges) {
    TriangleMesh m = cube();
    m.faces.pop_back();  // a hole: the three edges of the removed face are boundary edges
    const auto nb = face_neighbours(m);
    size_t boundary = 0;
    for (const auto& e : nb)
        for (uint32_t g : e) boundary += g == kNoFace;
    EXPECT_EQ(boundary, 3u);
}

TEST(Patches, PatchesMatchABruteForceReferenceOnRandomFaceSets) {
    const TriangleMesh m = icosphere(1.0, 2);  // 320 faces
    const auto nb = face_neighbours(m);
    std::mt19937 rng(7);
    for (double p : {0.2, 0.5, 0.8, 1.0}) {
        std::bernoulli_distribution in(p);
        std::vector<uint8_t> member(m.faces.size());
        for (auto& x : member) x = in(rng);
        const auto patches = face_patches(nb, member);
        const std::vector<int64_t> ref = brute_labels(m, member);
        std::vector<int64_t> got(m.faces.size(), -1);
        uint32_t previous_first = 0;
        for (size_t id = 0; id < patches.size(); ++id) {
            ASSERT_FALSE(patches[id].empty());
            EXPECT_EQ(patches[id].front(), *std::min_element(patches[id].begin(), patches[id].end()))
                << "a patch starts at its lowest face";
            if (id > 0) EXPECT_GT(patches[id].front(), previous_first) << "patches in order of their lowest face";
            previous_first = patches[id].front();
            for (uint32_t f : patches[id]) {
                EXPECT_EQ(got[f], -1) << "face " << f << " in two patches";
                got[f] = patches[id].front();
            }
        }
        EXPECT_EQ(got, ref) << "share " << p;
    }
}

TEST(Patches, BadInputIsAnError) {
    TriangleMesh m = cube();
    EXPECT_THROW(face_patches(face_neighbours(m), std::vector<uint8_t>(3, 1)), InvalidMesh);
    m.faces.push_back({0, 1, 99});
    EXPECT_THROW(face_neighbours(m), InvalidMesh);
}

TEST(Patches, FacesTouchingListedVerticesMatchABruteForceReference) {
    const TriangleMesh m = icosphere(1.0, 2);
    std::mt19937 rng(11);
    for (size_t count : {size_t(0), size_t(1), size_t(5), size_t(40)}) {
        std::vector<uint32_t> listed;
        for (size_t k = 0; k < count; ++k) listed.push_back(uint32_t(rng() % m.vertices.size()));
        if (count > 1) listed.push_back(listed.front());  // a repeat
        const std::vector<uint8_t> got = faces_touching(m, listed);
        ASSERT_EQ(got.size(), m.faces.size());
        for (size_t f = 0; f < m.faces.size(); ++f) {
            uint8_t want = 0;
            for (uint32_t v : m.faces[f]) want |= uint8_t(std::find(listed.begin(), listed.end(), v) != listed.end());
            EXPECT_EQ(got[f], want) << "face " << f << ", " << count << " listed";
        }
    }
    EXPECT_THROW(faces_touching(m, {uint32_t(m.vertices.size())}), InvalidMesh);
    TriangleMesh bad = m;
    bad.faces.push_back({0, 1, 9999});
    EXPECT_EQ(faces_touching(bad, {}).back(), 1) << "a face beyond the mesh counts as touching";
}
