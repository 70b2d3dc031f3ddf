// End to end on phantoms with known ECV, and on the real scans in ../shared/data when present.
#include <gtest/gtest.h>
#include <omp.h>

#include <filesystem>

#include "endocast/stages/distance.h"
#include "endocast/io.h"
#include "method/memory.h"
#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "meshpost/measure.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"
#include "../common/slice_reference.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;
using endocast::testing::to_float;

namespace {


struct Case {
    const char* name;
    PhantomParams params;
    bool automatic_iso;
    SurfaceMode surface = SurfaceMode::Iso;
};

// gtest prints a parameter with this (ctest's test list would otherwise show raw bytes).
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

Case make(const char* name, PhantomPreset preset, double tilt, bool auto_iso,
          SurfaceMode surface = SurfaceMode::Iso) {
    Case c{name, {}, auto_iso, surface};
    c.params.preset = preset;
    c.params.tilt_deg = tilt;
    return c;
}

}  // namespace

class PipelinePhantom : public ::testing::TestWithParam<Case> {};

TEST_P(PipelinePhantom, EcvWithinOnePercentAndCleanMesh) {
    const Case& c = GetParam();
    const PhantomResult ph = generate_phantom(c.params);
    ExtractParams p;
    if (!c.automatic_iso) p.binarize.isovalue = ph.suggested_iso;
    p.surface = c.surface;
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    EXPECT_EQ(r.params.surface, c.surface);
    // Issue 5's bars at the phantom's isovalue: 0.3 % for the human presets (tilt up to 30 deg),
    // 1 % for the macaque. The automatic isovalue (Otsu) lies off the brain-bone midpoint (human:
    // 661.5 instead of 717.5, -0.35 %): 1 %.
    const double tolerance =
        c.params.preset == PhantomPreset::Macaque || c.automatic_iso ? 0.01 : 0.003;
    EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, tolerance) << c.name << ": " << r.ecv_ml << " mL vs "
                                                            << ph.true_ecv_ml;
    EXPECT_NEAR(r.mask_volume_ml / ph.true_ecv_ml, 1.0, 0.01);
    EXPECT_GT(r.enclosure, 0.9);
    // A phantom's braincase lies on bone all round but for its closed foramina.
    EXPECT_GE(r.bone_contact, p.min_bone_contact);
    EXPECT_LE(r.bone_contact, 1.0);
    EXPECT_EQ(r.face_on_bone.size(), r.mesh.faces.size());
    EXPECT_TRUE(r.warnings.empty());
    EXPECT_NEAR(r.ecv_ml, meshpost::signed_volume_mm3(r.mesh) / 1000.0, 1e-9);
    expect_clean_genus0(r.mesh);
    // The seed is inside the braincase.
    ASSERT_FALSE(r.endocast_seeds_world.empty());
    const Vec3 s = r.endocast_seeds_world[0], cc = ph.cavity_centre_world;
    const double d = std::hypot(s[0] - cc[0], s[1] - cc[1], s[2] - cc[2]);
    EXPECT_LT(d, 0.5 * std::min({ph.cavity_semi_axes_mm[0], ph.cavity_semi_axes_mm[1],
                                 ph.cavity_semi_axes_mm[2]}));
}

INSTANTIATE_TEST_SUITE_P(
    Presets, PipelinePhantom,
    ::testing::Values(make("human_iso", PhantomPreset::Human, 0, false),
                      make("human_auto", PhantomPreset::Human, 0, true),
                      make("dry_iso", PhantomPreset::Dry, 0, false),
                      make("macaque_auto", PhantomPreset::Macaque, 0, true),
                      make("human_tilt30", PhantomPreset::Human, 30, false),
                      // The half-maximum surface meets the same bars (measured at the suggested
                      // isovalue: human +0.14 %, dry +0.08 %, tilt 30 +0.22 %, macaque +0.25 %;
                      // docs/accuracy.md).
                      make("human_iso_halfmax", PhantomPreset::Human, 0, false, SurfaceMode::HalfMax),
                      make("dry_iso_halfmax", PhantomPreset::Dry, 0, false, SurfaceMode::HalfMax),
                      make("human_tilt30_halfmax", PhantomPreset::Human, 30, false, SurfaceMode::HalfMax),
                      make("macaque_auto_halfmax", PhantomPreset::Macaque, 0, true, SurfaceMode::HalfMax)),
    [](const auto& info) { return std::string(info.param.name); });

TEST(Pipeline, MeshLandsInWorldCoordinatesWithOriginAndAnisotropicSpacing) {
    PhantomParams pp;
    pp.origin = {-100, 50, 20};
    pp.spacing = {1.0, 1.0, 1.5};
    // No crack: a discrete ball's one-voxel tip reaches 1.5 mm into a 1-voxel crack at this
    // spacing, which would move the top of the bounding box (0.04 mL, not a placement error).
    pp.crack = false;
    const PhantomResult ph = generate_phantom(pp);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, 0.01);
    // Centroid of the endocast: the cavity centre, shifted a little by the foramen's cut.
    const auto c = meshpost::volume_centroid(r.mesh);
    EXPECT_NEAR(c[0], ph.cavity_centre_world[0], 1.0);
    EXPECT_NEAR(c[1], ph.cavity_centre_world[1], 1.0);
    EXPECT_NEAR(c[2], ph.cavity_centre_world[2], 1.0);
    // Bounding box: the ellipsoid's extent around the centre (semi-axes before tilt = axes here).
    const auto bb = meshpost::bounding_box(r.mesh);
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(bb.max[a] - ph.cavity_centre_world[a], ph.cavity_semi_axes_mm[a], 0.5) << a;
        if (a != 2)  // the foramen magnum's cap may bulge below the base
            EXPECT_NEAR(ph.cavity_centre_world[a] - bb.min[a], ph.cavity_semi_axes_mm[a], 0.5) << a;
    }
    expect_clean_genus0(r.mesh);
}

TEST(Pipeline, IdenticalMeshForOneAndTwoThreads) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Macaque;
    const PhantomResult ph = generate_phantom(pp);
    const Volume<float> ct = to_float(ph.ct);
    omp_set_num_threads(1);
    const ExtractionResult a = extract_endocast(ct);
    omp_set_num_threads(2);
    const ExtractionResult b = extract_endocast(ct);
    EXPECT_EQ(a.params.isovalue, b.params.isovalue);
    EXPECT_EQ(a.mesh.vertices, b.mesh.vertices);
    EXPECT_EQ(a.mesh.faces, b.mesh.faces);
    EXPECT_EQ(a.mask.buffer(), b.mask.buffer());
}

// The CT held as int16 (what extract does with an integer-valued scan) gives the float CT's result,
// vertex for vertex.
TEST(Pipeline, Int16CtGivesTheFloatCtsResult) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Macaque;
    const PhantomResult ph = generate_phantom(pp);
    const Volume<float> ct = to_float(ph.ct);
    const Volume<int16_t> ct16 = exact_int16(ct);
    ASSERT_FALSE(ct16.empty());
    ExtractParams p;
    p.binarize.isovalue.reset();  // the automatic isovalue from the histogram too
    const ExtractionResult a = extract_endocast(ct, p);
    const ExtractionResult b = extract_endocast(ct16, p);
    EXPECT_EQ(a.params.isovalue, b.params.isovalue);
    EXPECT_EQ(a.mesh.vertices, b.mesh.vertices);
    EXPECT_EQ(a.mesh.faces, b.mesh.faces);
    EXPECT_EQ(a.bone_contact, b.bone_contact);
    EXPECT_EQ(a.ecv_ml, b.ecv_ml);
    EXPECT_EQ(a.thin_bone_voxels, b.thin_bone_voxels);
}

// The bone's box: its bounding box grown by 2 r / spacing + 2 voxels per axis, clamped; none when
// it would be the whole volume or there is no bone.
TEST(Pipeline, BoneWorkBoxIsTheBonesBoxGrownByTwiceTheVoidRadius) {
    Geometry g;
    g.dims = {60, 50, 40};
    g.spacing = {0.5, 1.0, 2.0};
    Volume<uint8_t> bone(g, 0);
    EXPECT_FALSE(bone_work_box(bone, 3.0));
    bone(20, 30, 10) = 1;
    bone(35, 22, 25) = 1;
    const auto box = bone_work_box(bone, 3.0);  // margins 12 + 2, 6 + 2, 3 + 2 voxels
    ASSERT_TRUE(box);
    EXPECT_EQ(box->lo, (Dims{6, 14, 5}));
    EXPECT_EQ(box->hi, (Dims{50, 39, 31}));
    const auto wide = bone_work_box(bone, 6.0);  // margins 26, 14, 8 voxels: clamped along x
    ASSERT_TRUE(wide);
    EXPECT_EQ(wide->lo, (Dims{0, 8, 2}));
    EXPECT_EQ(wide->hi, (Dims{60, 45, 34}));
    EXPECT_FALSE(bone_work_box(bone, 12.0));  // clamped to the whole volume
    bone(0, 0, 0) = 1;
    bone(59, 49, 39) = 1;
    EXPECT_FALSE(bone_work_box(bone, 3.0));  // the whole volume
}

// The watershed resumes the seeds' candidate flood by default; flooding again from scratch (a
// watershed quantum given, or cut planes) gives the same cavity up to ties within a quantum: the
// macaque phantom's ECV within 0.01 %, both closed genus-0 surfaces.
TEST(Pipeline, TheResumedWatershedGivesTheFullFloodsCavity) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Macaque;
    const PhantomResult ph = generate_phantom(pp);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    const ExtractionResult resumed = extract_endocast(ph.ct, p);
    EXPECT_TRUE(resumed.watershed_resumed);
    p.watershed.quantum_mm = ph.ct.geometry().smallest_spacing() / 64.0;  // the default's value, given
    const ExtractionResult full = extract_endocast(ph.ct, p);
    EXPECT_FALSE(full.watershed_resumed);
    EXPECT_NEAR(resumed.ecv_ml, full.ecv_ml, 1e-4 * full.ecv_ml);
    EXPECT_NEAR(resumed.ecv_ml, ph.true_ecv_ml, 5e-3 * ph.true_ecv_ml);
    for (const ExtractionResult* r : {&resumed, &full}) {
        const auto topo = meshpost::analyze_topology(r->mesh);
        EXPECT_TRUE(meshpost::is_closed_manifold(topo));
        EXPECT_EQ(topo.genus, 0);
    }
}

// The box against a brute-force one on sparse random bone, rows of lengths around the box scan's
// 32-voxel chunks (hits before, in and after a chunk, and in the tail).
TEST(Pipeline, BoneWorkBoxMatchesABruteForceBox) {
    uint32_t seed = 5;
    for (const int64_t nx : {1, 5, 31, 32, 33, 64, 70, 100})
        for (const double density : {0.0005, 0.003, 0.02}) {
            Geometry g;
            g.dims = {nx, 9, 7};
            Volume<uint8_t> bone = endocast::testing::random_mask(g, density, seed++);
            std::array<int64_t, 3> lo{nx, 9, 7}, hi{-1, -1, -1};
            for (int64_t z = 0; z < 7; ++z)
                for (int64_t y = 0; y < 9; ++y)
                    for (int64_t x = 0; x < nx; ++x)
                        if (bone(x, y, z)) {
                            const int64_t c[3] = {x, y, z};
                            for (size_t a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a]);
                        }
            const auto box = bone_work_box(bone, 0.0);  // grown by 2 voxels
            if (hi[0] < 0) {
                EXPECT_FALSE(box) << nx << " " << density;
                continue;
            }
            bool whole = true;
            Dims elo{}, ehi{};
            for (size_t a = 0; a < 3; ++a) {
                elo[a] = std::max<int64_t>(0, lo[a] - 2);
                ehi[a] = std::min<int64_t>(g.dims[a], hi[a] + 3);
                whole = whole && elo[a] == 0 && ehi[a] == g.dims[a];
            }
            ASSERT_EQ(bool(box), !whole) << nx << " " << density;
            if (!box) continue;
            EXPECT_EQ(box->lo, elo) << nx << " " << density;
            EXPECT_EQ(box->hi, ehi) << nx << " " << density;
        }
}

// The stages after binarize on the bone's box give the whole volume's result: the same mesh, and
// the mask and labels on the input's grid (the macaque phantom: 10 voxels of air on every side
// are left out).
TEST(Pipeline, BoneBoxGivesTheWholeVolumesResult) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Macaque;
    const PhantomResult ph = generate_phantom(pp);
    const Volume<float> ct = to_float(ph.ct);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    p.keep_labels = true;
    const ExtractionResult boxed = extract_endocast(ct, p);
    p.bone_box = false;
    const ExtractionResult whole = extract_endocast(ct, p);
    ASSERT_TRUE(boxed.work_box);
    EXPECT_FALSE(whole.work_box);
    const Dims size = boxed.work_box->size();
    EXPECT_LT(double(size[0] * size[1] * size[2]), 0.9 * double(ct.size()));
    EXPECT_EQ(boxed.mesh.vertices, whole.mesh.vertices);
    EXPECT_EQ(boxed.mesh.faces, whole.mesh.faces);
    EXPECT_EQ(boxed.ecv_ml, whole.ecv_ml);
    EXPECT_EQ(boxed.mask.dims(), ct.dims());
    EXPECT_EQ(boxed.mask.buffer(), whole.mask.buffer());
    EXPECT_EQ(boxed.labels.dims(), ct.dims());
    size_t differ = 0;
    for (size_t i = 0; i < ct.size(); ++i) differ += (boxed.labels[i] == kEndocast) != (whole.labels[i] == kEndocast);
    EXPECT_EQ(differ, 0u);
    EXPECT_NEAR(boxed.ecv_ml / ph.true_ecv_ml, 1.0, 0.01);
    // The CT given up (released once its box is copied) and no mask kept: the same mesh.
    p.bone_box = true;
    p.keep_labels = false;
    p.keep_mask = false;
    Volume<float> copy = ct;
    const ExtractionResult given = extract_endocast(std::move(copy), p);
    EXPECT_EQ(given.mesh.vertices, whole.mesh.vertices);
    EXPECT_EQ(given.mesh.faces, whole.mesh.faces);
    EXPECT_EQ(given.bone_contact, whole.bone_contact);
    EXPECT_TRUE(given.mask.empty());
    EXPECT_TRUE(given.labels.empty());
}

TEST(Pipeline, OpeningsIdenticalForOneAndTwoThreads) {
    // The human study case (spine, sinus, orbits; tilted 30 deg) at its suggested isovalue: three
    // openings cut by planes (foramen magnum, optic canals) and a speck. Every finding of
    // close_openings and of the seeds is the same. Without thin bone, which closes the speck.
    PhantomParams pp = human_full_phantom_params();
    pp.tilt_deg = 30;
    const PhantomResult ph = generate_phantom(pp);
    const Volume<float> ct = to_float(ph.ct);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    p.binarize.thin_bone_prominence = 0;
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    const ExtractionResult a = extract_endocast(ct, p);
    omp_set_num_threads(2);
    const ExtractionResult b = extract_endocast(ct, p);
    omp_set_num_threads(saved);
    ASSERT_GE(a.openings.openings.size(), 2u);
    EXPECT_GT(a.openings.small_openings_voxels, 0u);
    EXPECT_EQ(a.openings.radius_mm, b.openings.radius_mm);
    EXPECT_EQ(a.openings.core_voxels, b.openings.core_voxels);
    EXPECT_EQ(a.openings.corner_voxels, b.openings.corner_voxels);
    EXPECT_EQ(a.openings.small_openings_voxels, b.openings.small_openings_voxels);
    ASSERT_EQ(a.openings.openings.size(), b.openings.openings.size());
    for (size_t k = 0; k < a.openings.openings.size(); ++k) {
        const Opening &x = a.openings.openings[k], &y = b.openings.openings[k];
        EXPECT_EQ(x.centre_world, y.centre_world) << k;
        EXPECT_EQ(x.normal, y.normal) << k;
        EXPECT_EQ(x.radius_mm, y.radius_mm) << k;
        EXPECT_EQ(x.voxels_removed, y.voxels_removed) << k;
        EXPECT_EQ(x.plane_fitted, y.plane_fitted) << k;
    }
    ASSERT_EQ(a.candidates.size(), b.candidates.size());
    for (size_t k = 0; k < a.candidates.size(); ++k) {
        EXPECT_EQ(a.candidates[k].centre_world, b.candidates[k].centre_world) << k;
        EXPECT_EQ(a.candidates[k].volume_ml, b.candidates[k].volume_ml) << k;
        EXPECT_EQ(a.candidates[k].enclosure, b.candidates[k].enclosure) << k;
    }
    EXPECT_EQ(a.mask.buffer(), b.mask.buffer());
    EXPECT_EQ(a.mesh.vertices, b.mesh.vertices);
    EXPECT_EQ(a.mesh.faces, b.mesh.faces);
}

// close_openings' closing from the ball centres (one transform, what the pipeline does) against
// the closing as dilation then erosion of the bone (two transforms): the same labels and findings,
// on the human study case tilted 30 deg (three openings cut by planes, a speck) and on CThead.
void expect_centres_closing_equals_two_transforms(const Volume<float>& ct, double iso) {
    BinarizeParams bp;
    bp.isovalue = iso;
    const Volume<uint8_t> bone = fill_voids(binarize(ct, bp).bone).bone;
    const Volume<float> dist = distance_transform(bone);
    const Volume<uint8_t> labels = watershed(place_seeds(bone, dist).labels, dist).labels;
    const OpeningParams op;
    const EndocastExtent plain = endocast_extent(labels, dist);
    const EndocastExtent with_centres = endocast_extent(labels, dist, op);
    ASSERT_FALSE(with_centres.ball_centres.empty());
    ASSERT_TRUE(plain.ball_centres.empty());
    Volume<uint8_t> a = labels, b = labels;
    const OpeningsResult ra = close_openings(a, bone, plain, op);
    const OpeningsResult rb = close_openings(b, bone, with_centres, op);
    EXPECT_EQ(ra.core_voxels, rb.core_voxels);
    EXPECT_EQ(ra.corner_voxels, rb.corner_voxels);
    ASSERT_EQ(ra.openings.size(), rb.openings.size());
    for (size_t k = 0; k < ra.openings.size(); ++k) {
        EXPECT_EQ(ra.openings[k].centre_world, rb.openings[k].centre_world) << k;
        EXPECT_EQ(ra.openings[k].voxels_removed, rb.openings[k].voxels_removed) << k;
    }
    EXPECT_TRUE(a.buffer() == b.buffer());
}

TEST(Pipeline, OpeningsClosingFromBallCentresEqualsDilateThenErode) {
    PhantomParams pp = human_full_phantom_params();
    pp.tilt_deg = 30;
    const PhantomResult ph = generate_phantom(pp);
    expect_centres_closing_equals_two_transforms(to_float(ph.ct), ph.suggested_iso);
    const std::string cthead = std::string(ENDOCAST_SHARED_DATA) + "/cthead/cthead.nhdr";
    if (!std::filesystem::exists(cthead)) GTEST_SKIP() << "../shared/data not found: CThead part skipped";
    expect_centres_closing_equals_two_transforms(read_volume({cthead}).volume, 1300);
}

TEST(Pipeline, ReportsStagesInOrder) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Macaque;
    pp.noise = false;
    const PhantomResult ph = generate_phantom(pp);
    std::vector<std::string> stages;
    ExtractParams p;
    p.progress = [&](const std::string& s) { stages.push_back(s); };
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    EXPECT_EQ(stages, (std::vector<std::string>{"binarize", "void_fill", "distance", "seeds",
                                                "watershed", "openings", "polygonize"}));
    EXPECT_GT(r.timings_s.total, 0.0);
    EXPECT_GT(peak_memory_mb(), 0.0);
}

TEST(Pipeline, AnOpenRegionIsNoResult) {
    // Bone only in a slab: nothing is enclosed. The paper's rule still finds a deepest voxel, but
    // its region is neither enclosed by bone nor of a braincase's size: NoResult (exit 5), with a
    // message that says why.
    Geometry g;
    g.dims = {30, 30, 30};
    Volume<float> ct(g, -1000.0f);
    for (int y = 0; y < 30; ++y)
        for (int x = 0; x < 30; ++x) ct(x, y, 15) = 1500;
    ExtractParams p;
    p.binarize.isovalue = 300;
    try {
        extract_endocast(ct, p);
        FAIL() << "expected NoResult";
    } catch (const NoResult& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("the chosen cavity"), std::string::npos) << m;
        EXPECT_TRUE(m.find("not enclosed by bone") != std::string::npos ||
                    m.find("is smaller than") != std::string::npos) << m;
    }
}

TEST(Pipeline, EnclosureOfAClosedShellIsOne) {
    Geometry g;
    g.dims = {5, 5, 5};
    Volume<uint8_t> labels(g, kBone);
    labels(2, 2, 2) = kEndocast;
    EXPECT_DOUBLE_EQ(enclosure_by_bone(labels), 1.0);
    labels(2, 2, 3) = kOther;
    EXPECT_DOUBLE_EQ(enclosure_by_bone(labels), 5.0 / 6.0);
}

TEST(Pipeline, CutPlaneClosesTheCavityAtThePlane) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Macaque;
    pp.noise = false;
    const PhantomResult ph = generate_phantom(pp);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    // A horizontal plane 10 mm above the centre, normal up: the cavity above it is cut off.
    const Vec3 c = ph.cavity_centre_world;
    p.cut_planes.push_back({{c[0], c[1], c[2] + 10.0}, {0, 0, 1}});
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    expect_clean_genus0(r.mesh);
    const auto bb = meshpost::bounding_box(r.mesh);
    EXPECT_LT(bb.max[2], c[2] + 10.0 + 1.0);
    // Ellipsoid below the plane: V = pi a b c (2/3 + h/c - h^3/(3 c^3)), h = 10.
    const double a = ph.cavity_semi_axes_mm[0], b = ph.cavity_semi_axes_mm[1], cz = ph.cavity_semi_axes_mm[2];
    const double h = 10.0;
    const double below = M_PI * a * b * cz * (2.0 / 3.0 + h / cz - h * h * h / (3 * cz * cz * cz)) / 1000.0;
    EXPECT_NEAR(r.ecv_ml / below, 1.0, 0.02);
    EXPECT_GT(r.cut_voxels, 0u);
    p.cut_planes = {{{c[0], c[1], c[2] - 100}, {0, 0, 1}}};  // everything cut away
    EXPECT_THROW(extract_endocast(to_float(ph.ct), p), InvalidParameter);
}

namespace {
/// A spherical cavity (radius 20, centre (30,30,30)) in bone (1000) of a 60x60x90 volume, with a
/// canal (radius 4) along +z from the centre up to slice canal_end (exclusive); air is -1000.
Volume<float> sphere_with_canal(int64_t canal_end) {
    Geometry g;
    g.dims = {60, 60, 90};
    Volume<float> ct(g, 1000.0f);
    for (int64_t z = 0; z < 90; ++z)
        for (int64_t y = 0; y < 60; ++y)
            for (int64_t x = 0; x < 60; ++x) {
                const double dx = x - 30, dy = y - 30, dz = z - 30;
                const bool sphere = dx * dx + dy * dy + dz * dz <= 400;
                const bool canal = dx * dx + dy * dy <= 16 && z >= 30 && z < canal_end;
                if (sphere || canal) ct(x, y, z) = -1000;
            }
    return ct;
}
}  // namespace

TEST(Pipeline, ClosingOpeningsCutsACanalAtItsRim) {
    // A spherical cavity (radius 20) in bone with a canal (radius 4) running from it to the
    // volume border: the watershed's boundary lies somewhere along the canal; closing openings
    // moves it to the canal's mouth on the cavity wall.
    const Volume<float> ct = sphere_with_canal(90);
    ExtractParams p;
    p.binarize.isovalue = 0;
    p.void_fill.radius_voxels = 0;
    p.close_openings = false;
    const ExtractionResult leak = extract_endocast(ct, p);
    p.close_openings = true;
    const ExtractionResult r = extract_endocast(ct, p);
    expect_clean_genus0(r.mesh);
    const double sphere_ml = 4.0 / 3.0 * M_PI * 8000 / 1000.0;
    EXPECT_GT(meshpost::bounding_box(leak.mesh).max[2], 55.0);  // the plain watershed leaks
    EXPECT_LT(meshpost::bounding_box(r.mesh).max[2], 30 + 20 + 1.0);  // cut at the mouth (z ~ 49.6)
    EXPECT_NEAR(r.ecv_ml / sphere_ml, 1.0, 0.02);
    ASSERT_EQ(r.openings.openings.size(), 1u);
    const Opening& o = r.openings.openings[0];
    EXPECT_TRUE(o.plane_fitted);
    EXPECT_GT(o.normal[2], 0.9);
    EXPECT_NEAR(o.centre_world[0], 30, 1.0);
    EXPECT_NEAR(o.centre_world[1], 30, 1.0);
    EXPECT_NEAR(o.radius_mm, 5.0, 2.0);  // the rim ring: wall voxels within reach of the mouth
}

TEST(Pipeline, ClosingOpeningsCutsASealedCanalAtItsRim) {
    // As above, but the canal ends in bone 10 voxels before the border (a spinal canal sealed by
    // tissue above the isovalue, as cthead's at iso 1150): the watershed takes the whole canal into
    // the endocast, and only its reach from the core (30 mm > 1.5 R = 9 mm) shows it is a canal.
    const Volume<float> ct = sphere_with_canal(80);
    ExtractParams p;
    p.binarize.isovalue = 0;
    p.void_fill.radius_voxels = 0;
    p.openings.canal_reach_fraction = 0;  // off: the sealed canal stays (a deep corner)
    const ExtractionResult kept = extract_endocast(ct, p);
    EXPECT_GT(meshpost::bounding_box(kept.mesh).max[2], 75.0);
    p.openings.canal_reach_fraction = OpeningParams{}.canal_reach_fraction;
    const ExtractionResult r = extract_endocast(ct, p);
    expect_clean_genus0(r.mesh);
    const double sphere_ml = 4.0 / 3.0 * M_PI * 8000 / 1000.0;
    EXPECT_LT(meshpost::bounding_box(r.mesh).max[2], 30 + 20 + 1.0);  // cut at the mouth
    EXPECT_NEAR(r.ecv_ml / sphere_ml, 1.0, 0.02);
    ASSERT_EQ(r.openings.openings.size(), 1u);
    EXPECT_TRUE(r.openings.openings[0].plane_fitted);
    EXPECT_GT(r.openings.openings[0].normal[2], 0.9);
    // A sealed dimple 5 mm deep reaches less than 1.5 R from the core: a corner of the cavity, kept.
    const ExtractionResult dimple = extract_endocast(sphere_with_canal(55), p);
    expect_clean_genus0(dimple.mesh);
    EXPECT_TRUE(dimple.openings.openings.empty());
    EXPECT_GT(meshpost::bounding_box(dimple.mesh).max[2], 53.0);
}

TEST(PipelineAccuracy, EcvChangesLittleWithRotationAndHalfResolution) {
    // Issue 5: ECV changes <= 0.5 % when the phantom is rotated 30 deg, <= 1 % at half resolution.
    auto ecv = [](double tilt, double spacing) {
        PhantomParams pp;
        pp.tilt_deg = tilt;
        pp.spacing = {spacing, spacing, spacing};
        const PhantomResult ph = generate_phantom(pp);
        ExtractParams p;
        p.binarize.isovalue = ph.suggested_iso;
        return extract_endocast(to_float(ph.ct), p).ecv_ml;
    };
    const double base = ecv(0, 1.0), tilted = ecv(30, 1.0), half = ecv(0, 2.0);
    std::printf("human: ECV %.2f mL; tilted 30 deg %+.3f %%; 2 mm voxels %+.3f %%\n", base,
                100 * (tilted / base - 1), 100 * (half / base - 1));
    EXPECT_NEAR(tilted / base, 1.0, 0.005);
    EXPECT_NEAR(half / base, 1.0, 0.01);
}

TEST(PipelineAccuracy, CavityCutByTheVolumeBorderByDefault) {
    // The human phantom with its base cropped 15 mm up: the border balls (scale 0.9) eat into the
    // cavity (-14 % ECV, enclosure 0.80); the default retries with the border voxels alone.
    PhantomParams pp;
    pp.crop_base_mm = 15.0;
    const PhantomResult ph = generate_phantom(pp);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    std::printf("cropped base: ECV %+.3f %%, border seed scale %.1f\n", 100 * (r.ecv_ml / ph.true_ecv_ml - 1),
                r.border_seed_scale);
    expect_clean_genus0(r.mesh);
    EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, 0.01);
    EXPECT_EQ(r.border_seed_scale, 0.0);
    bool warned = false;
    for (const auto& w : r.warnings) warned |= w.message.find("cropped through the braincase") != std::string::npos;
    EXPECT_TRUE(warned);
    // Not cropped: no retry, the border balls keep the seed scale.
    PhantomParams whole;
    const PhantomResult ph2 = generate_phantom(whole);
    p.binarize.isovalue = ph2.suggested_iso;
    EXPECT_EQ(extract_endocast(to_float(ph2.ct), p).border_seed_scale, 0.9);
}

// ---- real scans (skipped when ../shared/data is absent)

namespace {
std::string shared(const std::string& rel) { return std::string(ENDOCAST_SHARED_DATA) + "/" + rel; }

}  // namespace

TEST(PipelineRealData, CtheadAtIso1300IsCleanAndPlausible) {
    if (!std::filesystem::exists(shared("cthead/cthead.nhdr")))
        GTEST_SKIP() << "../shared/data/cthead not found: real-data test skipped";
    const ReadResult in = read_volume({shared("cthead/cthead.nhdr")});
    ExtractParams p;
    p.binarize.isovalue = 1300;
    const ExtractionResult r = extract_endocast(in.volume, p);
    const auto t = meshpost::analyze_topology(r.mesh);
    EXPECT_TRUE(meshpost::is_closed_manifold(t));
    EXPECT_EQ(t.components, 1u);
    EXPECT_EQ(meshpost::find_self_intersections(r.mesh).intersecting_pairs, 0u);
    EXPECT_GT(r.ecv_ml, 1200);
    EXPECT_LT(r.ecv_ml, 1700);
    // Geometry: 1 x 1 x 2 mm, so the mesh spans world z up to ~2 * 112 mm.
    const auto bb = meshpost::bounding_box(r.mesh);
    EXPECT_GE(bb.min[2], 0.0);
    EXPECT_LE(bb.max[2], 224.0);
    EXPECT_GT(bb.max[2] - bb.min[2], 80.0);  // in mm, not slices

    // Against a reference that does not use the pipeline (tests/common/slice_reference.h): in every
    // axial slice above the foramen magnum (slices < 71; the canal starts at 76-78) whose braincase
    // section is closed by bone (2-D region >= 2000 px after a 9 x 9 closing), the endocast's
    // section lies inside that region and covers it. Measured: 48 slices, summed ratio 1.003,
    // 0.965-1.052 per slice (1.052 at slice 56, where the sella's sides are thin bone below the
    // isovalue that the reference does not see: the default --thin-bone 0.5 keeps it; 1.025 without);
    // cutting every far component as a canal (a past merge bug, ECV -2.4 %) gives a summed ratio of 0.98.
    const auto slices = test_reference::compare_slices(in.volume, r.mask, 0, 71, 1300.0f, 4, 2000);
    const double ratio = test_reference::expect_slices_match(slices, 0.94, 0.95, 1.065);
    EXPECT_GE(slices.size(), 40u);
    EXPECT_NEAR(ratio, 1.0, 0.01);
    std::printf("cthead: %zu closed slices, endocast / enclosed-by-bone area %.4f\n", slices.size(), ratio);
}

namespace {

// Area-weighted mean and max |distance| (mm) of the mesh's vertices to the phantom's true inner
// surface, leaving out vertices within `margin` mm of an opening (whose cap is a cut, not bone).
struct SurfaceError {
    double mean = 0, max = 0, excluded_fraction = 0;
};

SurfaceError surface_error(const meshpost::TriangleMesh& m, const PhantomResult& ph, double margin) {
    const std::vector<double> w = endocast::testing::vertex_areas(m);
    SurfaceError e;
    double sum = 0, wsum = 0, all = 0;
    for (size_t v = 0; v < m.vertices.size(); ++v) {
        all += w[v];
        const Vec3 p{m.vertices[v][0], m.vertices[v][1], m.vertices[v][2]};
        if (phantom_near_opening(ph, p, margin)) continue;
        const double d = std::fabs(phantom_cavity_signed_distance(ph, p));
        sum += w[v] * d;
        wsum += w[v];
        e.max = std::max(e.max, d);
    }
    e.mean = wsum > 0 ? sum / wsum : 0;
    e.excluded_fraction = all > 0 ? 1 - wsum / all : 0;
    return e;
}

}  // namespace

TEST(PipelineAccuracy, SurfaceWithinATenthOfAMillimetreAwayFromForamina) {
    // Human presets with spine, sinus, orbits and tilt (1 mm voxels, noise and blur on).
    // The same bars for both surfaces (--surface iso and half-max).
    for (const SurfaceMode surface : {SurfaceMode::Iso, SurfaceMode::HalfMax})
    for (const double tilt : {0.0, 30.0}) {
        PhantomParams pp = human_full_phantom_params();
        pp.tilt_deg = tilt;
        const PhantomResult ph = generate_phantom(pp);
        ExtractParams p;
        p.binarize.isovalue = ph.suggested_iso;
        p.surface = surface;
        const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
        const SurfaceError e = surface_error(r.mesh, ph, 3.0);
        std::printf("human-full tilt %.0f, %s: ECV %+.3f %%, mean surface distance %.4f mm, max %.3f mm "
                    "(%.2f %% of the area near openings left out)\n",
                    tilt, to_string(surface), 100 * (r.ecv_ml / ph.true_ecv_ml - 1), e.mean, e.max,
                    100 * e.excluded_fraction);
        SCOPED_TRACE(to_string(surface));
        EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, 0.003);
        EXPECT_LE(e.mean, 0.10);
        // The true cavity is a sphere-like closed surface: genus 0. Tilted 30 deg, the wall flaring
        // around the left optic canal left a ring of endocast around it (genus 1) until the cut
        // took the collar too (cut_collar, only where a handle is found next to an opening).
        SCOPED_TRACE("tilt " + std::to_string(tilt));
        expect_clean_genus0(r.mesh);
        // The 3 mm margins around the phantom's 9 openings (foramen magnum, 5 small foramina, the
        // crack, two optic canals) cover ~5 % of the surface; far more would hide a failure.
        EXPECT_LT(e.excluded_fraction, 0.08);

        // Nothing more than 2 mm past the foramen magnum: no vertex inside the opening (within its
        // radius of its axis, which points out of the cavity into the spinal canal) lies farther
        // than 2 mm beyond the foramen's plane on the inner skull surface. Printed too: the same
        // with the hole's bony wall included (radius + 2 mm), where the surface follows the wall
        // down to the cut.
        const Vec3 c = ph.foramen_magnum_world, n = ph.foramen_magnum_axis;
        double past_hole = -1e9, past_wall = -1e9;
        for (const auto& v : r.mesh.vertices) {
            const Vec3 d{v[0] - c[0], v[1] - c[1], v[2] - c[2]};
            const double along = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
            const double radial = std::sqrt(std::max(0.0, d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along));
            if (radial <= ph.foramen_magnum_radius_mm) past_hole = std::max(past_hole, along);
            if (radial <= ph.foramen_magnum_radius_mm + 2.0) past_wall = std::max(past_wall, along);
        }
        std::printf("human-full tilt %.0f, %s: deepest vertex past the foramen magnum's plane %.3f mm "
                    "inside the opening, %.3f mm with its wall\n", tilt, to_string(surface), past_hole, past_wall);
        EXPECT_LE(past_hole, 2.0);
        EXPECT_LE(past_wall, 2.5);
    }
}

