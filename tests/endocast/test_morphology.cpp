#include <gtest/gtest.h>

#include <cmath>

#include "endocast/errors.h"
#include "endocast/stages/morphology.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;
using endocast::testing::random_mask;

namespace {

// Brute-force dilation/erosion with the same closed-ball rule (|offset|_mm <= r).
Volume<uint8_t> brute(const Volume<uint8_t>& m, double r, bool dilate) {
    const auto& s = m.geometry().spacing;
    const double r2 = r * r * (1 + 1e-6) + 1e-9;
    Volume<uint8_t> out(m.geometry());
    for (int64_t z = 0; z < m.nz(); ++z)
        for (int64_t y = 0; y < m.ny(); ++y)
            for (int64_t x = 0; x < m.nx(); ++x) {
                bool hit = false;  // dilate: a feature within r; erode: a background within r
                for (int64_t c = 0; c < m.nz() && !hit; ++c)
                    for (int64_t b = 0; b < m.ny() && !hit; ++b)
                        for (int64_t a = 0; a < m.nx() && !hit; ++a) {
                            const double dx = (a - x) * s[0], dy = (b - y) * s[1], dz = (c - z) * s[2];
                            if (dx * dx + dy * dy + dz * dz > r2) continue;
                            hit = dilate ? m(a, b, c) != 0 : m(a, b, c) == 0;
                        }
                out(x, y, z) = dilate ? hit : !hit;
            }
    return out;
}

}  // namespace

TEST(Morphology, DilateAndErodeMatchBruteForceBalls) {
    const Vec3 spacings[] = {{1, 1, 1}, {1, 1, 2}, {0.6, 0.9, 1.2}};
    const double radii[] = {1.0, 2.0, 2.5, 3.7};
    uint32_t seed = 11;
    for (const auto& sp : spacings)
        for (double r : radii) {
            const auto m = random_mask(grid(12, 11, 10, sp), 0.04, seed);
            EXPECT_EQ(dilate_ball(m, r).buffer(), brute(m, r, true).buffer()) << "r=" << r;
            const auto m2 = random_mask(grid(12, 11, 10, sp), 0.9, seed++);
            EXPECT_EQ(erode_ball(m2, r).buffer(), brute(m2, r, false).buffer()) << "r=" << r;
        }
}

// Rows wide enough for the windowed pass's 16-float vectors and its scalar tail (35 = 2*16 + 3),
// windows of a few samples (r = 2.2 mm), and a radius whose window is too wide for it (r = 12 mm,
// 18+ samples along y and x: the parabola envelope), both against brute force.
TEST(Morphology, WindowedAndEnvelopePassesMatchBruteForce) {
    const Vec3 sp{0.5, 0.7, 1.1};
    uint32_t seed = 91;
    for (double r : {2.2, 12.0}) {
        const auto m = random_mask(grid(35, 20, 16, sp), 0.01, seed++);
        EXPECT_EQ(dilate_ball(m, r).buffer(), brute(m, r, true).buffer()) << "r=" << r;
        const auto m2 = random_mask(grid(35, 20, 16, sp), 0.97, seed++);
        EXPECT_EQ(erode_ball(m2, r).buffer(), brute(m2, r, false).buffer()) << "r=" << r;
    }
}

TEST(Morphology, ClosingContainsTheInput) {
    const auto m = random_mask(grid(16, 14, 12, {1, 1, 2}), 0.3, 5);
    const auto c = close_ball(m, 2.0);
    for (size_t i = 0; i < m.size(); ++i)
        if (m[i]) ASSERT_TRUE(c[i]);
}

namespace {

// Brute-force closing with walled faces: brute dilation then erosion over the volume grown by
// the ball's reach beyond each walled face, everything there foreground; nothing beyond the other
// faces (brute's own rule: background for the dilation, foreground for the erosion).
Volume<uint8_t> brute_walled_close(const Volume<uint8_t>& m, double r, const WalledFaces& w) {
    int64_t lo[3];
    Geometry pg = m.geometry();
    for (size_t a = 0; a < 3; ++a) {
        const int64_t reach = int64_t(std::ceil(r / pg.spacing[a])) + 1;
        lo[a] = w[2 * a] ? reach : 0;
        pg.dims[a] += lo[a] + (w[2 * a + 1] ? reach : 0);
    }
    Volume<uint8_t> padded(pg, 1);
    for (int64_t z = 0; z < m.nz(); ++z)
        for (int64_t y = 0; y < m.ny(); ++y)
            for (int64_t x = 0; x < m.nx(); ++x) padded(x + lo[0], y + lo[1], z + lo[2]) = m(x, y, z);
    const Volume<uint8_t> closed = brute(brute(padded, r, true), r, false);
    Volume<uint8_t> out(m.geometry());
    for (int64_t z = 0; z < m.nz(); ++z)
        for (int64_t y = 0; y < m.ny(); ++y)
            for (int64_t x = 0; x < m.nx(); ++x) out(x, y, z) = closed(x + lo[0], y + lo[1], z + lo[2]);
    return out;
}

}  // namespace

// A scan cropped through the cavity: its crop plane is a wall (creases.h). The closing with walled
// faces matches brute force with foreground beyond them, for any set of faces and anisotropic
// spacing; no walls is close_ball.
TEST(Morphology, ClosingWithWalledFacesMatchesBruteForce) {
    const Vec3 spacings[] = {{1, 1, 1}, {0.6, 0.9, 1.2}};
    const WalledFaces sets[] = {{false, false, false, false, true, false},
                                {true, false, false, true, false, true},
                                {true, true, true, true, true, true}};
    uint32_t seed = 41;
    for (const auto& sp : spacings)
        for (const WalledFaces& w : sets) {
            const auto m = random_mask(grid(10, 9, 8, sp), 0.15, seed++);
            EXPECT_EQ(close_ball(m, 2.2, w).buffer(), brute_walled_close(m, 2.2, w).buffer());
        }
    const auto m = random_mask(grid(10, 9, 8), 0.15, seed);
    EXPECT_EQ(close_ball(m, 2.2, WalledFaces{}).buffer(), close_ball(m, 2.2).buffer());
}

// A slit 5 voxels high between a plate of bone and the volume's lower face: a ball of radius 3
// does not close it while the face is open (the dilation reaches 3 voxels down from the plate, the
// erosion opens it again from the 2 voxels left), and closes it when the face is a wall.
TEST(Morphology, WalledFaceClosesTheSlitBetweenItAndTheBone) {
    Volume<uint8_t> bone(grid(20, 20, 16));
    for (int64_t z = 5; z < 8; ++z)
        for (int64_t y = 0; y < 20; ++y)
            for (int64_t x = 0; x < 20; ++x) bone(x, y, z) = 1;
    const WalledFaces below{false, false, false, false, true, false};
    for (int64_t z = 0; z < 5; ++z) {
        EXPECT_EQ(close_ball(bone, 3.0)(10, 10, z), 0) << z;
        EXPECT_EQ(close_ball(bone, 3.0, below)(10, 10, z), 1) << z;
    }
    EXPECT_EQ(close_ball(bone, 3.0, below)(10, 10, 12), 0);  // above the plate: open
}

TEST(Morphology, FillVoidsFillsSmallVoidsAndKeepsLargeOpenings) {
    // A slab of bone 10 voxels thick with a small spherical void (radius 2), a crack 1 voxel wide
    // and a large hole (radius 9) through it. Radius 6 fills the first two, not the hole.
    Volume<uint8_t> bone(grid(60, 60, 30));
    for (int64_t z = 10; z < 20; ++z)
        for (int64_t y = 0; y < 60; ++y)
            for (int64_t x = 0; x < 60; ++x) bone(x, y, z) = 1;
    auto carve = [&](auto pred) {
        for (int64_t z = 0; z < 30; ++z)
            for (int64_t y = 0; y < 60; ++y)
                for (int64_t x = 0; x < 60; ++x)
                    if (pred(x, y, z)) bone(x, y, z) = 0;
    };
    carve([](int64_t x, int64_t y, int64_t z) {
        return (x - 12) * (x - 12) + (y - 12) * (y - 12) + (z - 15) * (z - 15) <= 4;
    });
    carve([](int64_t x, int64_t y, int64_t) { return x == 40 && y >= 5 && y < 25; });
    carve([](int64_t x, int64_t y, int64_t) { return (x - 30) * (x - 30) + (y - 45) * (y - 45) <= 81; });
    VoidFillParams p;
    p.radius_voxels = 6;
    const auto r = fill_voids(bone, p);
    EXPECT_DOUBLE_EQ(r.radius_mm, 6.0);
    EXPECT_EQ(r.bone(12, 12, 15), 1);  // void filled
    EXPECT_EQ(r.bone(40, 15, 15), 1);  // crack filled
    EXPECT_EQ(r.bone(30, 45, 15), 0);  // large hole stays open
    EXPECT_GT(r.filled_voxels, 0u);
}

// The dilations fill_voids keeps, read off its own transform, are dilate_ball's and the brute
// force's; the fill is the same as without them; a radius beyond the fill's is refused.
TEST(Morphology, FillVoidsKeepsTheDilationsOfSmallerBalls) {
    uint32_t seed = 41;
    for (const Vec3 sp : {Vec3{1, 1, 1}, Vec3{0.5, 0.7, 1.1}}) {
        const auto m = random_mask(grid(35, 14, 12, sp), 0.05, seed++);
        VoidFillParams p;
        p.radius_mm = 3.0;
        p.keep_dilations_mm = {1.5, 0.75, 3.0, 0.0};
        const VoidFillResult r = fill_voids(m, p);
        ASSERT_EQ(r.dilations.size(), 4u);
        for (size_t k = 0; k < 4; ++k) {
            const double radius = p.keep_dilations_mm[k];
            EXPECT_EQ(r.dilations[k].unpack().buffer(), dilate_ball(m, radius).buffer()) << radius;
            EXPECT_EQ(r.dilations[k].unpack().buffer(), brute(m, radius, true).buffer()) << radius;
        }
        p.keep_dilations_mm = {3.0, 2.7, 2.4, 2.1, 1.8, 1.5, 1.2, 0.9, 0.6};  // beyond the seven read off one pass
        const VoidFillResult many = fill_voids(m, p);
        ASSERT_EQ(many.dilations.size(), 9u);
        for (size_t k = 0; k < 9; ++k)
            EXPECT_EQ(many.dilations[k].unpack().buffer(), dilate_ball(m, p.keep_dilations_mm[k]).buffer()) << k;
        EXPECT_EQ(many.bone.buffer(), r.bone.buffer());
        VoidFillParams plain;
        plain.radius_mm = 3.0;
        EXPECT_EQ(r.bone.buffer(), fill_voids(m, plain).bone.buffer());
        EXPECT_TRUE(fill_voids(m, plain).dilations.empty());
        p.keep_dilations_mm = {3.5};
        EXPECT_THROW(fill_voids(m, p), InvalidParameter);
    }
}

TEST(Morphology, RadiusInMmOverridesVoxels) {
    VoidFillParams p;
    p.radius_voxels = 6;
    p.radius_mm = 2.5;
    EXPECT_DOUBLE_EQ(void_fill_radius_mm(p, grid(4, 4, 4, {0.5, 0.5, 1})), 2.5);
    p.radius_mm.reset();
    EXPECT_DOUBLE_EQ(void_fill_radius_mm(p, grid(4, 4, 4, {0.5, 0.5, 1})), 3.0);
}

TEST(Morphology, RejectsNegativeRadius) {
    Volume<uint8_t> m(grid(4, 4, 4));
    EXPECT_THROW(dilate_ball(m, -1), InvalidParameter);
    VoidFillParams p;
    p.radius_voxels = std::nan("");
    EXPECT_THROW(fill_voids(m, p), InvalidParameter);
}
