#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "endocast/distance.h"
#include "endocast/seeds.h"
#include "endocast/watershed.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;

namespace {

// A closed spherical shell (cavity radius 10, centre (75,30,30)) beside two parallel bone plates
// (x = 3..5 and 50..52, spanning y and z) whose gap is deeper (22) but open to the border.
Volume<uint8_t> shell_and_plates() {
    Volume<uint8_t> bone(grid(100, 60, 60));
    for (int64_t z = 0; z < 60; ++z)
        for (int64_t y = 0; y < 60; ++y)
            for (int64_t x = 0; x < 100; ++x) {
                const double r = std::sqrt(double((x - 75) * (x - 75) + (y - 30) * (y - 30) + (z - 30) * (z - 30)));
                const bool plate = (x >= 3 && x <= 5) || (x >= 50 && x <= 52);
                bone(x, y, z) = plate || (r >= 10 && r <= 14);
            }
    return bone;
}

}  // namespace

TEST(Seeds, AutoChoosesTheEnclosedCavityNotTheDeepestSpace) {
    const auto bone = shell_and_plates();
    const auto d = distance_transform(bone);
    SeedParams largest;
    largest.mode = SeedMode::AutoLargest;
    const auto a = place_seeds(bone, d, largest);
    ASSERT_EQ(a.endocast_seeds_world.size(), 1u);
    EXPECT_LT(a.endocast_seeds_world[0][0], 50);  // the paper's rule takes the gap between the plates

    const auto b = place_seeds(bone, d);  // SeedMode::Auto
    ASSERT_GE(b.candidates.size(), 2u);
    ASSERT_FALSE(b.endocast_seeds_world.empty());
    EXPECT_NEAR(b.endocast_seeds_world[0][0], 75, 1.5);
    EXPECT_EQ(b.labels(75, 30, 30), kEndocast);
    // The chosen candidate is the enclosed one, and it scores best.
    int chosen = -1;
    for (size_t k = 0; k < b.candidates.size(); ++k)
        if (b.candidates[k].chosen && b.candidates[k].merged_into < 0) chosen = int(k);
    ASSERT_GE(chosen, 0);
    EXPECT_GT(b.candidates[chosen].enclosure, 0.95);
    for (const auto& c : b.candidates)
        if (!c.chosen) {
            EXPECT_LT(c.enclosure, 0.5);
            EXPECT_LT(c.score, b.candidates[chosen].score);
        }
    const auto w = watershed(b.labels, d);
    EXPECT_EQ(w.labels(75, 30, 36), kEndocast);
    EXPECT_EQ(w.labels(27, 30, 30), kOther);
}

// The border seeds are the union of the balls of radius scale * d(b) around the empty face voxels
// b: compared with a brute-force union on a random anisotropic volume (voxels within rounding of a
// ball's surface are not compared).
TEST(Seeds, BorderSeedsAreTheUnionOfTheFaceBalls) {
    const Geometry g = grid(23, 17, 13, {0.7, 1.1, 1.3});
    Volume<uint8_t> bone(g);
    uint32_t state = 12345;
    for (size_t i = 0; i < bone.size(); ++i) {
        state = state * 1664525u + 1013904223u;
        bone[i] = (state >> 24) < 50;  // about 20% bone
    }
    const auto d = distance_transform(bone);
    SeedParams p;
    p.mode = SeedMode::AutoLargest;
    p.scale = 0.6;
    const auto r = place_seeds(bone, d, p);
    size_t compared = 0, covered = 0;
    for (int64_t z = 0; z < 13; ++z)
        for (int64_t y = 0; y < 17; ++y)
            for (int64_t x = 0; x < 23; ++x) {
                if (bone(x, y, z)) continue;
                double best = std::numeric_limits<double>::infinity();
                for (int64_t bz = 0; bz < 13; ++bz)
                    for (int64_t by = 0; by < 17; ++by)
                        for (int64_t bx = 0; bx < 23; ++bx) {
                            const bool face = bx == 0 || by == 0 || bz == 0 || bx == 22 || by == 16 || bz == 12;
                            if (!face || bone(bx, by, bz)) continue;
                            const double rb = p.scale * d(bx, by, bz);
                            const double dx = (x - bx) * 0.7, dy = (y - by) * 1.1, dz = (z - bz) * 1.3;
                            best = std::min(best, dx * dx + dy * dy + dz * dz - rb * rb);
                        }
                if (std::fabs(best) < 1e-4) continue;
                ++compared;
                covered += best < 0;
                EXPECT_EQ(r.labels(x, y, z) == kOther, best < 0) << x << " " << y << " " << z;
            }
    EXPECT_GT(compared, 3000u);
    EXPECT_GT(covered, 500u);
    EXPECT_LT(covered, compared);
}

TEST(Seeds, ModeNames) {
    EXPECT_EQ(to_string(SeedMode::Auto), "auto");
    EXPECT_EQ(to_string(SeedMode::Point), "point");
    EXPECT_EQ(to_string(SeedMode::AutoLargest), "auto-largest");
}
