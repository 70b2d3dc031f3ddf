#pragma once
// Reading CT volumes and writing label/CT volumes.
//
// Formats read (chosen by what the input is):
//  - NRRD (.nrrd, or .nhdr with a detached, possibly gzip-encoded data file), NIfTI (.nii, .nii.gz),
//    MetaImage (.mha, .mhd): read with ITK, keeping spacing, origin and direction (ITK's LPS space).
//  - a directory holding one DICOM series: slices sorted by position along the slice normal,
//    RescaleSlope/RescaleIntercept applied (values in HU); a tilted (gantry tilt) or unevenly
//    spaced series is resampled onto a regular grid in patient space (slice_stack.h). A study
//    folder (searched recursively) or its DICOMDIR file: the series chosen by dicom_series.h
//    (ReadOptions::series_uid / series_description, or by default the CT volume with the thinnest
//    slices, with a warning).
//  - TIFF (tiff.h): a folder of 2-D slices, a printf/glob pattern or list of slice files, or one
//    multi-page file (.tif/.tiff); the voxel size from ReadOptions::spacing or the files' tags.
//  - headerless raw data: one file holding the whole volume, or several slice files (a list, or a
//    glob/printf pattern), when ReadOptions::raw is set.
// Voxel values are returned as float in the scan's own units.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "endocast/dicom_series.h"
#include "endocast/volume.h"

namespace endocast {

enum class RawType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
enum class Endian { Little, Big };

/// "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64" (the CLI parses them).
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

/// What a header says, before the voxels are read.
struct VolumeHeader {
    Geometry geometry;                   ///< dims, spacing, origin, direction as declared
    size_t stored_voxel_bytes = 0;       ///< bytes per voxel as stored (2 for uint16, ...)
    /// The voxels will be read a slab at a time and shrunk on the way (read_shrunk in
    /// slice_source.h), never held whole; false: the whole volume is read first.
    bool read_in_slabs = false;
};

struct ReadOptions {
    std::optional<RawOptions> raw;       ///< set: inputs are headerless raw file(s)
    std::string series_uid;              ///< DICOM: SeriesInstanceUID to read when several
    /// DICOM: a part of the SeriesDescription of the series to read (case-insensitive; see
    /// choose_dicom_series). Empty, with series_uid empty: the default choice.
    std::string series_description;
    /// Called once the header is known and before the voxels are allocated (e.g. to check that the
    /// work fits in memory); may throw to stop the read. For DICOM the size is that of the first
    /// slice times the number of slices.
    std::function<void(const VolumeHeader&)> check_header;
    /// A NRRD read directly (not through ITK) whose data is stored as 8- or 16-bit integers that all fit
    /// int16, or a DICOM series read directly whose values all fit int16 and that needs
    /// no resampling: the samples into ReadResult::volume16 (never as float: half the memory while
    /// it is read), ReadResult::volume holding only the geometry. Off by default: every other
    /// reader fills `volume`.
    bool int16 = false;
    /// DICOM: a series whose slices are tilted (gantry tilt) or not evenly spaced (mixed stacks) is
    /// resampled onto a regular grid in patient space (slice_stack.h) with slices this far apart
    /// (mm); 0: the smallest step of a run of evenly spaced slices. > 0 also resamples a regular
    /// series.
    double slice_spacing_mm = 0;
    /// TIFF input (the only format read here without a geometry of its own): the voxel size (mm),
    /// replacing the files' resolution tags and required when they have none, and the world
    /// position of voxel (0,0,0) (mm). Set for any other input: InvalidParameter.
    std::optional<Vec3> spacing;
    std::optional<Vec3> origin;
    /// false: DICOM slices are left stacked as read (ITK's geometry: along the normal, one step),
    /// for comparisons; a duplicated slice or a gap is still an error.
    bool resample_slices = true;
    /// read_shrunk reading in slabs (slice_source.h): called after each slab with the slices of
    /// the crop box read so far and their total (for progress with an ETA).
    std::function<void(int64_t slices_done, int64_t slices_total)> slab_progress;
};

/// What was read, for reports.
struct InputInfo {
    std::vector<std::string> paths;      ///< the file(s) or directory given
    std::string format;                  ///< "nrrd", "nifti", "metaimage", "dicom", "tiff", "raw"
    std::string voxel_type;              ///< stored component type, e.g. "uint16", "int16", "float32"
    std::string series_uid;              ///< DICOM only
    /// DICOM: every series the folder holds (list_dicom_series), the one read included.
    std::vector<DicomSeriesInfo> series_found;
    size_t files_read = 0;               ///< number of files actually read (slices for DICOM/raw)
    bool read_directly = false;          ///< data read without ITK (the direct NRRD, MetaImage and DICOM readers)
    /// DICOM: angle between the slices' stacking axis and their normal (gantry tilt, degrees; 0
    /// when the positions step along the normal).
    double gantry_tilt_deg = 0;
    /// DICOM: the slices were resampled onto a regular grid (tilt, uneven spacing, or
    /// ReadOptions::slice_spacing_mm); the volume's geometry is that grid's.
    bool resampled = false;
    std::string resample_reason;         ///< why, when resampled ("gantry tilt 18.5 deg; ...")
    /// DICOM: the runs of evenly spaced slices found along the normal ("01.dcm to 14.dcm: 14 slices
    /// 4 mm apart"), when there is more than one.
    std::vector<std::string> slice_runs;
    /// TIFF: where the voxel size came from ("given (--spacing)", "ImageJ description (unit mm,
    /// spacing 0.05) and XResolution/YResolution", ...).
    std::string spacing_source;
    std::vector<std::string> warnings;   ///< things a careful user should know about the input
    /// How the voxels were read: "whole" (the whole volume, then cropped/downsampled) or "slabs"
    /// (a slab at a time, shrunk while read: read_shrunk in slice_source.h).
    std::string read_path = "whole";
};

struct ReadResult {
    Volume<float> volume;
    /// ReadOptions::int16: the samples as int16 (`volume` then holds only the geometry); else empty.
    Volume<int16_t> volume16;
    InputInfo info;
    /// read_shrunk (slice_source.h): the input's own grid, before the crop and downsample (the
    /// other readers leave it default).
    Geometry input_grid;
};

/// Reads a CT volume. `inputs` is one path (file, DICOM directory or DICOMDIR file), or, for raw
/// slices, several paths or one pattern ("CThead.*", "slice%03d.raw"); slice files are ordered
/// naturally (CThead.2 before CThead.10). Throws IoError (missing/unreadable/truncated file, no
/// DICOM in a directory, only DICOM series that are not volumes, ...) or InvalidParameter (a DICOM
/// series choice that matches none or several, bad raw options, ...), each message naming the
/// file and the value that was expected.
ReadResult read_volume(const std::vector<std::string>& inputs, const ReadOptions& opt = {});

/// Reads headerless raw data (what read_volume does when ReadOptions::raw is set). `inputs`: one
/// file holding `header_bytes` + X*Y*Z voxels, or several slice/slab files (explicit paths, or one
/// glob pattern "CThead.*" / printf pattern "CThead.%d" numbered from 0 or 1 upward until a file is
/// missing), each holding `header_bytes` + X*Y*(Z/nfiles) voxels. Files are sorted naturally
/// (explicit lists too, so a shell-expanded `CThead.*` works). Sizes must match exactly (IoError);
/// the size must be > 0 with at most 2^40 voxels that fit in physical memory as float, spacing
/// finite and > 0, float data free of NaN/Inf (InvalidParameter).
/// `check_header`, when set, is called after the options and file sizes are checked and before
/// the volume is allocated.
ReadResult read_raw(const std::vector<std::string>& inputs, const RawOptions& raw,
                    const std::function<void(const VolumeHeader&)>& check_header = {});

/// Writes a volume with its geometry. Format by extension: .nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd,
/// or .tif/.tiff (write_tiff in tiff.h: multi-page, or a slice per file for a printf pattern).
/// The file is written to a temporary name beside `path` and renamed on success, so a failure never
/// leaves a partial file. The file(s) are first written under their final names into a hidden
/// temporary directory beside `path` (so detached .nhdr/.mhd data files keep consistent names),
/// then renamed into place, data file first. .nrrd, .nhdr (data as .raw.gz), .nii.gz and .mha are
/// compressed. A .nrrd is written by our code, not ITK: an attached header and gzip data in members
/// of 4 MiB, each indexed by its size in an extra subfield, compressed on all threads (the same
/// bytes for any thread count; read_volume inflates them on all threads; to any other reader it is
/// plain gzip). Throws IoError (also for an unknown extension or a missing parent directory).
void write_volume(const Volume<uint8_t>& v, const std::string& path);
void write_volume(const Volume<int16_t>& v, const std::string& path);
void write_volume(const Volume<float>& v, const std::string& path);

/// Writes an int16 volume a slab of slices at a time, for volumes too large to hold whole (the
/// phantom at microCT size). Destroyed before finish(): what was written is removed.
class SlabWriter {
public:
    virtual ~SlabWriter() = default;
    /// Appends the slices of `slab` (the whole grid's x and y size; slabs in order, z ascending).
    /// Throws IoError (disk full, ...) or InvalidParameter (a slab of another size, too many slices).
    virtual void write(const Volume<int16_t>& slab) = 0;
    /// Checks that every slice was written and puts the file(s) in place under their names.
    virtual void finish() = 0;
};

/// A SlabWriter for the grid `whole` at `path`: .nrrd (attached header, raw int16 in the host's byte order,
/// written under a temporary name and renamed by finish()), .tif/.tiff (one multi-page TIFF, BigTIFF
/// above 2 GiB)
/// or a .tif printf pattern (a file per slice; tiff.h). Throws IoError for another extension or an
/// unwritable place, InvalidParameter for a direction TIFF cannot store.
std::unique_ptr<SlabWriter> open_slab_writer(const std::string& path, const Geometry& whole);

}  // namespace endocast
