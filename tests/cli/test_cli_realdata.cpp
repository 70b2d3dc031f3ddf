// The real scans of ../shared/data through the CLI; skipped with a message when absent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "../common/slice_reference.h"
#include "cli_helpers.h"
#include "endocast/io.h"
#include "meshpost/io.h"

using namespace cli_test;

#define REQUIRE_SHARED(rel)                                                                 \
    if (!fs::exists(shared(rel)))                                                          \
    GTEST_SKIP() << "../shared/data/" << rel << " not found: real-data test skipped"

namespace {

// The cthead endocast ends at the foramen magnum (the canal starts at slices 76-78; 2 mm slices):
// no vertex more than 4 mm below slice 78.
void expect_ends_at_foramen_magnum(const fs::path& mesh_path) {
    const auto mesh = meshpost::read_mesh(mesh_path.string());
    double zmax = 0;
    for (const auto& v : mesh.vertices) zmax = std::max(zmax, v[2]);
    EXPECT_LT(zmax, 78 * 2.0 + 4.0);
}

}  // namespace

TEST(CliRealData, CtheadNrrdAtIso1300) {
    REQUIRE_SHARED("cthead/cthead.nhdr");
    const fs::path out = temp_dir("cthead");
    const CliRun r = run("extract " + shared("cthead/cthead.nhdr") + " --iso 1300 --check-all-faces -o " +
                      (out / "c.stl").string() + " --report " + (out / "c.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "c.json");
    EXPECT_EQ(j["input"]["dims"], (nlohmann::json{256, 256, 113}));
    EXPECT_EQ(j["input"]["spacing"], (nlohmann::json{1.0, 1.0, 2.0}));
    EXPECT_EQ(j["input"]["voxel_type"], "uint16");
    EXPECT_EQ(j["ct_storage"], "int16");  // uint16 values up to 4095
    EXPECT_TRUE(j["closed_manifold"].get<bool>());
    // Every pair of faces tested (by default only the faces moved after marching cubes).
    EXPECT_EQ(j["self_intersection_check"]["faces"], "all");
    EXPECT_EQ(j["self_intersection_check"]["faces_tested"], j["faces"]);
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    EXPECT_EQ(j["components"].get<int>(), 1);
    EXPECT_GT(j["ecv_ml"].get<double>(), 1200);
    EXPECT_LT(j["ecv_ml"].get<double>(), 1700);
    EXPECT_TRUE(fs::exists(out / "c.stl"));
    // Without closing openings it runs down to slice ~110.
    expect_ends_at_foramen_magnum(out / "c.stl");
}

TEST(CliRealData, CtheadHalfMaxSurfaceIsCleanAndEndsAtTheForamenMagnum) {
    REQUIRE_SHARED("cthead/cthead.nhdr");
    const fs::path out = temp_dir("cthead_hmh");
    const CliRun r = run("extract " + shared("cthead/cthead.nhdr") + " --iso 1300 --surface half-max -q -o " +
                         (out / "c.stl").string() + " --report " + (out / "c.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "c.json");
    EXPECT_EQ(j["parameters"]["surface"], "half-max");
    EXPECT_EQ(j["ct_storage"], "float32");  // the half-max field is built from a float CT
    EXPECT_TRUE(j["closed_manifold"].get<bool>());
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    EXPECT_EQ(j["components"].get<int>(), 1);
    // Voxels change side only where the surface keeps its topology at T (without that: genus 61).
    EXPECT_EQ(j["genus"].get<int>(), 0);
    // Measured 1497 mL (iso: 1429 mL; the brain-bone edge's half-way level, ~1550, lies above 1300).
    EXPECT_GT(j["ecv_ml"].get<double>(), 1400);
    EXPECT_LT(j["ecv_ml"].get<double>(), 1600);
    const auto& h = j["half_max"];
    EXPECT_NEAR(h["cavity_level"].get<double>(), 1080, 40);  // the brain
    EXPECT_GT(h["threshold_median"].get<double>(), 1300);
    EXPECT_LT(h["threshold_median"].get<double>(), 2000);
    EXPECT_LE(h["threshold_min"].get<double>(), h["threshold_median"].get<double>());
    EXPECT_GE(h["threshold_max"].get<double>(), h["threshold_median"].get<double>());
    EXPECT_GT(h["voxels_added"].get<int64_t>(), 0);
    expect_ends_at_foramen_magnum(out / "c.stl");
}

TEST(CliRealData, CtheadAsBigEndianSliceFilesGivesTheSameResult) {
    REQUIRE_SHARED("cthead/cthead.nhdr");
    // Re-create the original distribution: CThead.1 .. CThead.113, 256x256 big-endian uint16.
    const fs::path out = temp_dir("cthead_slices");
    const auto v = endocast::read_volume({shared("cthead/cthead.nhdr")}).volume;
    for (int64_t z = 0; z < v.nz(); ++z) {
        std::ofstream f(out / ("CThead." + std::to_string(z + 1)), std::ios::binary);
        for (int64_t y = 0; y < v.ny(); ++y)
            for (int64_t x = 0; x < v.nx(); ++x) {
                const auto u = static_cast<uint16_t>(v(x, y, z));
                const char b[2] = {char(u >> 8), char(u & 0xff)};
                f.write(b, 2);
            }
    }
    const std::string pattern = "'" + (out / "CThead.*").string() + "'";
    CliRun r = run("extract " + pattern + " --raw-size 256 256 113 --raw-type uint16 --raw-endian big "
                "--spacing 1 1 2 --iso 1300 -q --report " + (out / "raw.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    r = run("extract " + shared("cthead/cthead.nhdr") + " --iso 1300 -q --report " + (out / "nrrd.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto a = read_json(out / "raw.json"), b = read_json(out / "nrrd.json");
    EXPECT_EQ(a["input"]["format"], "raw");
    EXPECT_EQ(a["input"]["files_read"].get<int>(), 113);
    EXPECT_EQ(a["ecv_ml"], b["ecv_ml"]);
    EXPECT_EQ(a["faces"], b["faces"]);
}

// Issue 15: a living head with gantry tilt (+18.5 deg) and two stacks (4 mm, then 7 mm slices).
// It was refused ("slices are missing"); now it is resampled onto a regular grid in patient
// coordinates, with a warning, and the mesh lies inside that grid (SliceStackRealData checks
// where the grid puts the bone against each slice placed on its own).
TEST(CliRealData, GeTiltDicomIsResampledWithAWarning) {
    REQUIRE_SHARED("ge-tilt-dicom");
    const fs::path out = temp_dir("getilt");
    const CliRun r = run("extract " + shared("ge-tilt-dicom") + " --iso 300 -o " + (out / "g.ply").string() +
                         " --report " + (out / "g.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("gantry tilt 18.5 deg"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("uneven slice spacing"), std::string::npos) << r.output;
    const auto j = read_json(out / "g.json");
    EXPECT_NEAR(j["input"]["gantry_tilt_deg"].get<double>(), 18.5, 0.05);
    EXPECT_TRUE(j["input"]["resampled"].get<bool>());
    EXPECT_EQ(j["input"]["slice_runs"].size(), 3u);
    EXPECT_EQ(j["input"]["files_read"], 28);
    EXPECT_NEAR(j["input"]["spacing"][2].get<double>(), 4.0, 0.01);  // the 4 mm stack's step
    EXPECT_NEAR(j["input"]["direction"][8].get<double>(), std::cos(18.5 * M_PI / 180), 1e-4);  // axis along the normal
    bool warned = false;
    for (const auto& w : j["warnings"]) warned |= w.get<std::string>().find("gantry tilt") != std::string::npos;
    EXPECT_TRUE(warned);
    EXPECT_TRUE(j["closed_manifold"].get<bool>());
    EXPECT_EQ(j["genus"].get<int>(), 0);
    // The braincase, cut by the tilted slab's lower face (a lower bound of the ECV).
    EXPECT_GT(j["ecv_ml"].get<double>(), 1100);
    EXPECT_LT(j["ecv_ml"].get<double>(), 1700);
}

TEST(CliRealData, HeadphantomDicomAtIso250) {
    REQUIRE_SHARED("headphantom-dicom");
    const fs::path out = temp_dir("headphantom");
    const CliRun r = run("extract " + shared("headphantom-dicom") + " --iso 250 -o " + (out / "h.ply").string() +
                      " --report " + (out / "h.json").string() + " --mask " + (out / "h_mask.nrrd").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "h.json");
    EXPECT_EQ(j["input"]["format"], "dicom");
    EXPECT_EQ(j["input"]["dims"], (nlohmann::json{512, 512, 209}));
    EXPECT_NEAR(j["input"]["spacing"][0].get<double>(), 0.9765625, 1e-6);
    EXPECT_NEAR(j["input"]["spacing"][2].get<double>(), 2.0, 1e-6);
    EXPECT_TRUE(j["closed_manifold"].get<bool>());
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    EXPECT_TRUE(fs::exists(out / "h.ply"));
    // The braincase is chosen, not the air between couch and neck (the paper's rule takes that).
    const double ecv = j["ecv_ml"].get<double>();
    EXPECT_GT(ecv, 1000);
    EXPECT_LT(ecv, 1800);
    EXPECT_GT(j["enclosure"].get<double>(), 0.9);
    // Its seed lies in the head: within 150 mm of the top slice (chest-to-vertex field of view).
    const double top = j["input"]["origin"][2].get<double>() + 208 * 2.0;
    EXPECT_GT(j["seed_points_mm"][0][2].get<double>(), top - 150.0);

    // Against a reference that does not use the pipeline (tests/common/slice_reference.h): in every
    // axial slice whose braincase section is closed by bone (2-D region >= 2000 px after a 9 x 9
    // closing), the endocast's section lies inside that region and covers it. Measured: 62 slices
    // (z 120-189), summed ratio 1.003, 0.86-1.08 per slice (the larger gaps near the skull base;
    // 0.86 in slice 120, the lowest, at the foramen magnum: with thin bone, the default since issue
    // 18, the plane closing it lies a slice higher there; 0.91 without).
    const endocast::Volume<float> ct = endocast::read_volume({shared("headphantom-dicom")}).volume;
    const endocast::Volume<float> m = endocast::read_volume({(out / "h_mask.nrrd").string()}).volume;
    ASSERT_EQ(m.dims(), ct.dims());
    endocast::Volume<uint8_t> mask(m.geometry());
    for (size_t i = 0; i < m.size(); ++i) mask[i] = m[i] > 0.5f;
    const auto slices = test_reference::compare_slices(ct, mask, 0, ct.dims()[2], 250.0f, 4, 2000);
    const double ratio = test_reference::expect_slices_match(slices, 0.90, 0.85, 1.10);
    EXPECT_GE(slices.size(), 50u);
    EXPECT_NEAR(ratio, 1.0, 0.01);
    std::printf("headphantom: %zu closed slices, endocast / enclosed-by-bone area %.4f\n", slices.size(), ratio);
}

// The dry skull without --iso: the automatic rule takes Otsu's threshold between air and the rest
// (no soft tissue), far too low for its thin bone of 600-800 HU, and the bone contact comes out
// low. The warning names the bone's own threshold to try; with it, the contact is above the
// minimum and the volume that of the braincase (1,300 mL at the hand-picked iso 350, docs/accuracy.md).
TEST(CliRealData, DrySkullWithoutIsoWarnsWhichIsovalueToTry) {
    REQUIRE_SHARED("dryskull-phantom-dicom");
    const fs::path out = temp_dir("dryskull_auto");
    const CliRun r = run("extract " + shared("dryskull-phantom-dicom") + " -o " + (out / "d.ply").string() +
                         " --report " + (out / "d.json").string());
    // The plastic inserts divide the cavity at the automatic isovalue: the part chosen is either
    // kept, warned (a low bone contact), or refused as not enclosed by bone (exit 5, once its
    // canals are cut); either way the warning names the isovalue to try.
    ASSERT_TRUE(r.status == 0 || r.status == 5) << r.output;
    if (r.status == 0) {
        const auto j = read_json(out / "d.json");
        EXPECT_EQ(j["isovalue_rule"], "otsu-air-bone");
        EXPECT_LT(j["bone_contact"].get<double>(), 0.85);
    }
    EXPECT_NE(r.output.find("-313.5 was chosen automatically"), std::string::npos) << r.output;
    const std::string key = "(try --iso ";
    const size_t at = r.output.find(key);
    ASSERT_NE(at, std::string::npos) << r.output;
    const double suggested = std::stod(r.output.substr(at + key.size()));
    EXPECT_GT(suggested, -313.5);
    const CliRun again = run("extract " + shared("dryskull-phantom-dicom") + " --iso " + std::to_string(suggested) +
                             " -q -o " + (out / "d2.ply").string() + " --report " + (out / "d2.json").string());
    ASSERT_EQ(again.status, 0) << again.output;
    const auto j2 = read_json(out / "d2.json");
    EXPECT_GE(j2["bone_contact"].get<double>(), 0.85);
    EXPECT_GT(j2["ecv_ml"].get<double>(), 1200);
    EXPECT_LT(j2["ecv_ml"].get<double>(), 1400);
    EXPECT_TRUE(j2["closed_manifold"].get<bool>());
}
