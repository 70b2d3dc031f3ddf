#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "../meshpost/test_meshes.h"
#include "endocast/stages/bone_contact.h"
#include "endocast/errors.h"
#include "meshpost/patches.h"

using namespace endocast;
using meshpost::test::icosphere;
using meshpost::test::with_threads;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kR = 20.0;          // cavity radius, mm
constexpr double kShellOut = 30.0;   // outer radius of the bone shell, mm

/// A CT of 0.5 mm voxels covering [-36, 36] mm around `centre` (world), with `direction`:
/// bone (1000) where kR <= |x - centre| <= kShellOut, 0 elsewhere; with a hole, no bone within
/// `hole_deg` degrees of the +z axis (a round opening seen from the centre). The values depend on
/// the world position only, so any direction gives the same picture in world space.
Volume<float> shell_ct(double hole_deg = 0, const std::array<double, 9>& direction = {1, 0, 0, 0, 1, 0, 0, 0, 1},
                       Vec3 centre = {0, 0, 0}) {
    Geometry g;
    g.dims = {145, 145, 145};
    g.spacing = {0.5, 0.5, 0.5};
    g.direction = direction;
    // origin such that the middle voxel (72, 72, 72) lies at `centre`
    const Vec3 mid = Geometry{g.dims, g.spacing, {0, 0, 0}, direction}.index_to_world(72, 72, 72);
    g.origin = {centre[0] - mid[0], centre[1] - mid[1], centre[2] - mid[2]};
    Volume<float> ct(g, 0.0f);
    const double cos_hole = std::cos(hole_deg * kPi / 180.0);
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                const Vec3 w = g.index_to_world(double(x), double(y), double(z));
                const double dx = w[0] - centre[0], dy = w[1] - centre[1], dz = w[2] - centre[2];
                const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
                const bool in_hole = hole_deg > 0 && dz > r * cos_hole;
                if (r >= kR && r <= kShellOut && !in_hole) ct(x, y, z) = 1000.0f;
            }
    return ct;
}

/// The cavity's surface: an icosphere of radius kR (level 5: 20480 faces, edges of ~1.2 mm).
meshpost::TriangleMesh cavity(Vec3 centre = {0, 0, 0}) { return icosphere(kR, 5, {centre[0], centre[1], centre[2]}); }

}  // namespace

TEST(BoneContact, ClosedShellIsAllOnBone) {
    const BoneContact b = bone_contact(cavity(), shell_ct(), 500.0);
    EXPECT_EQ(b.share, 1.0);
    EXPECT_EQ(b.area_on_bone_mm2, b.area_mm2);
    // The icosphere's area, a little under the sphere's 4 pi R^2.
    EXPECT_NEAR(b.area_mm2, 4 * kPi * kR * kR, 0.005 * 4 * kPi * kR * kR);
    ASSERT_EQ(b.face_on_bone.size(), cavity().faces.size());
    for (uint8_t f : b.face_on_bone) ASSERT_EQ(f, 1);
}

TEST(BoneContact, RoundHoleLowersTheShareByItsCapsAreaFraction) {
    // A hole of half-angle 45 deg: its cap is (1 - cos 45) / 2 = 14.6 % of the sphere. Sampling
    // errs by about half a voxel (0.25 mm) along the rim and the faces straddling it (~1.2 mm
    // edges): a band of 2 pi R sin 45 x ~1 mm, < 0.5 % of the area.
    const double hole = 45.0;
    const double cap = (1.0 - std::cos(hole * kPi / 180.0)) / 2.0;
    const BoneContact b = bone_contact(cavity(), shell_ct(hole), 500.0);
    EXPECT_NEAR(b.share, 1.0 - cap, 0.005);
    EXPECT_NEAR(b.area_on_bone_mm2 / b.area_mm2, b.share, 1e-15);
    // The faces off bone are those of the cap (their centroid within the hole's cone, up to the
    // rim band), and nowhere else.
    const meshpost::TriangleMesh m = cavity();
    for (size_t f = 0; f < m.faces.size(); ++f) {
        const auto& a = m.vertices[m.faces[f][0]];
        const auto& c = m.vertices[m.faces[f][1]];
        const auto& d = m.vertices[m.faces[f][2]];
        const double z = (a[2] + c[2] + d[2]) / 3.0 / kR;
        const double deg = std::acos(std::min(1.0, z)) * 180.0 / kPi;
        if (deg < hole - 3) EXPECT_EQ(b.face_on_bone[f], 0) << f;
        if (deg > hole + 3) EXPECT_EQ(b.face_on_bone[f], 1) << f;
    }
}

TEST(BoneContact, RotatedAndShiftedGridGivesTheSameShare) {
    // Volume geometry with a non-identity direction (30 deg about an oblique axis, left-handed
    // too) and an origin far from 0: the CT is the same in world space, so is the share.
    const double c = std::cos(kPi / 6), s = std::sin(kPi / 6);
    const std::array<double, 9> rot{c, -s, 0, s, c, 0, 0, 0, 1};
    const std::array<double, 9> flip{c, -s, 0, s, c, 0, 0, 0, -1};
    const Vec3 centre{-120.5, 33.25, 410.0};
    const BoneContact ref = bone_contact(cavity(), shell_ct(45.0), 500.0);
    for (const auto& dir : {rot, flip}) {
        const BoneContact b = bone_contact(cavity(centre), shell_ct(45.0, dir, centre), 500.0);
        EXPECT_NEAR(b.share, ref.share, 0.003);
    }
}

TEST(BoneContact, EmptyCtOrMeshOrSamplesOutsideGiveZero) {
    EXPECT_EQ(bone_contact(cavity(), Volume<float>(shell_ct().geometry(), 0.0f), 500.0).share, 0.0);
    const BoneContact none = bone_contact(cavity(), Volume<float>(), 500.0);
    EXPECT_EQ(none.share, 0.0);
    EXPECT_GT(none.area_mm2, 0.0);
    EXPECT_EQ(bone_contact(meshpost::TriangleMesh{}, shell_ct(), 500.0).share, 0.0);
    // A mesh far outside the volume: every sample outside, none on bone (even at isovalue <= 0).
    EXPECT_EQ(bone_contact(cavity({500, 0, 0}), shell_ct(), -1.0).share, 0.0);
}

TEST(BoneContact, InwardFacesMissTheBoneAndTheOffsetSetsTheDepth) {
    // Faces turned inward sample the cavity (0 HU): nothing on bone.
    meshpost::TriangleMesh inward = cavity();
    for (auto& f : inward.faces) std::swap(f[1], f[2]);
    EXPECT_EQ(bone_contact(inward, shell_ct(), 500.0).share, 0.0);
    // The offset sets how far out the CT is read: a surface 2 mm inside the cavity reaches the
    // bone with 3 mm, not with 1 mm.
    BoneContactParams p;
    p.offset_mm = 3;
    EXPECT_EQ(bone_contact(icosphere(kR - 2, 5), shell_ct(), 500.0, p).share, 1.0);
    EXPECT_EQ(bone_contact(icosphere(kR - 2, 5), shell_ct(), 500.0).share, 0.0);
    p.offset_mm = -1;
    EXPECT_THROW(bone_contact(cavity(), shell_ct(), 500.0, p), InvalidParameter);
    p.offset_mm = std::nan("");
    EXPECT_THROW(bone_contact(cavity(), shell_ct(), 500.0, p), InvalidParameter);
    meshpost::TriangleMesh bad = cavity();
    bad.faces.push_back({0, 1, uint32_t(bad.vertices.size())});
    EXPECT_THROW(bone_contact(bad, shell_ct(), 500.0), InvalidParameter);
}

TEST(BoneContact, SameBytesForOneAndTwoThreads) {
    // Several chunks of faces (level 6: 81920 faces), with a hole so that both flags occur.
    const meshpost::TriangleMesh m = icosphere(kR, 6);
    const Volume<float> ct = shell_ct(30.0);
    const BoneContact a = with_threads(1, [&] { return bone_contact(m, ct, 500.0); });
    const BoneContact b = with_threads(2, [&] { return bone_contact(m, ct, 500.0); });
    EXPECT_EQ(std::memcmp(&a.share, &b.share, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&a.area_mm2, &b.area_mm2, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&a.area_on_bone_mm2, &b.area_on_bone_mm2, sizeof(double)), 0);
    EXPECT_EQ(a.face_on_bone, b.face_on_bone);
    EXPECT_GT(a.share, 0.5);
    EXPECT_LT(a.share, 1.0);
}

TEST(ClosingSurfaces, ARoundHoleIsOnePatchWithItsCapsAreaCentreAndNormal) {
    // The 45 deg hole's cap: area 2 pi R^2 (1 - cos 45), centroid on +z at R (1 + cos 45) / 2,
    // normal +z; nothing else is off bone, and a minimum area above the cap's lists nothing.
    const double hole = 45.0, c45 = std::cos(hole * kPi / 180.0);
    const meshpost::TriangleMesh m = cavity();
    const BoneContact b = bone_contact(m, shell_ct(hole), 500.0);
    const std::vector<ClosingSurface> s = closing_surfaces(m, b.face_on_bone, 1.0);
    ASSERT_EQ(s.size(), 1u);
    const double cap = 2 * kPi * kR * kR * (1 - c45);
    EXPECT_NEAR(s[0].area_mm2, cap, 0.03 * cap);
    EXPECT_NEAR(s[0].area_mm2, b.area_mm2 - b.area_on_bone_mm2, 1e-6 * cap);
    EXPECT_NEAR(s[0].centre[0], 0, 0.2);
    EXPECT_NEAR(s[0].centre[1], 0, 0.2);
    EXPECT_NEAR(s[0].centre[2], kR * (1 + c45) / 2, 0.3);
    EXPECT_NEAR(s[0].normal[2], 1.0, 1e-3);
    EXPECT_TRUE(closing_surfaces(m, b.face_on_bone, 1.1 * cap).empty());
    // A closed shell has no closing surface.
    EXPECT_TRUE(closing_surfaces(m, bone_contact(m, shell_ct(), 500.0).face_on_bone, 0).empty());
}

// bone_contact after some vertices moved samples only the faces around them: the same flags and
// sums, bit for bit, as sampling every face of the moved mesh (the vertices inside a cone round
// +z pulled in by 6 mm, off the bone, over several chunks of faces); the others keep `before`'s
// flags, which are trusted (a wrong flag on an unmoved face stays wrong). Bad input is refused.
TEST(BoneContact, AfterAMoveOnlyTheMovedFacesAreSampledAgain) {
    meshpost::TriangleMesh m = icosphere(kR, 6);
    const Volume<float> ct = shell_ct();
    const BoneContact before = bone_contact(m, ct, 500.0);
    std::vector<uint32_t> moved;
    for (uint32_t v = 0; v < m.vertices.size(); ++v) {
        meshpost::Point& p = m.vertices[v];
        if (p[2] < 0.8 * kR) continue;
        for (double& c : p) c *= (kR - 6.0) / kR;
        moved.push_back(v);
    }
    ASSERT_GT(moved.size(), 100u);
    const BoneContact full = bone_contact(m, ct, 500.0);
    const BoneContact again = bone_contact(m, ct, 500.0, {}, before.face_on_bone, moved);
    EXPECT_LT(full.share, before.share);
    EXPECT_EQ(again.face_on_bone, full.face_on_bone);
    EXPECT_EQ(std::memcmp(&again.share, &full.share, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&again.area_mm2, &full.area_mm2, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&again.area_on_bone_mm2, &full.area_on_bone_mm2, sizeof(double)), 0);
    std::vector<uint8_t> wrong = before.face_on_bone;
    wrong.back() = 0;  // the last face, far from the cone (-z side), keeps the flag it is given
    ASSERT_LT(m.vertices[m.faces.back()[0]][2], 0.8 * kR);
    EXPECT_EQ(bone_contact(m, ct, 500.0, {}, wrong, moved).face_on_bone.back(), 0);
    EXPECT_THROW(bone_contact(m, ct, 500.0, {}, std::vector<uint8_t>(3, 1), moved), InvalidParameter);
    EXPECT_THROW(bone_contact(m, ct, 500.0, {}, before.face_on_bone, {uint32_t(m.vertices.size())}), InvalidParameter);
}

TEST(ClosingSurfaces, GivenNeighboursGiveTheSamePatches) {
    const meshpost::TriangleMesh m = cavity();
    const BoneContact b = bone_contact(m, shell_ct(45.0), 500.0);
    const std::vector<ClosingSurface> a = closing_surfaces(m, b.face_on_bone, 1.0);
    const std::vector<ClosingSurface> c = closing_surfaces(m, b.face_on_bone, 1.0, meshpost::face_neighbours(m));
    ASSERT_EQ(a.size(), c.size());
    for (size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i].area_mm2, c[i].area_mm2);
        EXPECT_EQ(a[i].centre, c[i].centre);
        EXPECT_EQ(a[i].normal, c[i].normal);
    }
    EXPECT_THROW(closing_surfaces(m, b.face_on_bone, 1.0, {}), meshpost::InvalidMesh);
}
