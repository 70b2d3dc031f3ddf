#pragma once
// A study folder as PACS exports and CD copies hold them, written with dicom_writer.h from a CT
// volume: a 2-image localizer, a 5-slice-step series, two series at the CT's own slices with
// different kernels, a secondary-capture dose report and a licence text, each series in its own
// subfolder. For the tests of list_dicom_series / choose_dicom_series and `endocast series`.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "dicom_writer.h"
#include "endocast/phantom.h"

namespace endocast::testing {

/// The UIDs and subfolders of write_dicom_study's series, in UID order.
struct DicomStudyLayout {
    static constexpr const char* kLocalizer = "1.2.826.0.1.3680043.9.7777.1.1";
    static constexpr const char* kThick = "1.2.826.0.1.3680043.9.7777.1.2";   ///< every 5th slice, 5 mm thick
    static constexpr const char* kThinA = "1.2.826.0.1.3680043.9.7777.1.3";   ///< every slice, kernel H30s
    static constexpr const char* kThinB = "1.2.826.0.1.3680043.9.7777.1.4";   ///< every slice, kernel H70h
    static constexpr const char* kDose = "1.2.826.0.1.3680043.9.7777.1.5";    ///< secondary capture, 1 image
    int thin_slices = 0;   ///< slices of kThinA and kThinB (the CT's z size)
    int thick_slices = 0;  ///< slices of kThick
};

/// A series over `ct`'s x-y grid at its z slices `ks` (identity orientation), headers as given.
inline DicomSeriesSpec study_series(const Volume<int16_t>& ct, const std::vector<int>& ks, const char* uid,
                                    int number, const std::string& description, const std::string& kernel,
                                    double thickness_mm) {
    DicomSeriesSpec s;
    const Geometry& g = ct.geometry();
    s.series_uid = uid;
    s.series_number = number;
    s.series_description = description;
    s.kernel = kernel;
    s.slice_thickness_mm = thickness_mm;
    s.columns = int(g.dims[0]);
    s.rows = int(g.dims[1]);
    s.column_spacing_mm = g.spacing[0];
    s.row_spacing_mm = g.spacing[1];
    for (int k : ks) s.positions.push_back(g.index_to_world(0, 0, k));
    return s;
}

/// Writes the study under `dir` (created): LOCALIZER/, S5MM/, S1MM_H30/, S1MM_H70/, DOSE/ and
/// LICENSE.txt. The thin series' files are written in reverse slice order (IM0001 = last slice),
/// so that only sorting by position gives the CT back.
inline DicomStudyLayout write_dicom_study(const std::string& dir, const Volume<int16_t>& ct) {
    namespace fs = std::filesystem;
    const Geometry& g = ct.geometry();
    const int nz = int(g.dims[2]);
    DicomStudyLayout layout;
    layout.thin_slices = nz;
    std::vector<int> all, every5;
    std::vector<size_t> backwards;  // file i holds slice nz - 1 - i
    for (int k = 0; k < nz; ++k) all.push_back(k);
    for (int k = 0; k < nz; k += 5) every5.push_back(k);
    for (int k = nz - 1; k >= 0; --k) backwards.push_back(size_t(k));
    layout.thick_slices = int(every5.size());
    const double dz = g.spacing[2];
    const fs::path d(dir);

    DicomSeriesSpec loc = study_series(ct, {nz / 3, 2 * nz / 3}, DicomStudyLayout::kLocalizer, 1,
                                       "Topogram 0.6 T20s", "T20s", 0.6);
    loc.image_type = "ORIGINAL\\PRIMARY\\LOCALIZER";
    write_dicom_series_from((d / "LOCALIZER").string(), loc, ct);
    write_dicom_series_from((d / "S5MM").string(),
                            study_series(ct, every5, DicomStudyLayout::kThick, 2, "Head 5.0 H30s", "H30s", 5 * dz), ct);
    write_dicom_series_from((d / "S1MM_H30").string(),
                            study_series(ct, all, DicomStudyLayout::kThinA, 3, "Head 1.0 H30s", "H30s", dz), ct,
                            -1024, backwards);
    write_dicom_series_from((d / "S1MM_H70").string(),
                            study_series(ct, all, DicomStudyLayout::kThinB, 4, "Head 1.0 H70h", "H70h", dz), ct,
                            -1024, backwards);
    DicomSeriesSpec dose = study_series(ct, {0}, DicomStudyLayout::kDose, 5, "Dose Report", "", 0);
    dose.sop_class_uid = "1.2.840.10008.5.1.4.1.1.7";  // Secondary Capture Image Storage
    dose.modality = "OT";
    dose.image_type = "DERIVED\\SECONDARY\\OTHER";
    dose.rows = dose.columns = 16;
    write_dicom_series_from((d / "DOSE").string(), dose, ct);
    std::ofstream((d / "LICENSE.txt").string()) << "The images on this disc may be used for teaching.\n";
    return layout;
}

/// The study of write_dicom_study made from the macaque phantom at 1 mm (82 x 98 x 78 voxels,
/// seed 3): small enough that `endocast extract` takes about a second.
inline DicomStudyLayout write_phantom_dicom_study(const std::string& dir) {
    PhantomParams p;
    p.preset = PhantomPreset::Macaque;
    p.spacing = {1, 1, 1};
    p.seed = 3;
    return write_dicom_study(dir, generate_phantom(p).ct);
}

}  // namespace endocast::testing
