// Study folders and DICOMDIRs: list_dicom_series, choose_dicom_series and read_volume on them.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include <itkGDCMSeriesFileNames.h>

#include "../common/dicom_study.h"
#include "endocast/dicom_series.h"
#include "endocast/errors.h"
#include "endocast/io.h"
#include "test_helpers.h"

namespace {

namespace fs = std::filesystem;
using namespace endocast;
using endocast::testing::DicomStudyLayout;
using endocast::testing::error_of;
using endocast::testing::ScratchDir;

std::string data_dir() { return std::string(ENDOCAST_SHARED_DATA); }

/// A 24 x 20 x 30 CT of 1 mm voxels whose value tells where it lies: x + 10 y + 300 z - 1000.
Volume<int16_t> ramp_ct() {
    Geometry g;
    g.dims = {24, 20, 30};
    g.spacing = {1, 1, 1};
    g.origin = {-12, -10, 40};
    Volume<int16_t> v(g);
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) v(x, y, z) = int16_t(x + 10 * y + 300 * z - 1000);
    return v;
}

/// The files ITK's GDCMSeriesFileNames gives for the series `uid` of `dir` (not recursive), as
/// read_dicom_dir took them before list_dicom_series.
std::vector<std::string> itk_order(const std::string& dir, const std::string& uid) {
    auto names = itk::GDCMSeriesFileNames::New();
    names->SetUseSeriesDetails(false);
    names->SetRecursive(false);
    names->SetDirectory(dir);
    return names->GetFileNames(uid);
}

const DicomSeriesInfo& find(const DicomStudy& s, const std::string& uid) {
    for (const auto& x : s.series)
        if (x.series_uid == uid) return x;
    throw std::runtime_error("no series " + uid);
}

class DicomStudyFolder : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = new ScratchDir("study");
        ct_ = new Volume<int16_t>(ramp_ct());
        layout_ = endocast::testing::write_dicom_study(dir_->str(), *ct_);
    }
    static void TearDownTestSuite() {
        delete dir_;
        delete ct_;
    }
    static ScratchDir* dir_;
    static Volume<int16_t>* ct_;
    static DicomStudyLayout layout_;
};
ScratchDir* DicomStudyFolder::dir_ = nullptr;
Volume<int16_t>* DicomStudyFolder::ct_ = nullptr;
DicomStudyLayout DicomStudyFolder::layout_;

TEST_F(DicomStudyFolder, ListsEverySeriesWithItsHeaderAndVerdict) {
    const DicomStudy s = list_dicom_series(dir_->str());
    EXPECT_EQ(s.folder, dir_->str());
    ASSERT_EQ(s.series.size(), 5u);
    EXPECT_EQ(s.files_scanned, size_t(2 + layout_.thick_slices + 2 * layout_.thin_slices + 1 + 1));
    EXPECT_EQ(s.files_skipped, 1u);  // LICENSE.txt
    // Sorted by UID.
    EXPECT_EQ(s.series[0].series_uid, DicomStudyLayout::kLocalizer);
    EXPECT_EQ(s.series[4].series_uid, DicomStudyLayout::kDose);

    const DicomSeriesInfo& loc = find(s, DicomStudyLayout::kLocalizer);
    EXPECT_FALSE(loc.is_volume);
    EXPECT_NE(loc.reason.find("localizer"), std::string::npos) << loc.reason;
    EXPECT_EQ(loc.files.size(), 2u);

    const DicomSeriesInfo& thick = find(s, DicomStudyLayout::kThick);
    EXPECT_TRUE(thick.is_volume) << thick.reason;
    EXPECT_EQ(thick.files.size(), size_t(layout_.thick_slices));
    EXPECT_DOUBLE_EQ(thick.slice_thickness_mm, 5.0);
    EXPECT_NEAR(thick.slice_step_mm, 5.0, 1e-9);

    const DicomSeriesInfo& a = find(s, DicomStudyLayout::kThinA);
    EXPECT_TRUE(a.is_volume) << a.reason;
    EXPECT_TRUE(a.reason.empty());
    EXPECT_EQ(a.description, "Head 1.0 H30s");
    EXPECT_EQ(a.modality, "CT");
    EXPECT_EQ(a.sop_class_uid, "1.2.840.10008.5.1.4.1.1.2");
    EXPECT_EQ(a.sop_class, "CT Image Storage");
    EXPECT_EQ(a.image_type, "ORIGINAL\\PRIMARY\\AXIAL");
    EXPECT_EQ(a.kernel, "H30s");
    ASSERT_TRUE(a.series_number.has_value());
    EXPECT_EQ(*a.series_number, 3);
    EXPECT_EQ(a.columns, 24);
    EXPECT_EQ(a.rows, 20);
    EXPECT_DOUBLE_EQ(a.pixel_spacing_mm[0], 1.0);
    EXPECT_DOUBLE_EQ(a.pixel_spacing_mm[1], 1.0);
    EXPECT_DOUBLE_EQ(a.slice_thickness_mm, 1.0);
    EXPECT_NEAR(a.slice_step_mm, 1.0, 1e-9);
    EXPECT_EQ(a.folders, std::vector<std::string>{(fs::path(dir_->str()) / "S1MM_H30").string()});
    ASSERT_EQ(a.files.size(), size_t(layout_.thin_slices));
    // Written backwards (IM0001 = the last slice): sorted by position, the files are reversed.
    EXPECT_EQ(fs::path(a.files.front()).filename().string(), "IM0030.dcm");
    EXPECT_EQ(fs::path(a.files.back()).filename().string(), "IM0001.dcm");
    EXPECT_EQ(find(s, DicomStudyLayout::kThinB).kernel, "H70h");

    const DicomSeriesInfo& dose = find(s, DicomStudyLayout::kDose);
    EXPECT_FALSE(dose.is_volume);
    EXPECT_EQ(dose.modality, "OT");
    EXPECT_NE(dose.reason.find("Secondary Capture"), std::string::npos) << dose.reason;
    EXPECT_NE(dose.reason.find("not CT or MR image storage"), std::string::npos) << dose.reason;
    EXPECT_EQ(dose.files.size(), 1u);
    EXPECT_FALSE(dose.series_number == std::nullopt);
}

TEST_F(DicomStudyFolder, FileOrderIsItksForEverySeries) {
    const DicomStudy s = list_dicom_series(dir_->str());
    for (const auto& series : s.series) {
        ASSERT_EQ(series.folders.size(), 1u);
        EXPECT_EQ(series.files, itk_order(series.folders[0], series.series_uid)) << series.series_uid;
    }
}

TEST_F(DicomStudyFolder, DefaultIsTheThinnestCtVolumeThenMostSlicesThenUid) {
    const DicomStudy s = list_dicom_series(dir_->str());
    const DicomSeriesPick p = choose_dicom_series(s);
    // Two 1 mm series of as many slices: the smaller UID (H30s) is read.
    EXPECT_EQ(s.series[p.index].series_uid, DicomStudyLayout::kThinA);
    // The warning names every other series and why it was not read.
    const std::string& w = p.warning;
    EXPECT_NE(w.find(dir_->str()), std::string::npos) << w;
    EXPECT_NE(w.find("holds 5 DICOM series"), std::string::npos) << w;
    EXPECT_NE(w.find(std::string(DicomStudyLayout::kLocalizer) + " (Topogram 0.6 T20s): not a volume, localizer"),
              std::string::npos) << w;
    EXPECT_NE(w.find(std::string(DicomStudyLayout::kThick) + " (Head 5.0 H30s): slices of 5 mm"), std::string::npos)
        << w;
    EXPECT_NE(w.find(std::string(DicomStudyLayout::kThinB) + " (Head 1.0 H70h): as thin, as many slices, a later UID"),
              std::string::npos) << w;
    EXPECT_NE(w.find(std::string(DicomStudyLayout::kDose) + " (Dose Report): not a volume, Secondary Capture"),
              std::string::npos) << w;
}

TEST_F(DicomStudyFolder, ReadVolumeReadsTheChosenSeriesWithAWarning) {
    const ReadResult r = read_volume({dir_->str()});
    EXPECT_EQ(r.info.format, "dicom");
    EXPECT_EQ(r.info.series_uid, DicomStudyLayout::kThinA);
    EXPECT_EQ(r.info.files_read, size_t(layout_.thin_slices));
    ASSERT_EQ(r.info.series_found.size(), 5u);
    ASSERT_EQ(r.info.warnings.size(), 1u);
    EXPECT_NE(r.info.warnings[0].find(DicomStudyLayout::kThinB), std::string::npos);
    // The CT back, voxel for voxel, in its geometry.
    const Geometry& g = r.volume.geometry();
    EXPECT_EQ(g.dims, ct_->dims());
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(g.spacing[a], 1.0, 1e-9);
        EXPECT_NEAR(g.origin[a], ct_->geometry().origin[a], 1e-9);
    }
    for (size_t i = 0; i < ct_->size(); ++i)
        ASSERT_EQ(r.volume[i], float((*ct_)[i])) << "voxel " << i;
    // The same bytes as the series' own folder read alone (one series: no warning).
    const ReadResult alone = read_volume({*dir_ / "S1MM_H30"});
    EXPECT_TRUE(alone.info.warnings.empty());
    ASSERT_EQ(alone.volume.size(), r.volume.size());
    EXPECT_EQ(std::memcmp(alone.volume.data(), r.volume.data(), r.volume.size() * sizeof(float)), 0);
    EXPECT_EQ(alone.volume.geometry().origin, g.origin);
}

TEST_F(DicomStudyFolder, ChoiceByUidOrDescription) {
    ReadOptions o;
    o.series_description = "h70H";  // part of it, any case
    ReadResult r = read_volume({dir_->str()}, o);
    EXPECT_EQ(r.info.series_uid, DicomStudyLayout::kThinB);
    EXPECT_TRUE(r.info.warnings.empty());  // chosen, not defaulted
    o.series_description = "head 5.0";
    r = read_volume({dir_->str()}, o);
    EXPECT_EQ(r.info.series_uid, DicomStudyLayout::kThick);
    EXPECT_EQ(r.volume.dims()[2], layout_.thick_slices);
    o.series_description.clear();
    o.series_uid = DicomStudyLayout::kThinB;
    r = read_volume({dir_->str()}, o);
    EXPECT_EQ(r.info.series_uid, DicomStudyLayout::kThinB);

    const DicomStudy s = list_dicom_series(dir_->str());
    // An exact description wins over the ones that contain it.
    DicomStudy s2 = s;
    s2.series[1].description = "Head 1.0";
    EXPECT_EQ(s2.series[choose_dicom_series(s2, {"", "HEAD 1.0"}).index].series_uid, DicomStudyLayout::kThick);
    // UID and description must agree.
    EXPECT_EQ(s.series[choose_dicom_series(s, {DicomStudyLayout::kThinA, "Head 1.0"}).index].series_uid,
              DicomStudyLayout::kThinA);
}

TEST_F(DicomStudyFolder, ChoicesThatMatchNothingOrSeveralOrNoVolume) {
    const DicomStudy s = list_dicom_series(dir_->str());
    std::string m = error_of<InvalidParameter>([&] { choose_dicom_series(s, {"1.2.3.4", ""}); });
    EXPECT_NE(m.find(dir_->str()), std::string::npos) << m;
    EXPECT_NE(m.find("SeriesInstanceUID 1.2.3.4"), std::string::npos) << m;
    EXPECT_NE(m.find(DicomStudyLayout::kThinA), std::string::npos) << m;  // lists what there is
    EXPECT_NE(m.find(DicomStudyLayout::kDose), std::string::npos) << m;

    m = error_of<InvalidParameter>([&] { choose_dicom_series(s, {"", "sagittal"}); });
    EXPECT_NE(m.find("containing 'sagittal'"), std::string::npos) << m;
    EXPECT_NE(m.find("Head 1.0 H70h"), std::string::npos) << m;

    m = error_of<InvalidParameter>([&] { choose_dicom_series(s, {"", "Head 1.0"}); });
    EXPECT_NE(m.find("matches 2 DICOM series"), std::string::npos) << m;
    EXPECT_NE(m.find(DicomStudyLayout::kThinA), std::string::npos) << m;
    EXPECT_NE(m.find(DicomStudyLayout::kThinB), std::string::npos) << m;

    m = error_of<InvalidParameter>([&] { choose_dicom_series(s, {"", "topogram"}); });
    EXPECT_NE(m.find("is not a volume: localizer"), std::string::npos) << m;
    m = error_of<InvalidParameter>([&] { choose_dicom_series(s, {DicomStudyLayout::kDose, ""}); });
    EXPECT_NE(m.find("is not a volume"), std::string::npos) << m;
    m = error_of<InvalidParameter>([&] { choose_dicom_series(s, {DicomStudyLayout::kThick, "H70h"}); });
    EXPECT_NE(m.find(DicomStudyLayout::kThick), std::string::npos) << m;

    ReadOptions o;
    o.series_uid = "9.9";
    EXPECT_THROW(read_volume({dir_->str()}, o), InvalidParameter);
}

TEST_F(DicomStudyFolder, DicomdirFileWorksLikeItsFolder) {
    ScratchDir disc("disc");
    // A copy of the study as a CD holds it (ISO 9660 names: upper case, at most 8 characters, no
    // extension), with a DICOMDIR made by gdcmgendir when it is installed and accepts the files,
    // else a stand-in file of that name.
    const std::pair<const char*, const char*> folders[] = {
        {"LOCALIZER", "LOC"}, {"S5MM", "S5MM"}, {"S1MM_H30", "S1MMH30"}, {"S1MM_H70", "S1MMH70"}, {"DOSE", "DOSE"}};
    for (const auto& [from, to] : folders) {
        fs::create_directories(disc / to);
        for (const auto& e : fs::directory_iterator(*dir_ / from))
            fs::copy_file(e.path(), fs::path(disc / to) / e.path().stem());
    }
    const std::string dicomdir = disc / "DICOMDIR";
    const std::string cmd = "cd '" + disc.str() + "' && gdcmgendir -r -i . -o DICOMDIR 2>&1";
    const int status = std::system(cmd.c_str());
    const bool generated = status == 0 && fs::exists(dicomdir);
    if (!generated) std::ofstream(dicomdir) << "not a real DICOMDIR\n";
    std::cout << "[ info ] DICOMDIR " << (generated ? "written by gdcmgendir" : "stand-in") << "\n";
    fs::copy_file(*dir_ / "LICENSE.txt", disc / "LICENSE.txt");

    const DicomStudy s = list_dicom_series(dicomdir);
    EXPECT_EQ(s.path, dicomdir);
    EXPECT_EQ(s.folder, disc.str());
    ASSERT_EQ(s.series.size(), 5u);  // the DICOMDIR itself is no series
    EXPECT_EQ(s.files_skipped, 2u);  // LICENSE.txt, DICOMDIR
    const ReadResult r = read_volume({dicomdir});
    EXPECT_EQ(r.info.series_uid, DicomStudyLayout::kThinA);
    EXPECT_EQ(r.info.paths, std::vector<std::string>{dicomdir});
    const ReadResult lower = [&] {
        fs::rename(dicomdir, disc / "dicomdir");
        return read_volume({disc / "dicomdir"});
    }();
    EXPECT_EQ(lower.info.series_uid, DicomStudyLayout::kThinA);
}

TEST(DicomSeriesErrors, OnlyNonVolumesOrNothing) {
    ScratchDir dir("nonvolumes");
    const Volume<int16_t> ct = ramp_ct();
    endocast::testing::write_dicom_study(dir.str(), ct);
    for (const char* d : {"S5MM", "S1MM_H30", "S1MM_H70"}) fs::remove_all(dir / d);
    const std::string m = error_of<IoError>([&] { read_volume({dir.str()}); });
    EXPECT_NE(m.find(dir.str()), std::string::npos) << m;
    EXPECT_NE(m.find("holds no DICOM volume"), std::string::npos) << m;
    EXPECT_NE(m.find("localizer"), std::string::npos) << m;
    EXPECT_NE(m.find("Secondary Capture"), std::string::npos) << m;

    ScratchDir empty("nodicom");
    std::ofstream(empty / "README") << "nothing here\n";
    EXPECT_TRUE(list_dicom_series(empty.str()).series.empty());
    const std::string m2 = error_of<IoError>([&] { read_volume({empty.str()}); });
    EXPECT_NE(m2.find("holds no DICOM series"), std::string::npos) << m2;
    EXPECT_THROW(list_dicom_series(empty / "README"), IoError);  // a file, not a DICOMDIR
    EXPECT_THROW(list_dicom_series(empty / "missing"), IoError);
}

// A study gathered with symbolic links: linked folders are searched, each real folder once (a
// link back up to the study does not loop or count its files twice).
TEST(DicomSeriesLinks, LinkedFoldersAreSearchedOnce) {
    ScratchDir scratch("links");
    const fs::path dir(scratch.str());
    const Volume<int16_t> ct = ramp_ct();
    endocast::testing::write_dicom_study((dir / "real").string(), ct);
    const DicomStudy direct = list_dicom_series((dir / "real").string());
    fs::create_directories(dir / "linked");
    fs::create_directory_symlink(dir / "real", dir / "linked" / "study");
    fs::create_directory_symlink(dir / "linked", dir / "linked" / "loop");
    const DicomStudy via = list_dicom_series((dir / "linked").string());
    ASSERT_EQ(via.series.size(), direct.series.size());
    EXPECT_EQ(via.files_scanned, direct.files_scanned);
    for (size_t i = 0; i < direct.series.size(); ++i) {
        EXPECT_EQ(via.series[i].series_uid, direct.series[i].series_uid);
        EXPECT_EQ(via.series[i].files.size(), direct.series[i].files.size());
    }
}

/// A series of plain fields for the choice rules alone.
DicomSeriesInfo fake(const std::string& uid, const std::string& modality, double thickness, size_t slices,
                     bool volume = true) {
    DicomSeriesInfo s;
    s.series_uid = uid;
    s.modality = modality;
    s.slice_thickness_mm = thickness;
    s.files.assign(slices, "f");
    s.is_volume = volume;
    if (!volume) s.reason = "localizer";
    return s;
}

TEST(DicomSeriesChoice, RulesInOrder) {
    DicomStudy s;
    s.path = "/study";
    s.series = {fake("1.1", "CT", 1.0, 100), fake("1.2", "CT", 0.6, 50), fake("1.3", "MR", 0.5, 300),
                fake("1.4", "CT", 0.6, 80), fake("1.5", "CT", 0.1, 400, false)};
    // CT before MR, then 0.6 mm before 1 mm, then 80 slices before 50.
    EXPECT_EQ(choose_dicom_series(s).index, 3u);
    s.series[1].files.assign(80, "f");  // as many: the smaller UID
    EXPECT_EQ(choose_dicom_series(s).index, 1u);
    s.series[1].slice_thickness_mm = 0;  // unknown thickness: the slice step stands in
    s.series[1].slice_step_mm = 0.6004;
    EXPECT_EQ(choose_dicom_series(s).index, 1u);
    // No CT volume: any volume.
    DicomStudy mr;
    mr.path = "/mr";
    mr.series = {fake("2.1", "MR", 3, 40), fake("2.2", "MR", 1, 160)};
    EXPECT_EQ(choose_dicom_series(mr).index, 1u);
    // One series: no warning.
    DicomStudy one;
    one.series = {fake("3.1", "CT", 1, 10)};
    EXPECT_TRUE(choose_dicom_series(one).warning.empty());
    EXPECT_TRUE(is_dicomdir_path("/media/cdrom/DICOMDIR"));
    EXPECT_TRUE(is_dicomdir_path("dicomdir"));
    EXPECT_FALSE(is_dicomdir_path("/media/cdrom/DICOMDIR/IM1"));
}

TEST(DicomSeriesRealData, HeadPhantomListedInItsOwnOrder) {
    const std::string dir = data_dir() + "/headphantom-dicom";
    if (!fs::exists(dir)) GTEST_SKIP() << "../shared/data not found";
    const auto t0 = std::chrono::steady_clock::now();
    const DicomStudy s = list_dicom_series(dir);
    const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "[ info ] headphantom-dicom listed in " << sec << " s\n";
    ASSERT_EQ(s.series.size(), 1u);
    const DicomSeriesInfo& h = s.series[0];
    EXPECT_TRUE(h.is_volume) << h.reason;
    EXPECT_EQ(h.files.size(), 209u);
    EXPECT_EQ(h.rows, 512);
    EXPECT_EQ(h.columns, 512);
    EXPECT_NEAR(h.slice_step_mm, 2.0, 1e-3);
    EXPECT_EQ(h.files, itk_order(dir, h.series_uid));
    EXPECT_TRUE(choose_dicom_series(s).warning.empty());
}

// Every real series (each folder holds one) in the order ITK gave read_dicom_dir before.
TEST(DicomSeriesRealData, EveryRealSeriesInItksOrder) {
    int checked = 0;
    for (const char* name : {"headphantom-dicom", "dryskull-phantom-dicom", "ge-tilt-dicom"}) {
        const std::string dir = data_dir() + "/" + name;
        if (!fs::exists(dir)) continue;
        const DicomStudy s = list_dicom_series(dir);
        ASSERT_EQ(s.series.size(), 1u) << dir;
        EXPECT_EQ(s.series[0].files, itk_order(dir, s.series[0].series_uid)) << dir;
        ++checked;
    }
    if (checked == 0) GTEST_SKIP() << "../shared/data not found";
    // The whole data folder as one study (searched recursively): every series found.
    const DicomStudy all = list_dicom_series(data_dir());
    EXPECT_EQ(all.series.size(), size_t(checked));
}

}  // namespace
