#include <gtest/gtest.h>

#include <queue>
#include <random>

#include "endocast/components.h"
#include "endocast/distance.h"
#include "endocast/seeds.h"
#include "endocast/watershed.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;

namespace {

// Reference flood: a binary heap ordered by (quantized distance desc, push order asc).
Volume<uint8_t> reference_flood(const Volume<uint8_t>& seeds, const Volume<float>& d, double quantum) {
    Volume<uint8_t> lab = seeds;
    using Item = std::tuple<int64_t, int64_t, size_t>;  // level, -seq, index
    std::priority_queue<Item> q;
    int64_t seq = 0;
    auto level = [&](size_t i) { return int64_t(double(d[i]) / quantum); };
    for (size_t i = 0; i < lab.size(); ++i)
        if (lab[i] == kEndocast || lab[i] == kOther) q.emplace(level(i), -seq++, i);
    const auto offs = neighbour_offsets(Connectivity::Face6);
    const int64_t nx = lab.nx(), ny = lab.ny();
    while (!q.empty()) {
        const size_t i = std::get<2>(q.top());
        q.pop();
        const int64_t x = int64_t(i) % nx, y = (int64_t(i) / nx) % ny, z = int64_t(i) / (nx * ny);
        for (const auto& o : offs) {
            if (!lab.contains(x + o[0], y + o[1], z + o[2])) continue;
            const size_t j = lab.index(x + o[0], y + o[1], z + o[2]);
            if (lab[j] != kUnlabelled) continue;
            lab[j] = lab[i];
            q.emplace(level(j), -seq++, j);
        }
    }
    return lab;
}

}  // namespace

TEST(Watershed, MatchesReferenceFloodOnRandomVolumes) {
    for (uint32_t seed = 1; seed <= 6; ++seed) {
        const auto bone = endocast::testing::random_mask(grid(17, 15, 13, {1, 0.8, 1.6}), 0.15, seed);
        const auto d = distance_transform(bone);
        Volume<uint8_t> seeds(bone.geometry());
        std::mt19937 rng(seed);
        for (size_t i = 0; i < seeds.size(); ++i) {
            seeds[i] = bone[i] ? kBone : kUnlabelled;
            if (!bone[i] && rng() % 40 == 0) seeds[i] = (rng() % 2) ? kEndocast : kOther;
        }
        WatershedParams p;
        p.quantum_mm = 0.8 / 64.0;
        const auto r = watershed(seeds, d, p);
        const auto ref = reference_flood(seeds, d, p.quantum_mm);
        ASSERT_EQ(r.labels.buffer(), ref.buffer()) << "seed " << seed;
        // Flooded in the seeds' own memory: the same labels and counts.
        Volume<uint8_t> moved = seeds;
        const auto in_place = watershed(std::move(moved), d, p);
        EXPECT_EQ(in_place.labels.buffer(), ref.buffer()) << "seed " << seed;
        EXPECT_EQ(in_place.labels.geometry().dims, seeds.geometry().dims);
        EXPECT_EQ(in_place.endocast_voxels, r.endocast_voxels);
        EXPECT_EQ(in_place.unreached_voxels, r.unreached_voxels);
    }
}

TEST(Watershed, SplitsTwoChambersAtTheirNarrowConnection) {
    // Two spherical chambers (radius 9) joined by a narrow canal (radius 2) in solid bone.
    Volume<uint8_t> bone(grid(60, 24, 24), 1);
    for (int64_t z = 0; z < 24; ++z)
        for (int64_t y = 0; y < 24; ++y)
            for (int64_t x = 0; x < 60; ++x) {
                const double dy = y - 11.5, dz = z - 11.5;
                const double a = (x - 15) * (x - 15) + dy * dy + dz * dz;
                const double b = (x - 44) * (x - 44) + dy * dy + dz * dz;
                if (a <= 81 || b <= 81 || (dy * dy + dz * dz <= 4 && x > 15 && x < 44))
                    bone(x, y, z) = 0;
            }
    const auto d = distance_transform(bone);
    Volume<uint8_t> seeds(bone.geometry());
    for (size_t i = 0; i < seeds.size(); ++i) seeds[i] = bone[i] ? kBone : kUnlabelled;
    seeds(15, 12, 12) = kEndocast;
    seeds(44, 12, 12) = kOther;
    const auto r = watershed(seeds, d);
    EXPECT_EQ(r.unreached_voxels, 0u);
    // Each chamber is entirely one label.
    EXPECT_EQ(r.labels(10, 12, 12), kEndocast);
    EXPECT_EQ(r.labels(22, 12, 12), kEndocast);
    EXPECT_EQ(r.labels(38, 12, 12), kOther);
    EXPECT_EQ(r.labels(50, 12, 12), kOther);
}

TEST(Seeds, AutoSeedsFindTheEnclosedCavity) {
    // A closed shell (cavity radius 12) in a box: endocast seed at the centre, other at the border.
    const auto g = grid(41, 41, 41);
    const auto bone = endocast::testing::shell(g, 12.0, 16.0);
    const auto d = distance_transform(bone);
    const auto s = place_seeds(bone, d);
    ASSERT_EQ(s.endocast_seeds_world.size(), 1u);
    EXPECT_NEAR(s.endocast_seeds_world[0][0], 20, 1.0);
    EXPECT_NEAR(s.endocast_seeds_world[0][1], 20, 1.0);
    EXPECT_NEAR(s.endocast_seeds_world[0][2], 20, 1.0);
    EXPECT_EQ(s.labels(20, 20, 20), kEndocast);
    EXPECT_EQ(s.labels(0, 0, 0), kOther);
    EXPECT_GT(s.endocast_seed_voxels, 1000u);  // ball of radius 0.9 * ~12
    const auto w = watershed(s.labels, d);
    // The whole cavity (radius < 12) is endocast, the whole outside is other.
    EXPECT_EQ(w.labels(20, 20, 31), kEndocast);
    EXPECT_EQ(w.labels(20, 20, 38), kOther);
}

TEST(Seeds, PointAndDistanceModes) {
    const auto g = grid(41, 41, 41);
    const auto bone = endocast::testing::shell(g, 12.0, 16.0);
    const auto d = distance_transform(bone);
    SeedParams p;
    p.mode = SeedMode::Point;
    p.points_world = {{22, 20, 18}};
    const auto s = place_seeds(bone, d, p);
    EXPECT_EQ(s.labels(22, 20, 18), kEndocast);
    p.points_world = {{20, 20, 34}};  // in bone
    EXPECT_THROW(place_seeds(bone, d, p), InvalidParameter);
    p.points_world = {{200, 20, 20}};  // outside the volume
    EXPECT_THROW(place_seeds(bone, d, p), InvalidParameter);

    SeedParams q;
    q.mode = SeedMode::Distance;
    q.distance_threshold_mm = 5;
    const auto t = place_seeds(bone, d, q);
    EXPECT_EQ(t.labels(20, 20, 20), kEndocast);
    EXPECT_EQ(t.labels(0, 0, 0), kOther);
    q.distance_threshold_mm = 50;  // nothing that deep
    EXPECT_THROW(place_seeds(bone, d, q), NoResult);
    q.distance_threshold_mm = 0;
    EXPECT_THROW(place_seeds(bone, d, q), InvalidParameter);
}

TEST(Seeds, OpenSkullHasNoEnclosedCavity) {
    // Bone only in a thin slab: every empty voxel is reached by border balls of radius 0.9 d.
    Volume<uint8_t> bone(grid(20, 20, 20));
    for (int64_t y = 0; y < 20; ++y)
        for (int64_t x = 0; x < 20; ++x) bone(x, y, 10) = 1;
    const auto d = distance_transform(bone);
    SeedParams p;
    EXPECT_THROW(place_seeds(bone, d, p), NoResult);  // no enclosed cavity: a clear error
    p.scale = 1.5;
    EXPECT_THROW(place_seeds(bone, d, p), InvalidParameter);  // the scale is checked
}
