#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "endocast/stages/distance.h"
#include "endocast/stages/resample.h"
#include "endocast/stages/seeds.h"
#include "endocast/stages/watershed.h"
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

// Brute force: min over the empty face voxels b of the volume of |x - b|^2 - (scale d(b))^2 (mm^2),
// negative inside the union of their balls.
double face_ball_margin(const Volume<uint8_t>& bone, const Volume<float>& d, double scale, int64_t x,
                        int64_t y, int64_t z) {
    const Dims& n = bone.dims();
    const auto& s = bone.geometry().spacing;
    double best = std::numeric_limits<double>::infinity();
    for (int64_t bz = 0; bz < n[2]; ++bz)
        for (int64_t by = 0; by < n[1]; ++by)
            for (int64_t bx = 0; bx < n[0]; ++bx) {
                const bool face = bx == 0 || by == 0 || bz == 0 || bx == n[0] - 1 || by == n[1] - 1 || bz == n[2] - 1;
                if (!face || bone(bx, by, bz)) continue;
                const double rb = scale * d(bx, by, bz);
                const double dx = double(x - bx) * s[0], dy = double(y - by) * s[1], dz = double(z - bz) * s[2];
                best = std::min(best, dx * dx + dy * dy + dz * dz - rb * rb);
            }
    return best;
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
                const double best = face_ball_margin(bone, d, p.scale, x, y, z);
                if (std::fabs(best) < 1e-4) continue;
                ++compared;
                covered += best < 0;
                EXPECT_EQ(r.labels(x, y, z) == kOther, best < 0) << x << " " << y << " " << z;
            }
    EXPECT_GT(compared, 3000u);
    EXPECT_GT(covered, 500u);
    EXPECT_LT(covered, compared);
}

// On a box of a scan (SeedParams::box_lo, scan_dims) whose voxels outside the box are empty, the
// border seeds are the scan's: the balls of the scan's face voxels (radius scale * their distance
// to bone in the whole scan) within the box, and the empty voxels of the box's faces inside the
// scan. Brute force on the whole scan; one face of the box is the scan's own.
TEST(Seeds, BorderSeedsOfABoxAreTheScansBorderSeeds) {
    const Geometry gs = grid(23, 17, 13, {0.7, 1.1, 1.3});
    Volume<uint8_t> scan(gs);
    uint32_t state = 777;
    for (int64_t z = 3; z < 10; ++z)
        for (int64_t y = 4; y < 13; ++y)
            for (int64_t x = 5; x < 18; ++x) {
                state = state * 1664525u + 1013904223u;
                scan(x, y, z) = (state >> 24) < 60;
            }
    const auto ds = distance_transform(scan);
    const Dims lo{3, 2, 0}, hi{20, 15, 12};  // the -z face is the scan's
    const CropBox box{lo, hi};
    const Volume<uint8_t> bone = crop(scan, box);
    SeedParams p;
    p.mode = SeedMode::AutoLargest;
    p.scale = 0.6;
    p.box_lo = lo;
    p.scan_dims = gs.dims;
    const auto r = place_seeds(bone, distance_transform(bone), p);
    size_t compared = 0, covered = 0, on_faces = 0;
    for (int64_t z = lo[2]; z < hi[2]; ++z)
        for (int64_t y = lo[1]; y < hi[1]; ++y)
            for (int64_t x = lo[0]; x < hi[0]; ++x) {
                if (scan(x, y, z)) continue;
                const double best = face_ball_margin(scan, ds, p.scale, x, y, z);
                const bool box_face = x == lo[0] || x == hi[0] - 1 || y == lo[1] || y == hi[1] - 1 || z == hi[2] - 1;
                const uint8_t got = r.labels(x - lo[0], y - lo[1], z - lo[2]);
                if (box_face) {
                    ++on_faces;
                    EXPECT_EQ(got, kOther) << x << " " << y << " " << z;
                    continue;
                }
                if (std::fabs(best) < 1e-3) continue;
                ++compared;
                covered += best < 0;
                EXPECT_EQ(got == kOther, best < 0) << x << " " << y << " " << z;
            }
    EXPECT_GT(compared, 800u);
    EXPECT_GT(covered, 100u);
    EXPECT_LT(covered, compared);
    EXPECT_GT(on_faces, 500u);
}

TEST(Seeds, ModeNames) {
    EXPECT_EQ(to_string(SeedMode::Auto), "auto");
    EXPECT_EQ(to_string(SeedMode::Point), "point");
    EXPECT_EQ(to_string(SeedMode::AutoLargest), "auto-largest");
}
