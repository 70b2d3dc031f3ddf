#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <queue>
#include <random>

#include "endocast/stages/components.h"
#include "endocast/stages/distance.h"
#include "endocast/errors.h"
#include "endocast/stages/seeds.h"
#include "endocast/stages/watershed.h"
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

namespace {

// Random seeds of `labels` (each with probability 1/40) on the empty voxels of random bone, and a
// priority field whose quantized levels are all different (a random permutation), so that no two
// voxels tie: the watershed is then unique.
struct Field {
    Volume<uint8_t> seeds;
    Volume<float> d;
    WatershedParams p;
};
Field random_field(uint32_t seed, const std::vector<uint8_t>& labels) {
    Field f;
    const auto bone = endocast::testing::random_mask(grid(17, 15, 13, {1, 0.8, 1.6}), 0.15, seed);
    f.seeds = Volume<uint8_t>(bone.geometry());
    f.d = Volume<float>(bone.geometry());
    std::mt19937 rng(seed);
    std::vector<size_t> perm(f.d.size());
    for (size_t i = 0; i < perm.size(); ++i) perm[i] = i;
    std::shuffle(perm.begin(), perm.end(), rng);
    f.p.quantum_mm = 0.001;
    for (size_t i = 0; i < f.seeds.size(); ++i) {
        f.d[i] = float((double(perm[i]) + 0.5) * f.p.quantum_mm);
        f.seeds[i] = bone[i] ? kBone : kUnlabelled;
        if (!bone[i] && rng() % 40 == 0) f.seeds[i] = labels[rng() % labels.size()];
    }
    return f;
}

}  // namespace

// The flood runs on the unlabelled voxels' box grown by one voxel: with every voxel outside a
// corner box labelled (seeds next to it on all sides, some at the volume's faces), the labels are
// the reference flood's; with no unlabelled voxel, the seeds come back as they are.
TEST(Watershed, FloodOnTheUnlabelledVoxelsBoxMatchesReference) {
    for (uint32_t seed = 1; seed <= 6; ++seed) {
        const auto bone = endocast::testing::random_mask(grid(19, 16, 14, {1, 0.8, 1.6}), 0.15, seed);
        const auto d = distance_transform(bone);
        Volume<uint8_t> seeds(bone.geometry());
        std::mt19937 rng(seed);
        const int64_t x0 = seed % 3 == 0 ? 0 : 4, y0 = 3, z0 = seed % 2 ? 2 : 0;  // the box: [x0, 12) x [y0, 11) x [z0, 9)
        for (int64_t z = 0; z < seeds.nz(); ++z)
            for (int64_t y = 0; y < seeds.ny(); ++y)
                for (int64_t x = 0; x < seeds.nx(); ++x) {
                    const size_t i = seeds.index(x, y, z);
                    const bool inside = x >= x0 && x < 12 && y >= y0 && y < 11 && z >= z0 && z < 9;
                    if (bone[i]) seeds[i] = kBone;
                    else if (!inside || rng() % 40 == 0) seeds[i] = (rng() % 2) ? kEndocast : kOther;
                    else seeds[i] = kUnlabelled;
                }
        WatershedParams p;
        p.quantum_mm = 0.8 / 64.0;
        const auto ref = reference_flood(seeds, d, p.quantum_mm);
        EXPECT_EQ(watershed(seeds, d, p).labels.buffer(), ref.buffer()) << "seed " << seed;
        Volume<uint8_t> moved = seeds;
        EXPECT_EQ(watershed(std::move(moved), d, p).labels.buffer(), ref.buffer()) << "seed " << seed;
        // Everything labelled (a voxel bone walls in, left unreached, labelled too): nothing to flood.
        Volume<uint8_t> all = ref;
        for (size_t i = 0; i < all.size(); ++i)
            if (all[i] == kUnlabelled) all[i] = kOther;
        const WatershedResult again = watershed(all, d, p);
        EXPECT_EQ(again.labels.buffer(), all.buffer());
        EXPECT_EQ(again.unreached_voxels, 0u);
    }
}

// The recorded level of a voxel is the best path's bottleneck: the highest, over paths from a seed
// through empty voxels, of the lowest level on the path (its seed's and its own included), found by
// relaxation (for every voxel the flood reached from a seed). The labels are the plain flood's.
// At about 3 thousand levels (the flood keeps each voxel's own level in the record) and at 33
// thousand (above 2^15: it reads them from the distance).
TEST(Watershed, FloodLevelsAreTheBottleneckOfTheBestPath) {
    for (uint32_t seed = 1; seed <= 8; ++seed) {
        Field f = random_field(seed, {kEndocast, kOther});
        if (seed > 4) f.p.quantum_mm /= 10;
        FloodLevels levels;
        Volume<uint8_t> s = f.seeds;
        const WatershedResult r = watershed(std::move(s), f.d, f.p, levels);
        ASSERT_FALSE(levels.empty());
        EXPECT_EQ(levels.levels > 32768, seed > 4);
        EXPECT_EQ(r.labels.buffer(), watershed(f.seeds, f.d, f.p).labels.buffer());
        auto level = [&](size_t i) { return int64_t(flood_level(f.d[i], levels.quantum_mm, levels.levels)); };
        std::vector<int64_t> best(f.d.size(), -1);
        for (size_t i = 0; i < best.size(); ++i)
            if (f.seeds[i] != kUnlabelled && f.seeds[i] != kBone) best[i] = level(i);
        const auto offs = neighbour_offsets(Connectivity::Face6);
        const Volume<uint8_t>& g = f.seeds;
        for (bool changed = true; changed;) {
            changed = false;
            for (int64_t z = 0; z < g.nz(); ++z)
                for (int64_t y = 0; y < g.ny(); ++y)
                    for (int64_t x = 0; x < g.nx(); ++x) {
                        const size_t i = g.index(x, y, z);
                        if (g[i] == kBone) continue;
                        for (const auto& o : offs) {
                            if (!g.contains(x + o[0], y + o[1], z + o[2])) continue;
                            const int64_t b = best[g.index(x + o[0], y + o[1], z + o[2])];
                            if (b < 0) continue;
                            const int64_t via = std::min(b, level(i));
                            if (via > best[i]) best[i] = via, changed = true;
                        }
                    }
        }
        size_t reached = 0;
        for (size_t i = 0; i < best.size(); ++i) {
            if (f.seeds[i] != kUnlabelled || best[i] < 0) continue;  // a seed's level is its own
            ASSERT_EQ(int64_t(levels.level[i]), best[i]) << i << " seed " << seed;
            ++reached;
        }
        EXPECT_GT(reached, f.d.size() / 2);
    }
}

// A flood of four seed labels, two of them then taken away (one merged into kEndocast, one into
// kOther, two flooded again): resumed, it is the flood of the seeds kept, voxel for voxel.
TEST(Watershed, ResumedFloodIsTheFloodOfTheSeedsKept) {
    const uint8_t a = kBone + 1, b = kBone + 2, c = kBone + 3, e = kBone + 4;
    for (uint32_t seed = 1; seed <= 8; ++seed) {
        const Field f = random_field(seed + 100, {kEndocast, kOther, a, b, c, e});
        FloodLevels levels;
        Volume<uint8_t> s = f.seeds;
        Volume<uint8_t> start = watershed(std::move(s), f.d, f.p, levels).labels;
        Volume<uint8_t> kept = f.seeds;
        auto map = [&](uint8_t l) -> uint8_t {
            if (l == a) return kEndocast;
            if (l == c) return kOther;
            if (l == b || l == e) return kUnlabelled;
            return l;
        };
        for (size_t i = 0; i < start.size(); ++i) start[i] = map(start[i]), kept[i] = map(kept[i]);
        const WatershedResult resumed = resume_watershed(std::move(start), levels, f.d, f.p);
        const WatershedResult full = watershed(kept, f.d, f.p);
        EXPECT_EQ(resumed.labels.buffer(), full.labels.buffer()) << "seed " << seed;
        EXPECT_EQ(resumed.endocast_voxels, full.endocast_voxels);
        EXPECT_EQ(resumed.unreached_voxels, full.unreached_voxels);
    }
    // Levels of another flood are refused.
    const Field f = random_field(3, {kEndocast, kOther});
    FloodLevels levels;
    Volume<uint8_t> s = f.seeds;
    watershed(std::move(s), f.d, f.p, levels);
    WatershedParams coarser = f.p;
    coarser.quantum_mm = 0.002;
    EXPECT_THROW(resume_watershed(Volume<uint8_t>(f.seeds), levels, f.d, coarser), InvalidParameter);
    levels.level.pop_back();
    EXPECT_THROW(resume_watershed(Volume<uint8_t>(f.seeds), levels, f.d, f.p), InvalidParameter);
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

// With keep_flood the automatic seeds come with their candidate flood made the watershed's start:
// resumed, the watershed of the seeds (up to ties within a quantum: the distances of a shell tie
// often); without it, or in the other modes, none.
TEST(Seeds, TheCandidateFloodResumedIsTheWatershedOfTheSeeds) {
    // Two closed shells side by side: the cavities of radius 12 (chosen) and 6 (rejected).
    Volume<uint8_t> bone(grid(64, 41, 41), 0);
    for (int64_t z = 0; z < 41; ++z)
        for (int64_t y = 0; y < 41; ++y)
            for (int64_t x = 0; x < 64; ++x) {
                const double a = std::hypot(x - 20.0, y - 20.0, z - 20.0), b = std::hypot(x - 50.0, y - 20.0, z - 20.0);
                bone(x, y, z) = (a > 12 && a <= 16) || (b > 6 && b <= 9);
            }
    const auto d = distance_transform(bone);
    SeedParams p;
    EXPECT_FALSE(place_seeds(bone, d, p).flood);
    p.keep_flood = true;
    SeedResult s = place_seeds(bone, d, p);
    ASSERT_TRUE(s.flood);
    ASSERT_GE(s.candidates.size(), 2u);
    const WatershedResult full = watershed(s.labels, d);
    const WatershedResult resumed = resume_watershed(std::move(s.flood->labels), s.flood->levels, d);
    size_t differ = 0;
    for (size_t i = 0; i < full.labels.size(); ++i) differ += full.labels[i] != resumed.labels[i];
    EXPECT_LE(double(differ), 1e-3 * double(full.labels.size()));
    EXPECT_EQ(resumed.labels(20, 20, 31), kEndocast);
    EXPECT_EQ(resumed.labels(50, 20, 20), kOther);  // the rejected chamber
    EXPECT_EQ(resumed.labels(54, 20, 20), kOther);
    EXPECT_EQ(resumed.labels(20, 20, 38), kOther);
    EXPECT_EQ(resumed.unreached_voxels, full.unreached_voxels);
    p.mode = SeedMode::Point;
    p.points_world = {{20, 20, 20}};
    EXPECT_FALSE(place_seeds(bone, d, p).flood);
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
