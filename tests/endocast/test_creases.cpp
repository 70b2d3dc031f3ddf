// restore_creases (creases.h) on small synthetic skulls with exact answers: a crease of the cavity
// that the void fill closes comes back, a canal through the wall and a chamber behind a gap in
// the wall stay closed, a foramen in a crease's floor stays closed while the crease comes back,
// the void fill's sheets left inside the endocast come back, and so does a plug's flare beside the
// mouth of its canal.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "endocast/stages/components.h"
#include "endocast/stages/creases.h"
#include "endocast/errors.h"
#include "endocast/stages/morphology.h"
#include "endocast/pipeline.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;

namespace {

using Pred = std::function<bool(int64_t, int64_t, int64_t)>;

// A skull of 1 mm voxels in a 50^3 grid: a spherical cavity (radius 11 about the centre), bone
// out to radius 24, empty beyond; `carved` voxels of the bone are empty too.
struct Scene {
    Volume<uint8_t> bone, filled, labels;
    double radius_mm = 0;
};

bool in_cavity(int64_t x, int64_t y, int64_t z) {
    return std::hypot(double(x) - 25, double(y) - 25, double(z) - 25) <= 11.0;
}
bool in_skull(int64_t x, int64_t y, int64_t z) {
    return std::hypot(double(x) - 25, double(y) - 25, double(z) - 25) <= 24.0;
}
bool box(int64_t x, int64_t y, int64_t z, int64_t x0, int64_t x1, int64_t y0, int64_t y1, int64_t z0, int64_t z1) {
    return x >= x0 && x < x1 && y >= y0 && y < y1 && z >= z0 && z < z1;
}

// The labels the watershed gives: of the empty voxels the void fill leaves, those connected to the
// centre are the endocast, the others are other; the rest is bone.
Scene scene(const Pred& carved) {
    Geometry g;
    g.dims = {50, 50, 50};
    Scene s;
    s.bone = Volume<uint8_t>(g, 0);
    for (int64_t z = 0; z < 50; ++z)
        for (int64_t y = 0; y < 50; ++y)
            for (int64_t x = 0; x < 50; ++x)
                s.bone(x, y, z) = in_skull(x, y, z) && !in_cavity(x, y, z) && !carved(x, y, z);
    VoidFillResult f = fill_voids(s.bone);
    s.filled = std::move(f.bone);
    s.radius_mm = f.radius_mm;
    Volume<uint8_t> cavity(g, 0);
    for (size_t i = 0; i < cavity.size(); ++i) cavity[i] = !s.filled[i];
    keep_component_at(cavity, cavity.index(25, 25, 25), Connectivity::Face6);
    s.labels = Volume<uint8_t>(g, kBone);
    for (size_t i = 0; i < cavity.size(); ++i)
        if (!s.filled[i]) s.labels[i] = cavity[i] ? kEndocast : kOther;
    return s;
}

// The cavity's wall at y = 14 faces -y; the bone runs from y = 1 to 14 there. The slot and the
// canal are wider than the keep-closed ball (radius 3), narrower than the void fill's (radius 6).
bool slot(int64_t x, int64_t y, int64_t z) { return box(x, y, z, 21, 29, 8, 15, 21, 30); }      // 8 wide, 6 deep
bool canal(int64_t x, int64_t y, int64_t z) { return box(x, y, z, 21, 29, 0, 15, 21, 30); }     // through the wall
bool chamber(int64_t x, int64_t y, int64_t z) {
    return box(x, y, z, 20, 31, 3, 13, 20, 31) || box(x, y, z, 23, 27, 12, 15, 23, 27);  // 11 x 10 x 11 behind a 4 x 4 gap
}
// The same room behind a mouth 7 wide (more than half its width): a pocket like the sella.
bool pocket(int64_t x, int64_t y, int64_t z) {
    return box(x, y, z, 20, 31, 3, 13, 20, 31) || box(x, y, z, 22, 29, 12, 15, 22, 29);
}

}  // namespace

TEST(Creases, ACreaseTheVoidFillClosedComesBack) {
    Scene s = scene(slot);
    ASSERT_EQ(s.filled(25, 9, 25), 1);  // the void fill closed the slot
    ASSERT_EQ(s.labels(25, 9, 25), kBone);
    const CreaseResult r = restore_creases(s.labels, s.bone, s.filled, s.radius_mm);
    EXPECT_GE(r.pieces, 1u);
    EXPECT_EQ(r.pieces_too_deep, 0u);
    for (int64_t y = 8; y < 14; ++y) {
        EXPECT_EQ(s.labels(25, y, 25), kEndocast) << "y " << y;
        EXPECT_EQ(s.filled(25, y, 25), 0) << "y " << y;
    }
    EXPECT_EQ(s.labels(25, 7, 25), kBone);  // the bone below the slot's floor
}

// The closings' dilations given (read off the void fill's transform, as the pipeline does) or
// computed on the box: the same labels, fill and counts. In a grid larger than the endocast's box
// (the dilation reaches into the box from the bone beyond it) and with the cavity cut by the
// volume's border (walled faces).
TEST(Creases, TheVoidFillsDilationsGiveTheSameResult) {
    struct Case {
        Dims dims;
        std::array<int64_t, 3> centre;
        Pred carved;
    };
    const Case cases[] = {{{70, 66, 64}, {35, 34, 31}, slot},   {{70, 66, 64}, {35, 34, 31}, chamber},
                          {{70, 66, 64}, {35, 30, 33}, pocket}, {{70, 66, 64}, {33, 34, 31}, canal},
                          {{60, 50, 50}, {6, 25, 25}, slot},     {{50, 50, 44}, {25, 25, 40}, pocket}};
    for (const Case& c : cases) {
        Geometry g;
        g.dims = c.dims;
        g.spacing = {1.0, 1.0, 1.0};
        const int64_t ox = c.centre[0] - 25, oy = c.centre[1] - 25, oz = c.centre[2] - 25;
        Volume<uint8_t> bone(g, 0);
        for (int64_t z = 0; z < g.dims[2]; ++z)
            for (int64_t y = 0; y < g.dims[1]; ++y)
                for (int64_t x = 0; x < g.dims[0]; ++x) {
                    const int64_t u = x - ox, v = y - oy, w = z - oz;
                    // and bone again beyond a shell of air 7 voxels thick (the scanner's table, the
                    // other bones of the head): into the box and beyond it
                    const bool beyond = std::hypot(double(u) - 25, double(v) - 25, double(w) - 25) >= 31.0;
                    bone(x, y, z) = (in_skull(u, v, w) && !in_cavity(u, v, w) && !c.carved(u, v, w)) || beyond;
                }
        CreaseParams cp;
        VoidFillParams vp;
        for (double f : cp.keep_closed_fractions) vp.keep_dilations_mm.push_back(f * 6.0);
        const VoidFillResult f = fill_voids(bone, vp);
        Volume<uint8_t> cavity(g, 0);
        for (size_t i = 0; i < cavity.size(); ++i) cavity[i] = !f.bone[i];
        keep_component_at(cavity, cavity.index(c.centre[0], c.centre[1], c.centre[2]), Connectivity::Face6);
        Volume<uint8_t> labels(g, kBone);
        for (size_t i = 0; i < cavity.size(); ++i)
            if (!f.bone[i]) labels[i] = cavity[i] ? kEndocast : kOther;
        Volume<uint8_t> labels_a = labels, filled_a = f.bone, labels_b = labels, filled_b = f.bone;
        const CreaseResult a = restore_creases(labels_a, bone, filled_a, f.radius_mm, cp, f.dilations);
        const CreaseResult b = restore_creases(labels_b, bone, filled_b, f.radius_mm, cp);
        EXPECT_GT(a.voxels, 0u) << c.centre[0];
        EXPECT_EQ(a.voxels, b.voxels) << c.centre[0];
        EXPECT_EQ(a.pieces, b.pieces);
        EXPECT_EQ(a.pieces_kept_closed, b.pieces_kept_closed);
        EXPECT_EQ(a.plugs_split, b.plugs_split);
        EXPECT_EQ(labels_a.buffer(), labels_b.buffer()) << c.centre[0];
        EXPECT_EQ(filled_a.buffer(), filled_b.buffer()) << c.centre[0];
    }
    Scene s = scene(slot);
    const std::vector<PackedMask> one{PackedMask(s.bone)};
    EXPECT_THROW(restore_creases(s.labels, s.bone, s.filled, s.radius_mm, CreaseParams{}, one), InvalidParameter);
}

TEST(Creases, DisabledOrWithoutAVoidFillNothingChanges) {
    Scene s = scene(slot);
    const Volume<uint8_t> before = s.labels;
    CreaseParams off;
    off.enabled = false;
    EXPECT_EQ(restore_creases(s.labels, s.bone, s.filled, s.radius_mm, off).voxels, 0u);
    EXPECT_EQ(restore_creases(s.labels, s.bone, s.filled, 0.0).voxels, 0u);
    for (size_t i = 0; i < before.size(); ++i) ASSERT_EQ(s.labels[i], before[i]);
}

TEST(Creases, ACanalThroughTheWallStaysClosed) {
    Scene s = scene(canal);
    ASSERT_EQ(s.labels(25, 9, 25), kBone);
    const Volume<uint8_t> before = s.labels;
    const CreaseResult r = restore_creases(s.labels, s.bone, s.filled, s.radius_mm);
    EXPECT_GE(r.pieces_kept_closed, 1u);
    for (int64_t y = 0; y < 15; ++y)
        if (before(25, y, 25) == kBone) EXPECT_EQ(s.labels(25, y, 25), kBone) << "y " << y;
}

TEST(Creases, AChamberBehindAGapInTheWallStaysClosed) {
    Scene s = scene(chamber);
    ASSERT_EQ(s.labels(25, 9, 25), kBone);
    Scene deep = s;
    const CreaseResult r = restore_creases(s.labels, s.bone, s.filled, s.radius_mm);
    EXPECT_GE(r.pieces_too_deep, 1u);
    EXPECT_EQ(s.labels(25, 9, 25), kBone);
    // Without the depth rule the chamber would join the cavity.
    CreaseParams any_depth;
    any_depth.max_mean_depth_fraction = 1e9;
    restore_creases(deep.labels, deep.bone, deep.filled, deep.radius_mm, any_depth);
    EXPECT_EQ(deep.labels(25, 9, 25), kEndocast);
}

// A room as deep below its mouth as the chamber, but whose mouth is more than half as wide as it
// (mouth 49 mm^2, the largest ball inside 5 mm in radius: 0.62 of its cross-section): a pocket of
// the cavity (the sella turcica under the dorsum), given back; without the pocket rule it stays.
TEST(Creases, APocketUnderAWideMouthComesBackThoughDeep) {
    Scene s = scene(pocket);
    ASSERT_EQ(s.labels(25, 9, 25), kBone);
    Scene strict = s;
    const CreaseResult r = restore_creases(s.labels, s.bone, s.filled, s.radius_mm);
    EXPECT_EQ(r.deep_pockets, 1u);
    EXPECT_EQ(r.pieces_too_deep, 0u);
    EXPECT_EQ(s.labels(25, 9, 25), kEndocast);
    CreaseParams no_pockets;
    no_pockets.pocket_mouth_fraction = 0;
    const CreaseResult rs = restore_creases(strict.labels, strict.bone, strict.filled, strict.radius_mm, no_pockets);
    EXPECT_GE(rs.pieces_too_deep, 1u);
    EXPECT_EQ(strict.labels(25, 9, 25), kBone);
}

TEST(Creases, AForamenInACreaseFloorStaysClosedWhileTheCreaseComesBack) {
    // A 1-voxel canal from the slot's floor through the rest of the bone to the outside.
    Scene s = scene([](int64_t x, int64_t y, int64_t z) { return slot(x, y, z) || box(x, y, z, 25, 26, 0, 9, 25, 26); });
    ASSERT_EQ(s.labels(25, 4, 25), kBone);
    restore_creases(s.labels, s.bone, s.filled, s.radius_mm);
    EXPECT_EQ(s.labels(24, 10, 24), kEndocast);  // the crease
    // The foramen (the keep-closed ball's tip may reach a voxel into its mouth, y = 7).
    for (int64_t y = 3; y < 7; ++y) EXPECT_EQ(s.labels(25, y, 25), kBone) << "y " << y;
}

// The void fill's voxels left as sheets inside the endocast (a lid's remnant over a pocket given
// back, which the smaller balls close at its rim) come back: a sheet 1 voxel thick and one 3 thick
// (the endocast within 2 voxels on both sides). A slab 5 thick, a sheet of bone and a sheet of the
// void fill between the endocast and other empty space (a plug) stay. The crease passes are off,
// so that only the sheet rule acts.
TEST(Creases, TheVoidFillsSheetsInsideTheEndocastComeBack) {
    Geometry g;
    g.dims = {24, 24, 24};
    Volume<uint8_t> labels(g, kBone), bone(g, 1), filled(g, 1);
    auto set = [&](int64_t x0, int64_t x1, int64_t y0, int64_t y1, int64_t z0, int64_t z1, uint8_t l, uint8_t b) {
        for (int64_t z = z0; z < z1; ++z)
            for (int64_t y = y0; y < y1; ++y)
                for (int64_t x = x0; x < x1; ++x) {
                    labels(x, y, z) = l;
                    bone(x, y, z) = b;
                    filled(x, y, z) = l == kBone;
                }
    };
    set(2, 22, 2, 22, 2, 22, kEndocast, 0);
    set(4, 12, 4, 12, 8, 9, kBone, 0);      // a sheet of the void fill, 1 thick
    set(4, 12, 4, 12, 14, 17, kBone, 0);    // 3 thick
    set(14, 19, 4, 12, 4, 12, kBone, 0);    // a slab 5 thick (along x)
    set(14, 20, 14, 20, 8, 9, kBone, 1);    // bone
    set(14, 20, 14, 20, 18, 22, kOther, 0); // other empty space above a plug at z = 17
    set(14, 20, 14, 20, 17, 18, kBone, 0);
    CreaseParams p;
    p.keep_closed_fractions = {};
    Volume<uint8_t> off_labels = labels, off_filled = filled;
    CreaseParams off = p;
    off.sheet_voxels = 0;
    EXPECT_EQ(restore_creases(off_labels, bone, off_filled, 6.0, off).sheet_voxels, 0u);
    const CreaseResult r = restore_creases(labels, bone, filled, 6.0, p);
    EXPECT_EQ(r.sheet_voxels, 64u + 192u);
    EXPECT_EQ(labels(8, 8, 8), kEndocast);
    EXPECT_EQ(filled(8, 8, 8), 0);
    for (int64_t z = 14; z < 17; ++z) EXPECT_EQ(labels(8, 8, z), kEndocast) << "z " << z;
    EXPECT_EQ(labels(16, 8, 8), kBone);   // the slab
    EXPECT_EQ(labels(17, 17, 8), kBone);  // bone
    EXPECT_EQ(labels(17, 17, 17), kBone); // the plug
    EXPECT_EQ(off_labels(8, 8, 8), kBone);
}

// A hole's plug with the mouth's flare the ball joined to it (the wedge beside the internal
// acoustic meatus): the void fill's voxels form a room 9 x 5 x 9 open to the endocast and a canal
// 3 x 3 on from it to other empty space, one piece. Flooded from both sides down the distance to
// the bone, the room's core (up to 5 voxels from its walls) is more than a voxel wider than the
// canal (2): it comes back with what the balls inside it cover, the canal stays closed. Without
// the split the whole piece stays; with other space leading by 4 voxels the room is not wide enough.
TEST(Creases, ThePlugsFlareComesBackItsCanalStays) {
    Geometry g;
    g.dims = {30, 30, 30};
    Volume<uint8_t> labels(g, kBone), bone(g, 1), filled(g, 1);
    auto set = [&](int64_t x0, int64_t x1, int64_t y0, int64_t y1, int64_t z0, int64_t z1, uint8_t l) {
        for (int64_t z = z0; z < z1; ++z)
            for (int64_t y = y0; y < y1; ++y)
                for (int64_t x = x0; x < x1; ++x) {
                    labels(x, y, z) = l;
                    bone(x, y, z) = 0;
                    filled(x, y, z) = l == kBone;
                }
    };
    set(2, 28, 2, 12, 2, 28, kEndocast);
    set(10, 19, 12, 17, 10, 19, kBone);  // the flare
    set(13, 16, 17, 27, 13, 16, kBone);  // the canal
    set(0, 30, 27, 30, 0, 30, kOther);
    CreaseParams p;
    p.keep_closed_fractions = {0.0};  // every voxel the void fill added is a candidate
    p.sheet_voxels = 0;
    auto run = [&](double lead, Volume<uint8_t>& l, Volume<uint8_t>& f) {
        CreaseParams q = p;
        q.plug_lead_voxels = lead;
        return restore_creases(l, bone, f, 6.0, q);
    };
    Volume<uint8_t> l0 = labels, f0 = filled, l4 = labels, f4 = filled;
    const CreaseResult r = run(1.0, labels, filled);
    EXPECT_EQ(r.plugs_split, 1u);
    EXPECT_EQ(r.pieces_kept_closed, 1u);
    EXPECT_EQ(r.voxels, r.plug_voxels);
    // The flare to its walls (the balls inside the core cover them, all but its edges and corners),
    // and the canal's first voxel, which the core's ball (3.6 voxels to the floor's edge) dips into.
    for (int64_t z = 11; z < 18; ++z)
        for (int64_t y = 12; y < 16; ++y)
            for (int64_t x = 11; x < 18; ++x) ASSERT_EQ(labels(x, y, z), kEndocast) << x << " " << y << " " << z;
    EXPECT_EQ(labels(14, 13, 10), kEndocast);
    EXPECT_EQ(labels(14, 16, 14), kEndocast);
    EXPECT_EQ(labels(10, 16, 10), kBone);  // a corner at the floor
    EXPECT_EQ(labels(14, 17, 14), kEndocast);
    EXPECT_EQ(filled(14, 13, 14), 0);
    EXPECT_GT(r.plug_voxels, 7u * 4u * 7u + 9u);
    EXPECT_LT(r.plug_voxels, 9u * 5u * 9u + 9u);
    for (int64_t y = 18; y < 27; ++y) EXPECT_EQ(labels(14, y, 14), kBone) << "y " << y;
    EXPECT_EQ(run(0.0, l0, f0).plug_voxels, 0u);  // off
    EXPECT_EQ(l0(14, 13, 14), kBone);
    EXPECT_EQ(run(4.0, l4, f4).plug_voxels, 0u);
    EXPECT_EQ(l4(14, 13, 14), kBone);
}

TEST(Creases, RefusesBadInput) {
    Scene s = scene(slot);
    CreaseParams bad;
    bad.keep_closed_fractions = {0.5, -1};
    EXPECT_THROW(restore_creases(s.labels, s.bone, s.filled, s.radius_mm, bad), InvalidParameter);
    bad.keep_closed_fractions = {std::nan("")};
    EXPECT_THROW(restore_creases(s.labels, s.bone, s.filled, s.radius_mm, bad), InvalidParameter);
    bad = CreaseParams();
    bad.sheet_voxels = -1;
    EXPECT_THROW(restore_creases(s.labels, s.bone, s.filled, s.radius_mm, bad), InvalidParameter);
    bad = CreaseParams();
    bad.plug_lead_voxels = -0.5;
    EXPECT_THROW(restore_creases(s.labels, s.bone, s.filled, s.radius_mm, bad), InvalidParameter);
    Geometry g;
    g.dims = {10, 10, 10};
    Volume<uint8_t> small(g, 0);
    EXPECT_THROW(restore_creases(s.labels, small, s.filled, s.radius_mm), InvalidParameter);
}

// End to end: the slot's volume joins the ECV (the mesh follows its walls), the mesh stays a
// clean genus-0 manifold; with creases off the slot is cut at the void fill's surface.
TEST(Creases, ThePipelineKeepsTheSlotInTheEndocast) {
    const Scene s = scene(slot);
    Volume<float> ct(s.bone.geometry(), -1000.0f);
    for (size_t i = 0; i < ct.size(); ++i)
        if (s.bone[i]) ct[i] = 1000.0f;
    ExtractParams p;
    p.binarize.isovalue = 0;
    const ExtractionResult on = extract_endocast(ct, p);
    p.creases.enabled = false;
    const ExtractionResult off = extract_endocast(ct, p);
    expect_clean_genus0(on.mesh);
    EXPECT_GT(on.creases.voxels, 30u);
    EXPECT_EQ(off.creases.voxels, 0u);
    // The slot is 8 x 9 mm wide and 6-8 mm deep beyond the curved wall (~550 mm^3).
    EXPECT_GT((on.ecv_ml - off.ecv_ml) * 1000.0, 400.0);
    EXPECT_LT((on.ecv_ml - off.ecv_ml) * 1000.0, 700.0);
    EXPECT_EQ(on.mask(25, 10, 25), 1);
    EXPECT_EQ(off.mask(25, 10, 25), 0);
}
