#pragma once
// Shared by the readers in io.cpp, raw_io.cpp and dicom_direct.cpp (not installed).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "endocast/io.h"
#include "slice_source.h"
#include "endocast/tiff.h"

namespace endocast {

/// Which inputs are read here rather than through ITK: a NRRD with raw or gzip data in one file, a
/// MetaImage (its header parsed strictly, its files checked for size), a DICOM series of
/// uncompressed 16-bit slices (in parallel). The same voxels and geometry either way; all by
/// default, and tests compare both.
struct DirectReaders {
    bool nrrd = true, metaimage = true, dicom = true;
};

/// read_volume (io.h) with the readers chosen.
ReadResult read_volume(const std::vector<std::string>& inputs, const ReadOptions& opt, const DirectReaders& direct);

/// gzip data as written by write_nrrd_gzip: members (RFC 1952) of kGzipMemberBytes of the data each
/// (the last shorter), each with an extra field subfield "EC" of 4 bytes, little endian: the
/// member's whole size in bytes. Any gzip reader reads it (members are concatenated, unknown
/// subfields skipped); inflate_gzip_members hops from member to member by those sizes and inflates
/// them on all threads.
constexpr size_t kGzipMemberBytes = size_t(4) << 20;
constexpr char kGzipIndexId[2] = {'E', 'C'};
constexpr size_t kGzipMemberHeader = 20;  // 10 bytes, XLEN, the 8-byte subfield
constexpr int kGzipLevel = 6;

/// An attached NRRD (.nrrd) with gzip data in indexed members (above), compressed on all threads;
/// under a temporary name beside `path`, renamed when complete. Throws IoError.
template <class T>
void write_nrrd_gzip(const Volume<T>& v, const std::string& path);

/// Inflates gzip `data` into exactly `want` bytes at `out` when every member carries the "EC" index
/// (write_nrrd_gzip), on all threads; false when it does not (or does not hold exactly `want`
/// bytes, or a member is corrupt): the caller inflates it in order.
bool inflate_gzip_members(const unsigned char* data, size_t size, char* out, size_t want);

/// Natural order: runs of digits compare as numbers ("CThead.2" < "CThead.10"); equal up to
/// leading zeros, plain order (deterministic).
bool natural_less(const std::string& a, const std::string& b);

/// A printf-style pattern with exactly one integer conversion: prefix, "%[flags][width]d", suffix.
struct PrintfPattern {
    std::string prefix, spec, suffix;
    std::string format(long n) const;  ///< the name of file n
};

/// `s` as a printf pattern ("%%" is a literal %); nullopt when it has no integer conversion or
/// more than one.
std::optional<PrintfPattern> parse_printf(const std::string& s);

/// One input expanded to files: the file itself, or the files a glob pattern ("CThead.*") or a
/// printf pattern ("slice%03d.tif", numbered from 0 or 1 upward until a file is missing) names.
/// Throws IoError naming `in` for a directory (expected a `kind` file or pattern), a pattern that
/// matches nothing, or a missing file.
std::vector<std::string> expand_files(const std::string& in, const std::string& kind);

/// The whole file's bytes; nullopt when it cannot be opened or read.
std::optional<std::string> slurp(const std::string& path);

/// A whole file's bytes, mapped read-only (the page cache's own pages: nothing copied, no memory
/// of the process's own to fill: CThead's 7 MB gzip mapped in 0.6 ms against 3.5 ms for read()
/// into a zero-filled string; a raw NRRD no longer held twice, file and volume), or read into
/// memory (slurp) where it cannot be mapped (an empty file, a pipe). A file truncated by another
/// process while it is mapped is a SIGBUS, not an error message. Move-only.
class FileBytes {
public:
    /// nullopt when the file cannot be opened or read.
    static std::optional<FileBytes> open(const std::string& path);
    std::string_view view() const { return map_ ? std::string_view(static_cast<const char*>(map_), size_) : copy_; }
    FileBytes(FileBytes&& o) noexcept;
    FileBytes& operator=(FileBytes&& o) noexcept;
    FileBytes(const FileBytes&) = delete;
    FileBytes& operator=(const FileBytes&) = delete;
    ~FileBytes();

private:
    FileBytes() = default;
    void* map_ = nullptr;
    size_t size_ = 0;
    std::string copy_;
};

/// Converts n stored samples of type t at src (bytes reversed if `swap`) to float, one thread.
void convert_samples(RawType t, const unsigned char* src, size_t n, bool swap, float* dst);

/// convert_samples over n samples, in chunks on every thread (the same floats).
void convert_in_parallel(RawType t, const unsigned char* src, size_t n, bool swap, float* dst);

/// True on a little-endian host (the byte order raw data, NRRD and TIFF are compared with).
bool host_is_little_endian();

/// ImagePositionPatient (0020,0032) from its DICOM text, e.g. "-249.5\\-432.0\\551.5" (mm); nullopt if unreadable.
std::optional<Vec3> parse_image_position(std::string value);

/// Reads the pixels of a DICOM series, one slice per file in the order given, into `out`
/// (nx * ny * files.size() floats, x fastest), without GDCM and in parallel, with the values GDCM
/// gives through ITK (bits above BitsStored cleared or sign-filled, RescaleSlope and
/// RescaleIntercept applied). Only for the common case: CT Image Storage, uncompressed implicit or
/// explicit VR little endian, one frame of 16-bit MONOCHROME2 pixels, nx columns and ny rows,
/// integer slope and intercept. Returns the slices' ImagePositionPatient up to the first slice
/// without one, or nullopt when any file is outside that case or unreadable (then `out` holds
/// nothing useful and the series must be read with ITK).
std::optional<std::vector<Vec3>> read_dicom_pixels(const std::vector<std::string>& files, int64_t nx,
                                                   int64_t ny, float* out);
/// The same into int16 (the same values); `fits` false when a value is outside int16's range (then
/// `out` is not the series: read it as float).
std::optional<std::vector<Vec3>> read_dicom_pixels(const std::vector<std::string>& files, int64_t nx,
                                                   int64_t ny, int16_t* out, bool& fits);

/// Throws InvalidParameter unless a slab of dims `d` written after `next_z` slices fits the grid
/// `whole` (its x and y size, no slice beyond the last); for the SlabWriters (in tiff_io.cpp).
void check_slab(const std::string& path, const Geometry& whole, int64_t next_z, const Dims& d);

/// Headerless raw data's files, checked (options, sizes) as read_raw checks them, before reading.
struct RawLayout {
    std::vector<std::string> files;  ///< naturally sorted
    int64_t slices_per_file = 0;
    Geometry geometry;               ///< from the options
};
RawLayout scan_raw(const std::vector<std::string>& inputs, const RawOptions& o);

/// The grid of a TIFF stack as read_tiff gives it: voxel size given or from the tags (info's
/// spacing_source and warnings set), origin given or ImageJ's. Throws InvalidParameter when no
/// voxel size is known or it is not finite and > 0.
Geometry tiff_geometry(const TiffStack& s, const TiffReadOptions& opt, InputInfo& info);

/// Stored voxels at known places in files: `parts` in slice order, each `slices` whole slices of
/// type `type` from byte `offset` of `path` (bytes reversed when `swap`).
struct RawPart {
    std::string path;
    uint64_t offset = 0;
    int64_t slices = 0;
};
std::unique_ptr<SliceSource> open_raw_parts(std::vector<RawPart> parts, RawType type, bool swap,
                                            const VolumeHeader& header, const InputInfo& info);

/// Gzip data (one or more members) from byte `offset` of `path` to its end, inflated in order.
std::unique_ptr<SliceSource> open_gzip_part(std::string path, uint64_t offset, RawType type, bool swap,
                                            const VolumeHeader& header, const InputInfo& info);

/// A MetaImage (.mha/.mhd) header, read by read_metaimage_header (not by ITK's MetaIO).
struct MetaImageHeader {
    int ndims = 0;
    std::vector<int64_t> dims;          ///< DimSize, NDims values
    Geometry geometry;                  ///< the first three axes (ElementSpacing, Offset, TransformMatrix)
    std::optional<RawType> type;        ///< ElementType; nullopt for 64-bit integers (voxel_type "int64"/"uint64")
    size_t voxel_bytes = 0;
    std::string voxel_type;             ///< as InputInfo::voxel_type: "uint8", "int16", "float32", ...
    long channels = 1;                  ///< ElementNumberOfChannels
    bool binary = true;                 ///< BinaryData (false: ASCII numbers)
    bool compressed = false;            ///< CompressedData (zlib or gzip)
    bool msb = false;                   ///< BinaryDataByteOrderMSB / ElementByteOrderMSB
    int64_t compressed_size = 0;        ///< CompressedDataSize (bytes; 0: all that follow)
    int64_t header_size = 0;            ///< HeaderSize (bytes skipped; -1: the data are the file's last bytes)
    std::string data_file;              ///< ElementDataFile's value (LOCAL, a name, a pattern, LIST [D])
    int64_t header_end = -1;            ///< the byte after the ElementDataFile line; -1: the file ends on it
};

/// Reads the "Name = value" lines of a MetaImage header up to its ElementDataFile line (within the
/// file's first 64 KiB): NDims (1 to 16), DimSize, ElementSpacing (else ElementSize), Offset /
/// Position / Origin, TransformMatrix / Rotation / Orientation, ElementType, ElementNumberOfChannels,
/// BinaryData, CompressedData, CompressedDataSize, BinaryDataByteOrderMSB / ElementByteOrderMSB,
/// HeaderSize; other names are ignored. IoError naming the file and line for anything else: a line
/// that is not a field, a control character, a field given twice with different values, a count of
/// numbers other than NDims (NDims^2 for the matrix), a missing NDims, DimSize or ElementType.
MetaImageHeader read_metaimage_header(const std::string& path);

/// A SliceSource for one NRRD file whose data is raw or gzip in the file or in one detached data
/// file and whose axes are perpendicular; nullptr for anything else (read whole by read_volume).
std::unique_ptr<SliceSource> open_nrrd_slices(const std::string& path);

/// The same for a MetaImage whose voxels are uncompressed binary data in one file (LOCAL or a data
/// file) or one file per slice (a slice pattern), 8- to 32-bit integers or floats, on a grid with
/// perpendicular axes; nullptr for anything else (read whole by read_volume, which says what is
/// wrong with a bad one). The header is read by read_metaimage_header (IoError for a bad one).
std::unique_ptr<SliceSource> open_metaimage_slices(const std::string& path);

}  // namespace endocast
