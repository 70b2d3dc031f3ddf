#pragma once
// Reading CT volumes and writing label/CT volumes.
//
// Formats read (chosen by what the input is):
//  - NRRD (.nrrd, or .nhdr with a detached, possibly gzip-encoded data file), NIfTI (.nii, .nii.gz),
//    MetaImage (.mha, .mhd): read with ITK, keeping spacing, origin and direction (ITK's LPS space).
//  - a directory holding one DICOM series: slices sorted by position along the slice normal,
//    RescaleSlope/RescaleIntercept applied (values in HU). Several series: InvalidParameter listing
//    their UIDs unless ReadOptions::series_uid picks one.
//  - headerless raw data: one file holding the whole volume, or several slice files (a list, or a
//    glob/printf pattern), when ReadOptions::raw is set.
// Voxel values are returned as float in the scan's own units.
#include <optional>
#include <string>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

enum class RawType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
enum class Endian { Little, Big };

/// Parses "int8|uint8|int16|uint16|int32|uint32|float32|float64"; throws InvalidParameter.
RawType parse_raw_type(const std::string& s);
std::string to_string(RawType t);
size_t raw_type_size(RawType t);

/// How to read headerless raw data.
struct RawOptions {
    Dims size{0, 0, 0};                  ///< voxels along x, y, z of the whole volume
    RawType type = RawType::UInt16;
    Endian endian = Endian::Little;
    uint64_t header_bytes = 0;           ///< bytes skipped at the start of each file
    Vec3 spacing{1.0, 1.0, 1.0};         ///< mm
    Vec3 origin{0.0, 0.0, 0.0};          ///< mm
};

struct ReadOptions {
    std::optional<RawOptions> raw;       ///< set: inputs are headerless raw file(s)
    std::string series_uid;              ///< DICOM: SeriesInstanceUID to read when several
};

/// What was read, for reports.
struct InputInfo {
    std::vector<std::string> paths;      ///< the file(s) or directory given
    std::string format;                  ///< "nrrd", "nifti", "metaimage", "dicom", "raw"
    std::string voxel_type;              ///< stored component type, e.g. "uint16", "int16", "float32"
    std::string series_uid;              ///< DICOM only
    size_t files_read = 0;               ///< number of files actually read (slices for DICOM/raw)
};

struct ReadResult {
    Volume<float> volume;
    InputInfo info;
};

/// Reads a CT volume. `inputs` is one path (file or DICOM directory), or, for raw slices, several
/// paths or one pattern ("CThead.*", "slice%03d.raw"); slice files are ordered naturally
/// (CThead.2 before CThead.10). Throws IoError (missing/unreadable/truncated file, no DICOM in a
/// directory, ...) or InvalidParameter (several DICOM series, bad raw options, ...), each message
/// naming the file and the value that was expected.
ReadResult read_volume(const std::vector<std::string>& inputs, const ReadOptions& opt = {});

/// Writes a volume with its geometry. Format by extension: .nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd.
/// The file is written to a temporary name beside `path` and renamed on success, so a failure never
/// leaves a partial file. Throws IoError.
void write_volume(const Volume<uint8_t>& v, const std::string& path);
void write_volume(const Volume<int16_t>& v, const std::string& path);
void write_volume(const Volume<float>& v, const std::string& path);

}  // namespace endocast
