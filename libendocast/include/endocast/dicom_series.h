#pragma once
// The DICOM series of a study folder (a PACS export, a CD/DVD copy with its DICOMDIR) and the
// choice of the one to read.
//
// list_dicom_series() searches a folder recursively (or the folder a DICOMDIR file lies in; the
// DICOMDIR's records are not read), reads the headers of every file up to the pixel spacing
// (gdcm::Scanner: no pixel data), skips files that are not DICOM (licence texts, viewers) or hold
// no SeriesInstanceUID (the DICOMDIR itself), groups the rest by SeriesInstanceUID and says of
// each series whether it is a volume the method can use. choose_dicom_series() picks one: by UID,
// by description, or by default the CT volume with the thinnest slices.
// read_volume() (io.h) does both for a folder or a DICOMDIR file.
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace endocast {

/// One DICOM series (one SeriesInstanceUID) found in a folder. Header values are those of the
/// series' first file (in slice order), blank-trimmed; empty / 0 when the header lacks them.
struct DicomSeriesInfo {
    std::string series_uid;              ///< SeriesInstanceUID (0020,000E)
    std::string description;             ///< SeriesDescription (0008,103E)
    std::string modality;                ///< Modality (0008,0060): "CT", "MR", "OT", "SR", ...
    std::string sop_class_uid;           ///< SOPClassUID (0008,0016)
    std::string sop_class;               ///< its name ("CT Image Storage"), or the UID when unknown
    std::string image_type;              ///< ImageType (0008,0008), e.g. "ORIGINAL\PRIMARY\AXIAL"
    std::string kernel;                  ///< ConvolutionKernel (0018,1210), e.g. "H30s"
    std::optional<int> series_number;    ///< SeriesNumber (0020,0011)
    int rows = 0;                        ///< Rows (0028,0010): pixels along y
    int columns = 0;                     ///< Columns (0028,0011): pixels along x
    /// PixelSpacing (0028,0030) in mm: between rows (y), between columns (x); 0 when absent.
    std::array<double, 2> pixel_spacing_mm{0, 0};
    double slice_thickness_mm = 0;       ///< SliceThickness (0018,0050); 0 when absent
    /// Median distance (mm) between neighbouring slices along the slice normal, from
    /// ImagePositionPatient; 0 with fewer than 2 slices or positions.
    double slice_step_mm = 0;
    std::vector<std::string> folders;    ///< the folders holding its files, sorted
    /// Its files in slice order, as ITK's GDCMSeriesFileNames orders them (so that a folder of one
    /// series gives the volume it always gave): by ImagePositionPatient along the first file's
    /// slice normal, ascending; when positions repeat or are all equal, by InstanceNumber when
    /// those are distinct; else by path.
    std::vector<std::string> files;
    /// Whether the method can use it: CT or MR image storage (or no SOP class), modality not SR,
    /// OT, DOC, KO or PR, not a localizer (ImageType LOCALIZER or SCOUT), at least 3 slices, all
    /// of one size (Rows, Columns).
    bool is_volume = false;
    std::string reason;                  ///< why not, when !is_volume ("localizer (ImageType ...)")
};

/// What a folder holds.
struct DicomStudy {
    std::string path;                    ///< the folder or DICOMDIR file given
    std::string folder;                  ///< the folder searched (the DICOMDIR's folder for one)
    /// Every series, sorted by SeriesInstanceUID.
    std::vector<DicomSeriesInfo> series;
    size_t files_scanned = 0;            ///< regular files looked at (recursively)
    size_t files_skipped = 0;            ///< of those: not DICOM, or without a SeriesInstanceUID
};

/// Whether `path` names a DICOMDIR file (its file name, case-insensitive: "DICOMDIR", "dicomdir").
bool is_dicomdir_path(const std::string& path);

/// Lists the DICOM series under `path`: a folder (searched recursively; symbolic links to files
/// and folders followed, each real folder once) or a DICOMDIR file (its folder is searched the
/// same way).
/// Deterministic: files are visited in path order and series sorted by UID. Throws IoError when
/// `path` does not exist, is neither a folder nor a DICOMDIR file, or cannot be searched. A folder
/// without DICOM files gives an empty list (read_volume turns that into an IoError).
DicomStudy list_dicom_series(const std::string& path);

/// Which series to read. Both empty: the default rule (choose_dicom_series).
struct DicomSeriesChoice {
    std::string series_uid;              ///< SeriesInstanceUID, exactly
    /// A part of the SeriesDescription, case-insensitive; a description equal to it (ignoring
    /// case) wins over ones that only contain it.
    std::string description;
};

/// The series chosen, and why the others were not.
struct DicomSeriesPick {
    size_t index = 0;                    ///< in DicomStudy::series
    /// Set when the series was chosen by the default rule among several: names the others (UID,
    /// description, why not chosen) and how to choose another. Empty otherwise.
    std::string warning;
};

/// Chooses the series to read from `study`.
///  - `choice.series_uid` and/or `choice.description` given: the series matching both. The
///    description is matched among the volume series first, then among all. InvalidParameter
///    (naming the folder, the value and listing the series) when nothing matches, when the
///    description matches several, or when the match is not a volume (with its reason).
///  - neither: the volume series of modality CT (any volume when none is CT) with the thinnest
///    slices (SliceThickness, else the slice step; equal within 0.001 mm), then the most slices,
///    then the smallest UID.
/// Throws IoError when `study` holds no series ("holds no DICOM series") or, for the default rule,
/// only series that are not volumes (each listed with its reason).
DicomSeriesPick choose_dicom_series(const DicomStudy& study, const DicomSeriesChoice& choice = {});

/// One line describing a series for messages: "UID (DESCRIPTION, CT, 40 slices of 1 mm)".
std::string describe_dicom_series(const DicomSeriesInfo& s);

}  // namespace endocast
