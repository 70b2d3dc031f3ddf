// The closure of the endocast (openings.h, handles.h and the pipeline around them) on small
// synthetic skulls with exact answers: pockets stay whole, canals are cut at their mouth, handles
// are cut where they are narrowest, a cavity cut by the volume border is closed at the border, and
// a volume without a cavity gives no result.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>
#include <set>
#include <vector>

#include "endocast/errors.h"
#include "endocast/stages/handles.h"
#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "meshpost/measure.h"
#include "meshpost/topology.h"
#include "test_helpers.h"

// The Freudenthal link is an internal kernel (header only); its simple-point table is tested here,
// beside the handles it serves.
#include "../../libendocast/src/kernels/freudenthal.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;
using endocast::testing::to_float;

namespace {

// A CT of bone (1000) with empty space (-1000) where `empty(x, y, z)` holds (mm = voxels).
Volume<float> carve(const Dims& d, const std::function<bool(double, double, double)>& empty) {
    Geometry g;
    g.dims = d;
    Volume<float> ct(g, 1000.0f);
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x)
                if (empty(double(x), double(y), double(z))) ct(x, y, z) = -1000.0f;
    return ct;
}

double sq(double v) { return v * v; }

ExtractParams binary_params() {
    ExtractParams p;
    p.binarize.isovalue = 0;
    p.void_fill.radius_voxels = 0;
    return p;
}

// The braincase of the tests below: a sphere of radius 24 centred at (40, 40, 44) with a lateral
// pocket (a sphere of radius 9 at (62, 40, 30): 14 mm deep below the main sphere's wall, joined to
// it by a wide neck), whose floor is pierced by a foramen (radius 2.5) into an air space below the
// skull that reaches the volume border.
constexpr double kCx = 40, kCy = 40, kCz = 44, kR = 24;
constexpr double kPx = 62, kPy = 40, kPz = 30, kPr = 9;
bool in_braincase(double x, double y, double z) {
    return sq(x - kCx) + sq(y - kCy) + sq(z - kCz) <= kR * kR ||
           sq(x - kPx) + sq(y - kPy) + sq(z - kPz) <= kPr * kPr;
}
bool in_foramen(double x, double y, double z) { return sq(x - kPx) + sq(y - kPy) <= 2.5 * 2.5 && z < kPz; }
bool in_air_below(double, double, double z) { return z < 12; }

}  // namespace

TEST(Openings, APocketWithAForamenInItsFloorStaysWhole) {
    // The pocket is deeper than the openings' balls reach (R = 0.3 x depth = 7 mm) and opens to
    // the outside only through its foramen: it is braincase, and only the foramen is an opening.
    const Volume<float> ct = carve({80, 80, 80}, [](double x, double y, double z) {
        return in_braincase(x, y, z) || in_foramen(x, y, z) || in_air_below(x, y, z);
    });
    const ExtractionResult r = extract_endocast(ct, binary_params());
    expect_clean_genus0(r.mesh);
    // The pocket's deepest point (its floor, 14 mm below the main sphere) is inside the mesh.
    const meshpost::BoundingBox b = meshpost::bounding_box(r.mesh);
    EXPECT_LT(b.min[2], kPz - kPr + 1.0);
    EXPECT_GT(b.max[0], kPx + kPr - 1.0);
    // Volume: the two spheres' union (numerically, on a fine grid), and at most the foramen's
    // canal (through the 9 mm of bone down to the air) more.
    double union_mm3 = 0;
    const double h = 0.25;
    for (double z = kPz - kPr; z <= kCz + kR; z += h)
        for (double y = kCy - kR; y <= kCy + kR; y += h)
            for (double x = kCx - kR; x <= kPx + kPr; x += h)
                union_mm3 += in_braincase(x, y, z) ? h * h * h : 0;
    const double canal_mm3 = M_PI * 2.5 * 2.5 * (kPz - kPr - 12);
    EXPECT_GT(r.ecv_ml * 1000, union_mm3 * 0.98);
    EXPECT_LT(r.ecv_ml * 1000, (union_mm3 + canal_mm3) * 1.02);
}

TEST(Openings, AThinShelfWithAGapInsideTheCavityLeavesNoHandle) {
    // A bony shelf 2 voxels thick reaching into the cavity from its wall (like the lesser wing of
    // the sphenoid over the middle fossa), with a round gap in it (bone blurred below the
    // isovalue): the cavity runs above and below the shelf, round its free edge and through the
    // gap, a handle. It is cut where it is narrowest, across the gap: genus 0.
    auto shelf = [](double x, double y, double z) {
        return z >= 36 && z < 38 && x > 40 && !(sq(x - 54) + sq(y - 40) <= 3.0 * 3.0);
    };
    const Volume<float> ct = carve({80, 80, 80}, [&](double x, double y, double z) {
        return sq(x - kCx) + sq(y - kCy) + sq(z - kCz) <= kR * kR && !shelf(x, y, z);
    });
    ExtractParams p = binary_params();
    p.close_handles = false;
    const ExtractionResult kept = extract_endocast(ct, p);
    EXPECT_EQ(meshpost::analyze_topology(kept.mesh).genus, 1);
    p.close_handles = true;
    const ExtractionResult r = extract_endocast(ct, p);
    expect_clean_genus0(r.mesh);
    EXPECT_EQ(r.handles.euler_before, 0);
    EXPECT_EQ(r.handles.euler_after, 1);
    // Only a membrane across the gap left the cavity: about the gap's area in voxels.
    EXPECT_GT(r.handles.voxels_closed, 10u);
    EXPECT_LT(r.handles.voxels_closed, 3 * 30u);
    EXPECT_NEAR(r.ecv_ml, kept.ecv_ml, 0.1);
}

TEST(Handles, EulerCharacteristicOfBallRingAndHollowBall) {
    Geometry g;
    g.dims = {20, 20, 20};
    Volume<uint8_t> ball(g, 0), ring(g, 0), hollow(g, 0);
    for (int64_t z = 0; z < 20; ++z)
        for (int64_t y = 0; y < 20; ++y)
            for (int64_t x = 0; x < 20; ++x) {
                const double r2 = sq(x - 9.5) + sq(y - 9.5) + sq(z - 9.5);
                ball(x, y, z) = r2 <= 36 ? kEndocast : kBone;
                const double rho = std::sqrt(sq(x - 9.5) + sq(y - 9.5));
                ring(x, y, z) = sq(rho - 6) + sq(z - 9.5) <= 4 ? kEndocast : kBone;
                hollow(x, y, z) = r2 <= 64 && r2 > 9 ? kEndocast : kBone;
            }
    EXPECT_EQ(freudenthal_euler_characteristic(ball, kEndocast), 1);
    EXPECT_EQ(freudenthal_euler_characteristic(ring, kEndocast), 0);
    EXPECT_EQ(freudenthal_euler_characteristic(hollow, kEndocast), 2);
}

// Against a brute-force count of the simplices V - E + F - T of the Freudenthal triangulation (each
// simplex a chain p < p + a < p + a + b < ... of unit steps along distinct axes), on random sets
// that touch the volume's border, with other labels beside the one counted.
TEST(Handles, EulerCharacteristicMatchesABruteForceCountOfSimplices) {
    Geometry g;
    g.dims = {13, 11, 9};
    std::mt19937 rng(7);
    for (int trial = 0; trial < 6; ++trial) {
        Volume<uint8_t> v(g, 0);
        std::uniform_int_distribution<int> pick(0, 9);
        const int density = 2 + trial;  // of 10
        for (size_t i = 0; i < v.size(); ++i) {
            const int k = pick(rng);
            v[i] = k < density ? kEndocast : (k % 2 ? kBone : kOther);
        }
        auto in = [&](int64_t x, int64_t y, int64_t z) { return v.contains(x, y, z) && v(x, y, z) == kEndocast; };
        long chi = 0;
        // Every chain from p: steps along a sequence of distinct axes, 0 to 3 of them.
        const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (int64_t z = 0; z < 9; ++z)
            for (int64_t y = 0; y < 11; ++y)
                for (int64_t x = 0; x < 13; ++x) {
                    if (!in(x, y, z)) continue;
                    ++chi;  // the vertex
                    // A simplex of dimension k is a chain whose k steps are groups of axes: count each
                    // chain of vertices once by its set of vertices (distinct subsets of {0,1}^3 offsets).
                    std::set<std::vector<int>> simplices;
                    for (const auto& q : perms)
                        for (int mask = 1; mask < 8; ++mask) {  // which of the 3 prefix points are kept
                            std::vector<int> pts;
                            int off = 0;
                            for (int s = 0; s < 3; ++s) {
                                off |= 1 << q[s];
                                if (mask >> s & 1) pts.push_back(off);
                            }
                            bool ok = true;
                            for (int o : pts) ok = ok && in(x + (o & 1), y + (o >> 1 & 1), z + (o >> 2 & 1));
                            if (ok) simplices.insert(pts);
                        }
                    for (const auto& s : simplices) chi += s.size() % 2 ? -1 : 1;  // edge -, triangle +, tet -
                }
        EXPECT_EQ(freudenthal_euler_characteristic(v, kEndocast), chi) << "trial " << trial;
    }
}

// A torus of E voxels (in bone) whose tube narrows at one place (x > 15), with its distance to bone.
static void narrowing_ring(Volume<uint8_t>& labels, Volume<float>& dist) {
    Geometry g;
    g.dims = {24, 24, 16};
    labels = Volume<uint8_t>(g, kBone);
    dist = Volume<float>(g, 0.0f);
    for (int64_t z = 0; z < 16; ++z)
        for (int64_t y = 0; y < 24; ++y)
            for (int64_t x = 0; x < 24; ++x) {
                const double rho = std::sqrt(sq(x - 11.5) + sq(y - 11.5));
                const double tube = x > 15 ? 1.6 : 3.2;
                const double t = std::sqrt(sq(rho - 7) + sq(z - 7.5));
                if (t <= tube) {
                    labels(x, y, z) = kEndocast;
                    dist(x, y, z) = float(tube - t + 0.5);
                }
            }
}

// Every one of the 2^14 configurations of a voxel's 14 neighbours: FreudenthalLink::simple (a
// table) against the definition worked out on the offsets themselves (the set's part of the link
// and the rest both non-empty and connected, two neighbours joined when their difference is one of
// the 14 offsets).
TEST(Handles, SimplePointTableMatchesTheLinkDefinition) {
    std::vector<std::array<int, 3>> offs;
    auto freudenthal = [](int dx, int dy, int dz) {
        if (!dx && !dy && !dz) return false;
        const bool up = dx >= 0 && dy >= 0 && dz >= 0, down = dx <= 0 && dy <= 0 && dz <= 0;
        return (up || down) && std::abs(dx) <= 1 && std::abs(dy) <= 1 && std::abs(dz) <= 1;
    };
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx)
                if (freudenthal(dx, dy, dz)) offs.push_back({dx, dy, dz});
    ASSERT_EQ(offs.size(), 14u);
    auto connected = [&](const std::vector<int>& members) {
        if (members.empty()) return false;
        std::vector<int> reached{members[0]};
        for (size_t i = 0; i < reached.size(); ++i)
            for (int b : members) {
                const auto& p = offs[size_t(reached[i])];
                const auto& q = offs[size_t(b)];
                if (std::find(reached.begin(), reached.end(), b) == reached.end() &&
                    freudenthal(q[0] - p[0], q[1] - p[1], q[2] - p[2]))
                    reached.push_back(b);
            }
        return reached.size() == members.size();
    };
    endocast::Geometry g;
    g.dims = {3, 3, 3};
    endocast::Volume<uint8_t> mask(g, 0);
    const endocast::FreudenthalLink link(3, 3);
    const size_t centre = mask.index(1, 1, 1);
    for (unsigned c = 0; c < (1u << 14); ++c) {
        std::vector<int> in, out;
        for (int k = 0; k < 14; ++k) {
            const auto& o = offs[size_t(k)];
            const bool set = (c >> k) & 1;
            mask(1 + o[0], 1 + o[1], 1 + o[2]) = set;
            (set ? in : out).push_back(k);
        }
        ASSERT_EQ(link.simple(mask, centre), connected(in) && connected(out)) << "configuration " << c;
    }
}

TEST(Handles, WithoutAnEndocastNothingChangesAndTheCharacteristicIsZero) {
    Geometry g;
    g.dims = {8, 8, 8};
    Volume<uint8_t> labels(g, kOther);
    labels(3, 3, 3) = kBone;
    const Volume<uint8_t> before = labels;
    const Volume<float> dist(g, 1.0f);
    const HandleClosing h = close_handles(labels, 0, dist, {0, 0, 0});
    EXPECT_EQ(h.euler_before, 0);
    EXPECT_EQ(h.euler_after, 0);
    EXPECT_EQ(h.voxels_closed, 0u);
    EXPECT_EQ(labels.buffer(), before.buffer());
}

TEST(Handles, ARingIsCutOnceWhereItIsThinnest) {
    // A torus of E voxels whose tube narrows at one place (x > 15): close_handles leaves a ball,
    // cut across the narrow part.
    Volume<uint8_t> labels;
    Volume<float> dist;
    narrowing_ring(labels, dist);
    const long before = freudenthal_euler_characteristic(labels, kEndocast);
    ASSERT_EQ(before, 0);
    size_t seed = 0;
    for (size_t i = 0; i < labels.size(); ++i)
        if (dist[i] > dist[seed]) seed = i;
    const HandleClosing h = close_handles(labels, seed, dist, {0, 0, 0});
    EXPECT_EQ(h.euler_before, 0);
    EXPECT_EQ(h.euler_after, 1);
    EXPECT_GT(h.voxels_closed, 0u);
    // The cut lies in the narrow part.
    for (int64_t z = 0; z < 16; ++z)
        for (int64_t y = 0; y < 24; ++y)
            for (int64_t x = 0; x <= 15; ++x) {
                const double rho = std::sqrt(sq(x - 11.5) + sq(y - 11.5));
                if (std::sqrt(sq(rho - 7) + sq(z - 7.5)) <= 3.2) EXPECT_EQ(labels(x, y, z), kEndocast);
            }
}

TEST(Handles, AHandleHiddenBehindAVoidIsCutToo) {
    // The ring of the test above with a bone voxel enclosed in its thick part: its Euler
    // characteristic is 1 (no handle to see: 1 piece - 1 handle + 1 void), but the polygonizer
    // fills the void, and its mesh would have genus 1. close_handles fills it first, then cuts.
    Volume<uint8_t> labels;
    Volume<float> dist;
    narrowing_ring(labels, dist);
    labels(5, 12, 8) = kBone;
    ASSERT_EQ(freudenthal_euler_characteristic(labels, kEndocast), 1);
    const size_t seed = labels.index(5, 12, 7);
    ASSERT_EQ(labels[seed], kEndocast);
    const HandleClosing h = close_handles(labels, seed, dist, {0, 0, 0});
    EXPECT_EQ(h.voxels_matched, 1u);
    EXPECT_EQ(labels(5, 12, 8), kEndocast);
    EXPECT_EQ(h.euler_before, 0);
    EXPECT_EQ(h.euler_after, 1);
    EXPECT_GT(h.voxels_closed, 0u);
    EXPECT_EQ(freudenthal_euler_characteristic(labels, kEndocast), 1);
}

TEST(Openings, NoCavityIsNoResult) {
    // A plate of bone 4 voxels thick across a 40^3 volume: empty space on both sides, open to the
    // border everywhere; nothing is enclosed.
    const Volume<float> ct = carve({40, 40, 40}, [](double, double, double z) { return z < 18 || z >= 22; });
    EXPECT_THROW(extract_endocast(ct, binary_params()), NoResult);
}

TEST(Openings, ACavityCutByTheVolumeBorderIsClosedAtTheBorderWithoutADent) {
    // The human phantom cropped at its skull base, the cavity meeting the lower face of the volume
    // over a small disk (10 mm above its lowest point) or a large one (30 mm): the border balls of
    // the outside seeds must not eat into it. Away from the border's first voxel layer no vertex
    // lies more than 2 mm inside the true cavity, and it is reported and warned.
    for (const double crop : {2.0, 4.0, 10.0, 30.0}) {
        PhantomParams pp;
        pp.crop_base_mm = crop;
        const PhantomResult ph = generate_phantom(pp);
        ExtractParams p;
        p.binarize.isovalue = ph.suggested_iso;
        const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
        const double voxel = ph.ct.geometry().spacing[2];
        double deepest = 0, at_z = 0;
        for (const auto& v : r.mesh.vertices) {
            if (v[2] < ph.crop_plane_z_mm + voxel) continue;
            const double s = phantom_cavity_signed_distance(ph, {v[0], v[1], v[2]});
            if (s < deepest) {
                deepest = s;
                at_z = v[2] - ph.crop_plane_z_mm;
            }
        }
        std::printf("cropped %.0f mm: ECV %+.3f %%, deepest vertex %.2f mm inside the truth, %.1f mm above "
                    "the border; border contact %.0f mm^2\n",
                    crop, 100 * (r.ecv_ml / ph.true_ecv_ml - 1), -deepest, at_z, r.border_contact_mm2);
        SCOPED_TRACE("crop " + std::to_string(crop));
        EXPECT_GT(deepest, -2.0);
        EXPECT_GT(r.border_contact_mm2, 0.0);
        bool warned = false;
        for (const auto& w : r.warnings) warned = warned || w.message.find("meets the volume border") != std::string::npos;
        EXPECT_TRUE(warned);
        EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, 0.005);
    }
}

TEST(Openings, WithThinBoneAirInATissueFilledCavityIsLeftOut) {
    // A tissue-filled braincase (35) holding a pocket of air (-1000) against its floor: the
    // watershed takes it, being empty space. A living braincase holds no air: with thin bone
    // recovered (whose closed sinus walls let an air sinus join the cavity: cthead's sphenoid
    // sinus), the air and the voxels within two voxels of it leave the cavity. Without it, nothing
    // changes.
    // A 6 mm skull in air, as a scan holds it: the air/tissue split (Otsu) lies between them.
    Geometry g;
    g.dims = {80, 80, 80};
    Volume<float> ct(g, -1000.0f);
    for (int64_t z = 0; z < 80; ++z)
        for (int64_t y = 0; y < 80; ++y)
            for (int64_t x = 0; x < 80; ++x) {
                const double r2 = sq(x - kCx) + sq(y - kCy) + sq(z - kCz);
                if (r2 <= sq(kR + 6)) ct(x, y, z) = 1400.0f;
                if (r2 <= kR * kR) ct(x, y, z) = 35.0f;
                if (r2 <= kR * kR && sq(x - kCx) + sq(y - kCy) + sq(z - (kCz - kR + 4)) <= 5.0 * 5.0)
                    ct(x, y, z) = -1000.0f;
            }
    ExtractParams p;
    p.binarize.isovalue = 700;
    p.void_fill.radius_voxels = 0;
    p.binarize.thin_bone_prominence = 0;
    const ExtractionResult kept = extract_endocast(ct, p);
    const double sphere_ml = 4.0 / 3.0 * M_PI * kR * kR * kR / 1000.0;
    EXPECT_NEAR(kept.ecv_ml / sphere_ml, 1.0, 0.01);  // the air is in
    EXPECT_EQ(kept.air_excluded_voxels, 0u);
    p.binarize.thin_bone_prominence = 0.5;
    const ExtractionResult r = extract_endocast(ct, p);
    EXPECT_GT(r.air_excluded_voxels, 300u);
    // The air (about 0.4 mL) and its rim are out.
    EXPECT_GT(kept.ecv_ml - r.ecv_ml, 0.3);
    expect_clean_genus0(r.mesh);
}
