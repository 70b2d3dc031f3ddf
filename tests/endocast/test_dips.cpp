// flush_dips and plug_contacts (dips.h): a closing surface the void fill's ball dips into a hole
// with is moved onto the membrane spanning the hole's rim; a pocket of the cavity (no plug) and the
// faces on bone stay as they are; a closure the watershed left sunk down a channel wider than the
// ball is raised to the channel's mouth.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <thread>

#include "endocast/stages/bone_contact.h"
#include "endocast/stages/dips.h"
#include "endocast/errors.h"
#include "endocast/pipeline.h"
#include "endocast/stages/polygonize.h"
#include "meshpost/topology.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;
using endocast::testing::grid;

namespace {

// 1 mm voxels, 80^3: a cubic cavity [18, 62)^3 in a box of bone [10, 70)^3 (8 mm walls), air
// outside; `carved` voxels of the wall are empty too. Bone 1000, empty -1000, isovalue 0: the
// inner face of the +x wall lies at x = 61.5.
Volume<float> skull(const std::function<bool(int64_t, int64_t, int64_t)>& carved) {
    Volume<float> ct(grid(80, 80, 80), -1000.0f);
    for (int64_t z = 0; z < 80; ++z)
        for (int64_t y = 0; y < 80; ++y)
            for (int64_t x = 0; x < 80; ++x) {
                auto in = [&](int64_t lo, int64_t hi) {
                    return x >= lo && x < hi && y >= lo && y < hi && z >= lo && z < hi;
                };
                if (in(10, 70) && !in(18, 62) && !carved(x, y, z)) ct(x, y, z) = 1000.0f;
            }
    return ct;
}

// Within `radius` mm of the +x wall's axis through (y, z) = (40, 40).
bool near_axis(double y, double z, double radius) { return std::hypot(y - 40, z - 40) < radius; }

// The farthest a vertex of the mesh reaches beyond the +x wall's inner face (mm), over the disk
// of `radius` about the axis.
double beyond_wall(const meshpost::TriangleMesh& m, double radius) {
    double d = -1e9;
    for (const auto& v : m.vertices)
        if (near_axis(v[1], v[2], radius)) d = std::max(d, v[0] - 61.5);
    return d;
}

// The labels of the sunk-closure tests: bone where the CT is >= 0, the cavity and the first 3 mm of
// the 7 mm channel through the +x wall endocast, the rest of the channel `beyond`, other elsewhere.
Volume<uint8_t> channel_labels(const Volume<float>& ct, uint8_t beyond) {
    Volume<uint8_t> labels(ct.geometry(), kOther);
    for (int64_t z = 0; z < 80; ++z)
        for (int64_t y = 0; y < 80; ++y)
            for (int64_t x = 0; x < 80; ++x) {
                const bool cavity = x >= 18 && x < 62 && y >= 18 && y < 62 && z >= 18 && z < 62;
                const bool channel = x >= 62 && near_axis(double(y), double(z), 7.0);
                if (ct(x, y, z) >= 0) labels(x, y, z) = kBone;
                else if (cavity || (channel && x < 65)) labels(x, y, z) = kEndocast;
                else if (channel && x < 70) labels(x, y, z) = beyond;
            }
    return labels;
}

ExtractParams params() {
    ExtractParams p;
    p.binarize.isovalue = 0;
    p.binarize.thin_bone_prominence = 0;
    return p;
}

}  // namespace

// A hole 10 mm wide through the wall: the void fill plugs it and its 6 mm ball dips
// 6 - sqrt(36 - 25) = 2.7 mm into it; flushed, the closing surface lies on the wall's face.
TEST(Dips, AHoleThePlugDipsIntoIsClosedFlushWithTheWall) {
    const Volume<float> ct = skull([](int64_t x, int64_t y, int64_t z) {
        return x >= 62 && near_axis(double(y), double(z), 5.0);
    });
    ExtractParams p = params();
    const ExtractionResult on = extract_endocast(ct, p);
    p.dips.enabled = false;
    const ExtractionResult off = extract_endocast(ct, p);
    EXPECT_GE(beyond_wall(off.mesh, 5.0), 2.0) << "the dip this step is for";
    EXPECT_LE(beyond_wall(on.mesh, 5.0), 0.75);
    EXPECT_GE(on.dips.flushed, 1u);
    EXPECT_EQ(off.dips.flushed, 0u);
    EXPECT_GT(on.dips.max_depth_mm, 1.5);
    // The volume taken out is the dip's: a cap of a 6 mm ball over a 10 mm hole, ~100 mm^3 (the
    // hole's rounded rim adds to it); the ECV drops by what the report says.
    EXPECT_GT(on.dips.volume_removed_mm3, 50.0);
    EXPECT_LT(on.dips.volume_removed_mm3, 250.0);
    EXPECT_NEAR((off.ecv_ml - on.ecv_ml) * 1000.0, on.dips.volume_removed_mm3, 1e-6 * off.ecv_ml * 1000.0 + 1e-3);
    expect_clean_genus0(on.mesh);
    // Away from the hole nothing moved: the wall's face beside it is where it was.
    EXPECT_NEAR(beyond_wall(on.mesh, 30.0) - beyond_wall(on.mesh, 9.0), 0.0, 1e-12);
    // The vertices listed as moved are exactly those that differ from the mesh without the step
    // (the extraction's self-intersection check tests only their faces).
    EXPECT_EQ(on.dips.moved_vertices.size(), on.dips.vertices_moved);
    ASSERT_EQ(on.mesh.vertices.size(), off.mesh.vertices.size());
    std::vector<uint8_t> listed(on.mesh.vertices.size(), 0);
    for (uint32_t v : on.dips.moved_vertices) listed[v] = 1;
    size_t differ = 0;
    for (size_t v = 0; v < on.mesh.vertices.size(); ++v) {
        if (on.mesh.vertices[v] == off.mesh.vertices[v]) continue;
        ++differ;
        EXPECT_TRUE(listed[v]) << "vertex " << v << " moved but is not listed";
    }
    EXPECT_EQ(differ, on.dips.moved_vertices.size());
    // The topology, analysed beside the dips' loop on the faces and completed with the final
    // positions, is the final mesh's; without the dips there is none.
    ASSERT_TRUE(on.topology.has_value());
    const meshpost::TopologyReport t = meshpost::analyze_topology(on.mesh);
    EXPECT_EQ(on.topology->vertices, t.vertices);
    EXPECT_EQ(on.topology->faces, t.faces);
    EXPECT_EQ(on.topology->edges, t.edges);
    EXPECT_EQ(on.topology->components, t.components);
    EXPECT_EQ(on.topology->genus, t.genus);
    EXPECT_EQ(on.topology->degenerate_faces, t.degenerate_faces);
    EXPECT_TRUE(meshpost::is_closed_manifold(*on.topology));
    EXPECT_FALSE(off.topology.has_value());
}

// flush_dips' `beside` runs once: on a thread of its own with two threads, after the loop on the
// caller's with one, also when there is nothing to flush or the step is off; its exception comes
// back to the caller.
TEST(Dips, BesideRunsOnceOnAThreadOfItsOwn) {
    meshpost::TriangleMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    const Geometry g = grid(4, 4, 4);
    const std::vector<uint8_t> on_bone(4, 1);
    const int threads = omp_get_max_threads();
    DipParams off;
    off.enabled = false;
    for (int t : {1, 2}) {
        omp_set_num_threads(t);
        for (const DipParams& dp : {DipParams(), off}) {
            int runs = 0;
            std::thread::id ran_on;
            flush_dips(m, on_bone, g, {}, 6.0, dp, {}, [&] {
                ++runs;
                ran_on = std::this_thread::get_id();
            });
            EXPECT_EQ(runs, 1) << t << " threads";
            if (dp.enabled) EXPECT_EQ(ran_on != std::this_thread::get_id(), t > 1) << t << " threads";
        }
        EXPECT_THROW(flush_dips(m, on_bone, g, {}, 6.0, {}, {}, [] { throw InvalidParameter("beside"); }),
                     InvalidParameter);
    }
    omp_set_num_threads(threads);
}

// A blind pocket of the same width in the wall (4 mm deep): the creases step gives it back to the
// endocast; no plug, so nothing is flushed and the mesh is the same with the step off.
TEST(Dips, APocketWithNoPlugStaysWhole) {
    const Volume<float> ct = skull([](int64_t x, int64_t y, int64_t z) {
        return x >= 62 && x < 66 && near_axis(double(y), double(z), 5.0);
    });
    ExtractParams p = params();
    const ExtractionResult on = extract_endocast(ct, p);
    p.dips.enabled = false;
    const ExtractionResult off = extract_endocast(ct, p);
    EXPECT_EQ(on.dips.flushed, 0u);
    EXPECT_EQ(on.mesh.vertices, off.mesh.vertices);
    EXPECT_GT(beyond_wall(on.mesh, 4.0), 3.0);  // the pocket is in the endocast, down to its floor
}

// A hole 8 mm wide running through the wall at 63 degrees to its normal: the plug's dip runs down the hole's
// wall on one side, past the rim rings; grown across that wall first (DipParams::wall_rings), the
// membrane spans the rim on the wall's face.
TEST(Dips, ADipDownAnObliqueHoleIsClosedAtItsRim) {
    const Volume<float> ct = skull([](int64_t x, int64_t y, int64_t z) {
        return x >= 62 && near_axis(double(y), double(z) - 2.0 * double(x - 62), 4.0);
    });
    ExtractParams p = params();
    const ExtractionResult grown = extract_endocast(ct, p);
    p.dips.wall_rings = 0;
    const ExtractionResult rim_only = extract_endocast(ct, p);
    std::printf("oblique hole: beyond the wall %.2f mm (rim rings only %.2f), flushed %zu (%zu), crossing %zu\n",
                beyond_wall(grown.mesh, 8.0), beyond_wall(rim_only.mesh, 8.0), grown.dips.flushed, rim_only.dips.flushed,
                grown.dips.crossing);
    EXPECT_GE(grown.dips.flushed, 1u);
    EXPECT_LT(beyond_wall(grown.mesh, 8.0), beyond_wall(rim_only.mesh, 8.0) - 0.3);
    expect_clean_genus0(grown.mesh);
}

// A channel 14 mm wide through the wall (wider than the void fill's ball: no plug), its closing
// surface left 3 mm down it (the labels: the endocast reaches x = 64, other space beyond). The
// walk up the channel's wall reaches every face around the patch, and the patch faces other space:
// a closure sunk down its channel, raised onto the membrane spanning the channel's mouth. The
// same channel with bone's label beyond (a floor of thin bone below the isovalue: a pocket) and
// without the face_on_other flags stays.
TEST(Dips, AClosureSunkDownItsChannelIsRaisedToItsMouth) {
    // Blurred as a scanner does ([1 2 1] / 4 along each axis, twice): its edges rounded, the
    // channel's wall meets the closure at a steep face, not a voxel's chamfer.
    Volume<float> ct = skull([](int64_t x, int64_t y, int64_t z) {
        return x >= 62 && near_axis(double(y), double(z), 7.0);
    });
    for (int pass = 0; pass < 6; ++pass) {
        const Volume<float> in = ct;
        const int a = pass % 3;
        for (int64_t z = 1; z < 79; ++z)
            for (int64_t y = 1; y < 79; ++y)
                for (int64_t x = 1; x < 79; ++x) {
                    const int64_t dx = a == 0, dy = a == 1, dz = a == 2;
                    ct(x, y, z) = 0.25f * in(x - dx, y - dy, z - dz) + 0.5f * in(x, y, z) + 0.25f * in(x + dx, y + dy, z + dz);
                }
    }
    auto run = [&](uint8_t beyond, bool flags, DipResult& r) {
        const Volume<uint8_t> labels = channel_labels(ct, beyond);
        PolygonizeParams pp;
        pp.isovalue = 0;
        meshpost::TriangleMesh m = polygonize(ct, labels, pp).mesh;
        const BoneContact contact = bone_contact(m, ct, 0.0);
        const std::vector<uint8_t> other = flags ? faces_on_other_space(m, labels) : std::vector<uint8_t>();
        r = flush_dips(m, contact.face_on_bone, ct.geometry(), {}, 6.0, {}, other);
        return m;
    };
    DipResult sunk, pocket, unflagged;
    const meshpost::TriangleMesh raised = run(kOther, true, sunk);
    const meshpost::TriangleMesh floor = run(kBone, true, pocket);
    const meshpost::TriangleMesh left = run(kOther, false, unflagged);
    std::printf("sunk closure: beyond the wall %.2f mm (left %.2f), sunk %zu, max move %.2f mm\n", beyond_wall(raised, 5.0),
                beyond_wall(left, 5.0), sunk.sunk, sunk.max_depth_mm);
    EXPECT_GE(beyond_wall(left, 5.0), 2.5) << "the closure 3 mm down the channel";
    // Raised to where the channel's wall turns into the blur's fillet at its mouth (the walk takes
    // faces steeper than 60 degrees to the patch): 1.6 mm from the wall's sharp face.
    EXPECT_LE(beyond_wall(raised, 5.0), 1.75);
    EXPECT_GE(beyond_wall(left, 5.0) - beyond_wall(raised, 5.0), 1.2);
    EXPECT_EQ(sunk.sunk, 1u);
    EXPECT_EQ(sunk.flushed, 1u);
    EXPECT_EQ(pocket.sunk, 0u);
    EXPECT_EQ(unflagged.sunk, 0u);
    EXPECT_EQ(floor.vertices, left.vertices);
    expect_clean_genus0(raised);
    DipParams off;  // off: the flags change nothing
    off.sunk_wall_share = 0;
    meshpost::TriangleMesh again = left;
    EXPECT_EQ(flush_dips(again, bone_contact(again, ct, 0.0).face_on_bone, ct.geometry(), {}, 6.0, off,
                         std::vector<uint8_t>(again.faces.size(), 1)).sunk, 0u);
}

// A closure the sunk test cannot take (the wall all round asked of it) is faired onto its thin
// plate; with the faired closures capped below its share of the surface it is left as it is.
TEST(Dips, AFairedClosureOverMoreThanTheAreaShareIsLeftAsItIs) {
    const Volume<float> ct = skull([](int64_t x, int64_t y, int64_t z) { return x >= 62 && near_axis(double(y), double(z), 7.0); });
    const Volume<uint8_t> labels = channel_labels(ct, kOther);
    PolygonizeParams pp;
    pp.isovalue = 0;
    const meshpost::TriangleMesh m = polygonize(ct, labels, pp).mesh;
    const std::vector<uint8_t> on_bone = bone_contact(m, ct, 0.0).face_on_bone;
    const std::vector<uint8_t> other = faces_on_other_space(m, labels);
    DipParams fair;
    fair.sunk_wall_share = 1.0;
    meshpost::TriangleMesh faired = m;
    const DipResult r = flush_dips(faired, on_bone, ct.geometry(), {}, 6.0, fair, other);
    EXPECT_EQ(r.faired, 1u);
    EXPECT_NE(faired.vertices, m.vertices);
    DipParams capped = fair;
    capped.fair_max_area_share = 1e-4;
    meshpost::TriangleMesh left = m;
    const DipResult c = flush_dips(left, on_bone, ct.geometry(), {}, 6.0, capped, other);
    EXPECT_EQ(c.faired, 0u);
    EXPECT_EQ(left.vertices, m.vertices);
}

TEST(Dips, RefusesBadInput) {
    meshpost::TriangleMesh m;
    m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    const Geometry g = grid(4, 4, 4);
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(3, 0), g, {}, 6.0), InvalidParameter);
    DipParams bad;
    bad.min_mean_depth_voxels = -1;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    bad = DipParams();
    bad.wall_max_cosine = 2;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    bad = DipParams();
    bad.wall_rings = -1;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    bad = DipParams();
    bad.fair_max_move_voxels = -1;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    for (double share : {0.0, 1.5, std::nan("")}) {
        bad = DipParams();
        bad.fair_max_area_share = share;
        EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    }
    bad = DipParams();
    bad.wall_length_voxels = -1;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    bad = DipParams();
    bad.rim_rings_retry = -1;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    bad = DipParams();
    bad.min_plug_share = 1.5;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    bad = DipParams();
    bad.sunk_wall_share = -0.5;
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, bad), InvalidParameter);
    EXPECT_THROW(flush_dips(m, std::vector<uint8_t>(4, 0), g, {}, 6.0, {}, std::vector<uint8_t>(3, 0)), InvalidParameter);
    meshpost::TriangleMesh broken = m;
    broken.faces.push_back({0, 1, 7});
    EXPECT_THROW(flush_dips(broken, std::vector<uint8_t>(5, 0), g, {}, 6.0), InvalidParameter);
    Volume<uint8_t> a(g, 0), b(grid(5, 4, 4), 0);
    EXPECT_THROW(plug_contacts(a, a, b, 6.0), InvalidParameter);
    // Nothing off bone: nothing to flush, the mesh unchanged.
    const meshpost::TriangleMesh before = m;
    EXPECT_EQ(flush_dips(m, std::vector<uint8_t>(4, 1), g, {}, 6.0).flushed, 0u);
    EXPECT_EQ(m.vertices, before.vertices);
}
