// `endocast series` and `endocast extract` on a study folder (tests/common/dicom_study.h) made
// from a small phantom: a localizer, a 5 mm series, two 1 mm series, a dose report, a licence.
#include <gtest/gtest.h>

#include <sstream>

#include "../common/dicom_study.h"
#include "cli_helpers.h"

using namespace cli_test;
using endocast::testing::DicomStudyLayout;

namespace {

/// The study, written once per process.
const fs::path& study() {
    static const fs::path d = [] {
        const fs::path s = temp_dir("study") / "STUDY";
        endocast::testing::write_phantom_dicom_study(s.string());
        return s;
    }();
    return d;
}

/// The line of `table` that holds `uid`.
std::string line_of(const std::string& table, const std::string& uid) {
    std::istringstream in(table);
    for (std::string l; std::getline(in, l);)
        if (l.find(uid) != std::string::npos) return l;
    return "";
}

}  // namespace

TEST(CliDicomSeries, ListsTheSeriesAndMarksThePick) {
    CliRun r = run("series " + study().string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("5 DICOM series"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("1 skipped"), std::string::npos) << r.output;  // LICENSE.txt
    EXPECT_EQ(line_of(r.output, DicomStudyLayout::kThinA).rfind("*", 0), 0u) << r.output;
    for (const char* uid : {DicomStudyLayout::kLocalizer, DicomStudyLayout::kThick, DicomStudyLayout::kThinB,
                            DicomStudyLayout::kDose})
        EXPECT_EQ(line_of(r.output, uid).rfind(" ", 0), 0u) << uid << "\n" << r.output;
    EXPECT_NE(line_of(r.output, DicomStudyLayout::kLocalizer).find("no: localizer"), std::string::npos) << r.output;
    EXPECT_NE(line_of(r.output, DicomStudyLayout::kDose).find("no: Secondary Capture"), std::string::npos) << r.output;
    EXPECT_NE(line_of(r.output, DicomStudyLayout::kThinB).find("H70h"), std::string::npos) << r.output;
    EXPECT_NE(line_of(r.output, DicomStudyLayout::kThick).find("5 mm"), std::string::npos) << r.output;

    r = run_shell(std::string(ENDOCAST_CLI) + " series " + study().string() + " --json");
    ASSERT_EQ(r.status, 0) << r.output;
    const nlohmann::json j = nlohmann::json::parse(r.output);
    EXPECT_EQ(j["chosen_series_uid"], DicomStudyLayout::kThinA);
    EXPECT_TRUE(j["choice_warning"].get<std::string>().find(DicomStudyLayout::kThinB) != std::string::npos);
    ASSERT_EQ(j["series"].size(), 5u);
    const bool volume[5] = {false, true, true, true, false};
    for (size_t i = 0; i < 5; ++i) {
        EXPECT_EQ(j["series"][i]["is_volume"], volume[i]) << i;
        EXPECT_EQ(j["series"][i]["chosen"], i == 2) << i;
    }
    EXPECT_EQ(j["series"][2]["slices"], j["series"][2]["files"].size());
    EXPECT_EQ(j["series"][2]["kernel"], "H30s");

    // A choice is previewed; one that matches nothing is an invalid parameter (4).
    r = run("series " + study().string() + " --series-description h70h");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(line_of(r.output, DicomStudyLayout::kThinB).rfind("*", 0), 0u) << r.output;
    r = run("series " + study().string() + " --series-description 'Head 1.0'");
    EXPECT_EQ(r.status, 4) << r.output;
    EXPECT_NE(r.output.find("matches 2 DICOM series"), std::string::npos) << r.output;
    // Nothing DICOM: unreadable input (3).
    const fs::path empty = temp_dir("series_empty");
    r = run("series " + empty.string());
    EXPECT_EQ(r.status, 3) << r.output;
    EXPECT_NE(r.output.find("no DICOM series"), std::string::npos) << r.output;
}

TEST(CliDicomSeries, ExtractReadsTheThinVolumeAndNamesTheOthers) {
    const fs::path out = temp_dir("series_extract");
    const CliRun r = run("extract " + study().string() + " -o " + (out / "out.ply").string() + " --report " +
                         (out / "r.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    // The choice warning on stderr like the others ...
    EXPECT_NE(r.output.find("warning: " + study().string() + ": holds 5 DICOM series"), std::string::npos)
        << r.output;
    const nlohmann::json j = read_json(out / "r.json");
    const auto& in = j["input"];
    EXPECT_EQ(in["format"], "dicom");
    EXPECT_EQ(in["series_uid"], DicomStudyLayout::kThinA);
    EXPECT_EQ(in["files_read"], 78);
    EXPECT_EQ(in["dims"], nlohmann::json({82, 98, 78}));
    ASSERT_EQ(in["series_found"].size(), 5u);
    for (const auto& s : in["series_found"]) {
        EXPECT_EQ(s["chosen"], s["series_uid"] == DicomStudyLayout::kThinA);
        EXPECT_FALSE(s.contains("files"));
    }
    // ... and in the report, naming every other series.
    ASSERT_GE(j["warnings"].size(), 1u);
    const std::string w = j["warnings"][0];
    for (const char* uid : {DicomStudyLayout::kLocalizer, DicomStudyLayout::kThick, DicomStudyLayout::kThinB,
                            DicomStudyLayout::kDose})
        EXPECT_NE(w.find(uid), std::string::npos) << uid << " in " << w;
    EXPECT_GT(j["ecv_ml"].get<double>(), 50.0);
    EXPECT_TRUE(fs::exists(out / "out.ply"));

    // --series-description picks the other kernel.
    const CliRun b = run("extract " + study().string() + " --series-description H70h --report " +
                         (out / "b.json").string() + " -q");
    ASSERT_EQ(b.status, 0) << b.output;
    EXPECT_EQ(read_json(out / "b.json")["input"]["series_uid"], DicomStudyLayout::kThinB);
    EXPECT_EQ(b.output.find("holds 5 DICOM series"), std::string::npos) << b.output;  // chosen: no warning
    // A description that matches nothing: exit 4, naming the value and the series there are.
    const CliRun c = run("extract " + study().string() + " --series-description sagittal -o " +
                         (out / "c.ply").string());
    EXPECT_EQ(c.status, 4) << c.output;
    EXPECT_NE(c.output.find("'sagittal'"), std::string::npos) << c.output;
    EXPECT_NE(c.output.find(DicomStudyLayout::kThinA), std::string::npos) << c.output;
    EXPECT_FALSE(fs::exists(out / "c.ply"));
}

// The binary does not link GDCM, whose libraries build its DICOM dictionaries as they load (about
// 45 ms of every start): it loads libendocast_gdcm.so on its first DICOM input (io/gdcm_api.h).
TEST(CliDicomModule, TheBinaryLinksNoGdcm) {
    const CliRun r = run_shell("ldd " + std::string(ENDOCAST_CLI) + " 2>&1");
    if (r.status != 0) GTEST_SKIP() << "ldd did not run: " << r.output;
    ASSERT_NE(r.output.find("libITKCommon"), std::string::npos) << r.output;  // a real listing
    EXPECT_EQ(r.output.find("gdcm"), std::string::npos) << r.output;
}

TEST(CliDicomModule, WithoutTheModuleDicomIsAClearErrorAndVolumeFilesStillRead) {
    const std::string missing = "/nonexistent/libendocast_gdcm.so";
    const std::string env = "ENDOCAST_GDCM_MODULE=" + missing + " ";
    const fs::path out = temp_dir("nomodule");
    CliRun r = run_shell(env + ENDOCAST_CLI + " extract " + study().string() + " -o " + (out / "d.ply").string() +
                         " -q 2>&1");
    EXPECT_EQ(r.status, 3) << r.output;
    EXPECT_NE(r.output.find(missing), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("ENDOCAST_GDCM_MODULE"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "d.ply"));
    r = run_shell(env + ENDOCAST_CLI + " series " + study().string() + " 2>&1");
    EXPECT_EQ(r.status, 3) << r.output;
    EXPECT_NE(r.output.find(missing), std::string::npos) << r.output;

    // Nor does an empty folder: it holds no DICOM series, which is the error.
    fs::create_directories(out / "empty");
    r = run_shell(env + ENDOCAST_CLI + " series " + (out / "empty").string() + " 2>&1");
    EXPECT_EQ(r.status, 3) << r.output;
    EXPECT_NE(r.output.find("holds no DICOM series"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find(missing), std::string::npos) << r.output;

    // A volume file needs no module.
    r = run("phantom " + (out / "mq.nrrd").string() + " --preset macaque --spacing 2 2 2 -q");
    ASSERT_EQ(r.status, 0) << r.output;
    r = run_shell(env + ENDOCAST_CLI + " extract " + (out / "mq.nrrd").string() + " -o " + (out / "mq.ply").string() +
                  " -q 2>&1");
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_TRUE(fs::exists(out / "mq.ply"));
}
