// The coarse-to-fine path's fine pass (refine.h) on a shell of bone with a known cavity; the
// skull-base phantoms' accuracy on it is in test_skull_base_accuracy.cpp (SkullBaseRefine).
#include <gtest/gtest.h>

#include <cmath>

#include "endocast/errors.h"
#include "endocast/stages/marching_cubes.h"
#include "method/refine.h"
#include "endocast/stages/resample.h"
#include "meshpost/measure.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;
using endocast::testing::grid;

namespace {

constexpr double kT = 500;

// A spherical cavity of radius 12 mm in a shell of bone to 15 mm, edges ramped over 1 mm (the CT
// is T = 500 at 12 and 15 mm), on 0.5 mm voxels: 72^3.
Volume<float> shell_ct() {
    const Geometry g = grid(72, 72, 72, {0.5, 0.5, 0.5});
    Volume<float> ct(g);
    for (int64_t z = 0; z < 72; ++z)
        for (int64_t y = 0; y < 72; ++y)
            for (int64_t x = 0; x < 72; ++x) {
                const double r = std::hypot((x - 35.3) * 0.5, (y - 35.6) * 0.5, (z - 35.4) * 0.5);
                const double inner = std::clamp(r - 11.5, 0.0, 1.0), outer = std::clamp(15.5 - r, 0.0, 1.0);
                ct(x, y, z) = float(1000 * std::min(inner, outer));
            }
    return ct;
}

struct Coarse {
    Volume<float> ct;
    Volume<uint8_t> region, labels;
};

// What the method would leave on the grid downsampled by 2: the region = the coarse cavity's voxels
// (CT < T, inside the shell), labels kBone where CT >= T, kOther beyond the shell.
Coarse coarse_of(const Volume<float>& fine) {
    Coarse c{downsample(fine, 2), {}, {}};
    c.region = Volume<uint8_t>(c.ct.geometry(), 0);
    c.labels = Volume<uint8_t>(c.ct.geometry(), kOther);
    const Geometry& g = c.ct.geometry();
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                const Vec3 w = g.index_to_world(double(x), double(y), double(z));
                const double r = std::hypot(w[0] - 35.3 * 0.5, w[1] - 35.6 * 0.5, w[2] - 35.4 * 0.5);
                if (c.ct(x, y, z) >= kT) c.labels(x, y, z) = kBone;
                else if (r < 13.5) c.region(x, y, z) = 1, c.labels(x, y, z) = kEndocast;
            }
    return c;
}

RefineResult refine(const Volume<float>& fine, const Volume<uint8_t>& classes, int64_t slab,
                    const meshpost::TriangleMesh* clip = nullptr) {
    RefineParams p;
    p.isovalue = kT;
    p.other_value = 2 * kT;
    p.slab_planes = slab;
    p.clip_mesh = clip;
    const Geometry& g = fine.geometry();
    return refine_full_resolution(
        g, [&](int64_t z, float* dst) { std::copy(&fine(0, 0, z), &fine(0, 0, z) + g.dims[0] * g.dims[1], dst); },
        classes, 2, p);
}

const double kSphere = 4.0 / 3.0 * M_PI * 12 * 12 * 12;

}  // namespace

TEST(Refine, TheWallIsTheFineIsosurfaceWhateverTheSlabs) {
    const Volume<float> fine = shell_ct();
    const Coarse c = coarse_of(fine);
    const Volume<uint8_t> classes = refine_classes(c.region, c.labels, c.ct, kT, {}, {});
    size_t counts[4] = {0, 0, 0, 0};
    for (size_t i = 0; i < classes.size(); ++i) ++counts[classes[i]];
    EXPECT_GT(counts[kRefineCore], 0u);
    EXPECT_GT(counts[kRefineBandIn], 0u);
    EXPECT_GT(counts[kRefineBandBone], 0u);
    const RefineResult one = refine(fine, classes, 1000);
    expect_clean_genus0(one.mesh);
    // The coarse region's mesh is a voxel staircase on 1 mm voxels; the refined one the 0.5 mm
    // isosurface of the cavity (its volume within 0.3 % of the sphere's).
    EXPECT_NEAR(meshpost::signed_volume_mm3(one.mesh) / kSphere, 1.0, 0.003);
    EXPECT_NEAR(one.region_volume_ml * 1000 / kSphere, 1.0, 0.03);
    EXPECT_GT(one.changed_voxels, 0u);
    EXPECT_EQ(one.slabs, 1u);
    for (int64_t slab : {1, 7}) {
        const RefineResult r = refine(fine, classes, slab);
        EXPECT_GT(r.slabs, 5u);
        EXPECT_TRUE(r.mesh.vertices == one.mesh.vertices) << slab;
        EXPECT_TRUE(r.mesh.faces == one.mesh.faces) << slab;
        EXPECT_EQ(r.region_voxels, one.region_voxels);
    }
}

TEST(Refine, NearAClosingSurfaceTheBandStaysInsideTheCoarseMesh) {
    const Volume<float> fine = shell_ct();
    const Coarse c = coarse_of(fine);
    // A coarse mesh that closes lower than the wall (a sphere of radius 11 mm), every face of it
    // "not on bone": the band is clipped to it.
    Volume<float> f(c.ct.geometry());
    for (int64_t z = 0; z < f.nz(); ++z)
        for (int64_t y = 0; y < f.ny(); ++y)
            for (int64_t x = 0; x < f.nx(); ++x) {
                const Vec3 w = f.geometry().index_to_world(double(x), double(y), double(z));
                f(x, y, z) = float(std::hypot(w[0] - 35.3 * 0.5, w[1] - 35.6 * 0.5, w[2] - 35.4 * 0.5));
            }
    const meshpost::TriangleMesh closing = isosurface(f, 11.0);
    const std::vector<uint8_t> not_on_bone(closing.faces.size(), 0);
    const Volume<uint8_t> classes = refine_classes(c.region, c.labels, c.ct, kT, closing, not_on_bone);
    size_t clip = 0;
    for (size_t i = 0; i < classes.size(); ++i) clip += (classes[i] & kRefineClip) != 0;
    EXPECT_GT(clip, 0u);
    const RefineResult r = refine(fine, classes, 16, &closing);
    EXPECT_GT(r.clipped_voxels, 0u);
    expect_clean_genus0(r.mesh);
    const double v = meshpost::signed_volume_mm3(r.mesh);
    EXPECT_LT(v, 0.9 * kSphere);  // within the closing sphere (11 mm: 0.77 of the cavity), not the wall
    EXPECT_GT(v, 0.6 * kSphere);
    EXPECT_THROW(refine(fine, classes, 16, nullptr), InvalidParameter);  // clip flags need the mesh
}

TEST(Refine, BadInputIsRefused) {
    const Volume<float> fine = shell_ct();
    const Coarse c = coarse_of(fine);
    const Volume<uint8_t> classes = refine_classes(c.region, c.labels, c.ct, kT, {}, {});
    EXPECT_THROW(refine_classes(c.region, c.labels, fine, kT, {}, {}), InvalidParameter);  // sizes differ
    EXPECT_THROW(refine_classes(c.region, c.labels, c.ct, kT, {}, {}, 0), InvalidParameter);
    meshpost::TriangleMesh one_face;
    one_face.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    one_face.faces = {{0, 1, 2}};
    EXPECT_THROW(refine_classes(c.region, c.labels, c.ct, kT, one_face, {}), InvalidParameter);  // no flags
    RefineParams p;
    p.isovalue = kT;
    p.other_value = kT;  // must be above T
    const auto read = [&](int64_t z, float* dst) {
        std::copy(&fine(0, 0, z), &fine(0, 0, z) + fine.nx() * fine.ny(), dst);
    };
    EXPECT_THROW(refine_full_resolution(fine.geometry(), read, classes, 2, p), InvalidParameter);
    p.other_value = 2 * kT;
    EXPECT_THROW(refine_full_resolution(fine.geometry(), read, classes, 3, p), InvalidParameter);  // grid
    p.slab_planes = 0;
    EXPECT_THROW(refine_full_resolution(fine.geometry(), read, classes, 2, p), InvalidParameter);
    p.slab_planes = 64;
    const Volume<uint8_t> none(classes.geometry(), kRefineOut);
    EXPECT_THROW(refine_full_resolution(fine.geometry(), read, none, 2, p), NoResult);
}
