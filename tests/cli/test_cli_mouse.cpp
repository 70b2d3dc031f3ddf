// Real mouse microCT (../shared/data/mouse-microct): `endocast batch` over the 20 shared scans at
// the automatic isovalue, scored against the expert label carried onto each scan by landmarks
// (tests/mouse/mouse_truth.h), and the template against its own label.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "cli_helpers.h"
#include "endocast/io.h"
#include "endocast/pipeline.h"
#include "mouse_truth.h"

using namespace cli_test;

namespace {

const std::string kMouse = "mouse-microct";

#define REQUIRE_MOUSE()                                                                   \
    if (!fs::exists(shared(kMouse + "/scans")))                                           \
    GTEST_SKIP() << "../shared/data/" << kMouse << " not found: real-data test skipped"

std::vector<std::string> scan_names() {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(shared(kMouse + "/scans"))) {
        const std::string f = e.path().filename().string();
        if (f.size() > 7 && f.substr(f.size() - 7) == ".nii.gz") names.push_back(f.substr(0, f.size() - 7));
    }
    std::sort(names.begin(), names.end());
    return names;
}

mouse_truth::Carried truth_of(const mouse_truth::Template& tpl, const std::string& name, const endocast::Geometry& grid) {
    static const auto frames = mouse_truth::read_frames(std::string(ENDOCAST_SOURCE_DIR) + "/tests/mouse/landmark_frames.json");
    return mouse_truth::carry(tpl, grid,
                              mouse_truth::scan_landmarks(shared(kMouse + "/landmarks/" + name + ".mrk.json"), name, frames));
}

endocast::Volume<uint8_t> read_mask(const fs::path& p) {
    const endocast::Volume<float> f = endocast::read_volume({p.string()}).volume;
    endocast::Volume<uint8_t> m(f.geometry(), 0);
    for (size_t i = 0; i < f.size(); ++i) m[i] = f[i] != 0.f;
    return m;
}

}  // namespace

TEST(MouseMicroCT, LandmarksLieOnTheScansBoneInTheirFrames) {
    // Every landmark file, mapped by landmark_frames.json where it lists the scan, lies on its
    // scan's bone: the median CT at the landmarks is above the 90th percentile of the head's
    // voxels (bone is the brightest tenth); the five files of another frame do not without it.
    REQUIRE_MOUSE();
    const auto frames = mouse_truth::read_frames(std::string(ENDOCAST_SOURCE_DIR) + "/tests/mouse/landmark_frames.json");
    EXPECT_EQ(frames.size(), 5u);
    for (const std::string& name : scan_names()) {
        const endocast::Volume<float> ct = endocast::read_volume({shared(kMouse + "/scans/" + name + ".nii.gz")}).volume;
        std::vector<float> head;
        for (size_t i = 0; i < ct.size(); i += 7)
            if (ct[i] > 0) head.push_back(ct[i]);
        std::nth_element(head.begin(), head.begin() + std::ptrdiff_t(head.size() * 9 / 10), head.end());
        const double p90 = head[head.size() * 9 / 10];
        auto median_at = [&](const std::map<int, endocast::Vec3>& lm) {
            std::vector<double> v;
            for (const auto& [k, p] : lm) {
                const endocast::Vec3 q = ct.geometry().world_to_index(p);
                const int64_t x = std::llround(q[0]), y = std::llround(q[1]), z = std::llround(q[2]);
                double best = 0;  // the brightest voxel next to the landmark (it sits on the surface)
                for (int64_t c = z - 1; c <= z + 1; ++c)
                    for (int64_t b = y - 1; b <= y + 1; ++b)
                        for (int64_t a = x - 1; a <= x + 1; ++a)
                            if (ct.contains(a, b, c)) best = std::max(best, double(ct(a, b, c)));
                v.push_back(best);
            }
            std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
            return v[v.size() / 2];
        };
        const std::string file = shared(kMouse + "/landmarks/" + name + ".mrk.json");
        EXPECT_GT(median_at(mouse_truth::scan_landmarks(file, name, frames)), p90) << name;
        if (frames.count(name)) EXPECT_LT(median_at(mouse_truth::read_markups(file)), p90) << name << " needs no frame?";
    }
}

TEST(MouseMicroCT, TemplateCarriedOntoItselfIsItsLabel) {
    // The spline through identical landmarks is the identity: the carried label is the label.
    REQUIRE_MOUSE();
    const auto tpl = mouse_truth::load_template(shared(kMouse + "/template"));
    EXPECT_NEAR(tpl.label_mm3, 458.53, 0.01);
    const mouse_truth::Carried c = mouse_truth::carry(tpl, tpl.labels.geometry(), tpl.landmarks);
    size_t differ = 0;
    for (size_t i = 0; i < c.label.size(); ++i) differ += (c.label[i] != 0) != (tpl.labels[i] == 15.f);
    EXPECT_EQ(differ, 0u);
}

TEST(MouseMicroCT, BatchOverTheSharedScansMeetsTheExpertLabel) {
    // Issue 55's bars on every shared scan at the automatic isovalue: Dice >= 0.92 (median >= 0.94),
    // |ECV - label| <= 7 %, < 2 % of the label's volume in the nasal cavity, the surface within
    // 3 mm of the foramen magnum's plane, bone contact >= 0.85 and no warning.
    REQUIRE_MOUSE();
    const fs::path out = temp_dir("mouse_batch");
    const CliRun r = run("batch " + shared(kMouse + "/scans") + "/*.nii.gz -o " + (out / "res").string() + " --masks -j 2");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto tpl = mouse_truth::load_template(shared(kMouse + "/template"));
    std::vector<double> dice;
    for (const std::string& name : scan_names()) {
        const fs::path dir = out / "res" / name;
        const auto rep = read_json(dir / "report.json");
        const endocast::Volume<uint8_t> mask = read_mask(dir / "mask.nii.gz");
        const mouse_truth::Scores s =
            mouse_truth::score(tpl, truth_of(tpl, name, mask.geometry()), mask, rep["ecv_ml"].get<double>());
        std::printf("%-12s iso %5.1f  Dice %.3f  ECV %+5.1f %%  nasal %.2f %%  past FM %5.2f mm  contact %.3f  leak %.3f\n",
                    name.c_str(), rep["isovalue"].get<double>(), s.dice, 100 * s.ecv_error, 100 * s.nasal_share,
                    s.fm_reach_mm, rep["bone_contact"].get<double>(), rep["leak_share"].get<double>());
        dice.push_back(s.dice);
        EXPECT_GE(s.dice, 0.92) << name;
        EXPECT_LE(std::abs(s.ecv_error), 0.07) << name;
        EXPECT_LT(s.nasal_share, 0.02) << name;
        EXPECT_LE(s.fm_reach_mm, 3.0) << name;
        EXPECT_EQ(rep["isovalue_rule"], "otsu-tissue-near-air") << name;
        EXPECT_GE(rep["bone_contact"].get<double>(), 0.85) << name;
        EXPECT_TRUE(rep["warnings"].empty()) << name << ": " << rep["warnings"].dump();
        EXPECT_TRUE(rep["closed_manifold"].get<bool>()) << name;
    }
    ASSERT_EQ(dice.size(), 20u);
    std::nth_element(dice.begin(), dice.begin() + 10, dice.end());
    EXPECT_GE(dice[10], 0.94);
}

TEST(MouseMicroCT, TemplateAgainstItsExpertLabel) {
    // The strain-average template with its own label: ECV within 3 %, Dice >= 0.96.
    REQUIRE_MOUSE();
    const fs::path out = temp_dir("mouse_template");
    const CliRun r = run("extract " + shared(kMouse + "/template/low_res_template_UCHAR.nii.gz") + " -q -o " +
                         (out / "t.ply").string() + " --mask " + (out / "t.nii.gz").string() + " --report " +
                         (out / "t.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto tpl = mouse_truth::load_template(shared(kMouse + "/template"));
    const endocast::Volume<uint8_t> mask = read_mask(out / "t.nii.gz");
    const auto rep = read_json(out / "t.json");
    const mouse_truth::Scores s = mouse_truth::score(
        tpl, mouse_truth::carry(tpl, mask.geometry(), tpl.landmarks), mask, rep["ecv_ml"].get<double>());
    std::printf("template: ECV %+.2f %%, Dice %.4f, contact %.3f\n", 100 * s.ecv_error, s.dice, rep["bone_contact"].get<double>());
    EXPECT_LE(std::abs(s.ecv_error), 0.03);
    EXPECT_GE(s.dice, 0.96);
    EXPECT_TRUE(rep["warnings"].empty()) << rep["warnings"].dump();
}

TEST(MouseMicroCT, ALeakThroughThinBoneIsFlagged) {
    // At a high isovalue the thin ethmoid bone vanishes and the surface leaks into the nasal
    // cavity (the old automatic rule's second mode, 85-98): bone contact and the leak share warn.
    REQUIRE_MOUSE();
    const fs::path out = temp_dir("mouse_leak");
    for (const std::string name : {"129X1_SVJ_", "PL.J_"}) {
        const CliRun r = run("extract " + shared(kMouse + "/scans/" + name + ".nii.gz") + " --iso 90 -q -o " +
                             (out / (name + ".ply")).string() + " --report " + (out / (name + ".json")).string());
        ASSERT_EQ(r.status, 0) << r.output;
        const auto rep = read_json(out / (name + ".json"));
        EXPECT_LT(rep["bone_contact"].get<double>(), 0.85) << name;
        EXPECT_GT(rep["leak_share"].get<double>(), 0.14) << name;
        const std::string w = rep["warnings"].dump();
        EXPECT_NE(w.find("bone contact"), std::string::npos) << name;
        EXPECT_NE(w.find("possible leak"), std::string::npos) << name;
    }
}

TEST(MouseMicroCT, AtlasSkullAtTwoResolutionsAgainstItsLabel) {
    // The atlas' expert skull at 35 um made into a CT (mouse_truth::atlas_ct), block-averaged to
    // 70 um and to 141 um, extracted at the automatic isovalue and scored against the expert's own
    // endocranial label: the same anatomy at two scales of the grid.
    REQUIRE_MOUSE();
    const std::string path = shared(kMouse + "/template/35_mic_23strain_mus_template_UCHAR-label.nii.gz");
    if (!fs::exists(path)) GTEST_SKIP() << path << " not found";
    const endocast::Volume<float> labels = endocast::read_volume({path}).volume;
    for (const int factor : {2, 4}) {
        SCOPED_TRACE("block of " + std::to_string(factor));
        const mouse_truth::AtlasCt a = mouse_truth::atlas_ct(labels, factor);
        const endocast::ExtractionResult r = endocast::extract_endocast(a.ct, endocast::ExtractParams{});
        const double d = mouse_truth::dice(r.mask, a.label), err = 1000 * r.ecv_ml / a.label_mm3 - 1;
        std::printf("atlas skull at %.0f um: Dice %.4f, ECV %+.2f %% (label %.1f mm^3), contact %.3f, leak %.3f\n",
                    1000 * a.ct.geometry().spacing[0], d, 100 * err, a.label_mm3, r.bone_contact, r.leak_share);
        EXPECT_GE(d, 0.97);
        EXPECT_LE(std::abs(err), 0.06);
        EXPECT_GE(r.bone_contact, 0.85);
        EXPECT_TRUE(r.warnings.empty());
    }
}
