#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <omp.h>
#include <zlib.h>

#include <itkImage.h>
#include <itkImageFileWriter.h>
#include <itkMetaImageIO.h>

#include "../../libendocast/src/io/io_internal.h"  // inflate_gzip_members
#include "endocast/io.h"
#include "io/slice_source.h"
#include "test_helpers.h"

using namespace endocast;
namespace fs = std::filesystem;

namespace {

const std::string kData = ENDOCAST_SHARED_DATA;

using TempDir = endocast::testing::ScratchDir;

void write_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(f.good()) << path;
}

void write_text(const std::string& path, const std::string& text) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f << text;
}

std::vector<uint8_t> read_bytes(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), {});
}

/// Appends `v` as stored type S with the given byte order.
template <class S>
void append(std::vector<uint8_t>& out, S v, Endian e) {
    uint8_t b[sizeof(S)];
    std::memcpy(b, &v, sizeof(S));
    const uint16_t one = 1;
    uint8_t first;
    std::memcpy(&first, &one, 1);
    const bool host_little = first == 1;
    if ((e == Endian::Little) != host_little) std::reverse(b, b + sizeof(S));
    out.insert(out.end(), b, b + sizeof(S));
}

void append_as(std::vector<uint8_t>& out, RawType t, double v, Endian e) {
    switch (t) {
        case RawType::Int8: return append(out, static_cast<int8_t>(v), e);
        case RawType::UInt8: return append(out, static_cast<uint8_t>(v), e);
        case RawType::Int16: return append(out, static_cast<int16_t>(v), e);
        case RawType::UInt16: return append(out, static_cast<uint16_t>(v), e);
        case RawType::Int32: return append(out, static_cast<int32_t>(v), e);
        case RawType::UInt32: return append(out, static_cast<uint32_t>(v), e);
        case RawType::Float32: return append(out, static_cast<float>(v), e);
        case RawType::Float64: return append(out, static_cast<double>(v), e);
    }
}

template <class E, class F>
std::string error_message(F&& f) {
    try {
        f();
    } catch (const E& e) {
        return e.what();
    } catch (const std::exception& e) {
        return std::string("wrong exception type: ") + e.what();
    }
    return "no exception";
}

#define EXPECT_THROW_MSG(stmt, Exc, needle)                                          \
    do {                                                                             \
        const std::string msg_ = error_message<Exc>([&] { stmt; });                  \
        EXPECT_NE(msg_.find(needle), std::string::npos)                              \
            << "message \"" << msg_ << "\" lacks \"" << (needle) << "\"";            \
        EXPECT_EQ(msg_.find("wrong exception type"), std::string::npos) << msg_;     \
        EXPECT_NE(msg_, "no exception");                                             \
    } while (0)

// ---------------------------------------------------------------------------------------------
// Round trips through ITK writers and readers.

Geometry test_geometry() {
    Geometry g;
    g.dims = {5, 4, 3};
    g.spacing = {0.5, 0.7, 1.3};
    g.origin = {-10, 20, 5};
    // Rotation by 90 degrees about z (x axis -> +y, y axis -> -x) and a flipped z axis.
    g.direction = {0, -1, 0, 1, 0, 0, 0, 0, -1};
    return g;
}

template <class T>
Volume<T> test_volume(double scale, double offset) {
    Volume<T> v(test_geometry());
    for (size_t i = 0; i < v.size(); ++i) v[i] = static_cast<T>(offset + scale * static_cast<double>(i % 53));
    return v;
}

template <class T>
void check_round_trip(const Volume<T>& v, const std::string& ext, const std::string& type) {
    TempDir dir("roundtrip_" + type + "_" + ext.substr(1));
    const std::string path = dir / ("vol" + ext);
    write_volume(v, path);
    const ReadResult r = read_volume({path});
    const Geometry& a = v.geometry();
    const Geometry& b = r.volume.geometry();
    EXPECT_EQ(b.dims, a.dims) << ext;
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(b.spacing[i], a.spacing[i], 1e-6) << ext << " spacing " << i;
        EXPECT_NEAR(b.origin[i], a.origin[i], 1e-6) << ext << " origin " << i;
    }
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(b.direction[i], a.direction[i], 1e-6) << ext << " dir " << i;
    EXPECT_EQ(r.info.voxel_type, type) << ext;
    EXPECT_EQ(r.info.files_read, 1u);
    ASSERT_EQ(r.volume.size(), v.size());
    size_t diff = 0;
    for (size_t i = 0; i < v.size(); ++i)
        if (r.volume[i] != static_cast<float>(v[i])) ++diff;
    EXPECT_EQ(diff, 0u) << ext;
    // Nothing but the written file(s) is left in the directory.
    for (const auto& e : dir.entries()) EXPECT_EQ(e.rfind("vol", 0), 0u) << "left over: " << e;
}

}  // namespace

TEST(IoRoundTrip, FloatKeepsGeometryAndVoxels) {
    const auto v = test_volume<float>(0.25, -100.5);
    for (const char* ext : {".nrrd", ".nii.gz", ".mha", ".nii", ".nhdr", ".mhd"})
        check_round_trip(v, ext, "float32");
}

TEST(IoRoundTrip, Int16AndUInt8) {
    const auto s = test_volume<int16_t>(37, -1024);
    const auto u = test_volume<uint8_t>(3, 1);
    for (const char* ext : {".nrrd", ".nii.gz", ".mha"}) {
        check_round_trip(s, ext, "int16");
        check_round_trip(u, ext, "uint8");
    }
}

TEST(IoRoundTrip, FormatNamesAndDeterministicBytes) {
    TempDir dir("formats");
    const auto v = test_volume<uint8_t>(1, 0);
    const std::map<std::string, std::string> formats = {
        {".nrrd", "nrrd"}, {".nii.gz", "nifti"}, {".mha", "metaimage"}};
    for (const auto& [ext, name] : formats) {
        write_volume(v, dir / ("a" + ext));
        write_volume(v, dir / ("b" + ext));
        EXPECT_EQ(read_volume({dir / ("a" + ext)}).info.format, name);
        EXPECT_EQ(read_bytes(dir / ("a" + ext)), read_bytes(dir / ("b" + ext))) << ext;
    }
}

TEST(IoRoundTrip, OverwritesExistingFile) {
    TempDir dir("overwrite");
    write_volume(test_volume<uint8_t>(1, 0), dir / "v.nrrd");
    write_volume(test_volume<uint8_t>(2, 0), dir / "v.nrrd");
    const auto r = read_volume({dir / "v.nrrd"});
    EXPECT_EQ(r.volume[3], 6.0f);
    EXPECT_EQ(dir.entries(), std::vector<std::string>{"v.nrrd"});
}

TEST(IoWrite, FailuresAreIoErrorsAndLeaveNothing) {
    TempDir dir("writefail");
    const auto v = test_volume<uint8_t>(1, 0);
    EXPECT_THROW_MSG(write_volume(v, dir / "missing/sub/v.nrrd"), IoError, "v.nrrd");
    EXPECT_THROW_MSG(write_volume(v, dir / "v.xyz"), IoError, "v.xyz");
    fs::create_directory(dir / "taken.nrrd");  // the target is a directory: rename fails
    EXPECT_THROW(write_volume(v, dir / "taken.nrrd"), IoError);
    EXPECT_EQ(dir.entries(), std::vector<std::string>{"taken.nrrd"});
}

// FileBytes: a regular file mapped, its bytes as written; an empty file (nothing to map) read
// instead; a missing file nullopt; moves keep the bytes.
TEST(IoFileBytes, MappedOrReadTheFilesBytes) {
    TempDir dir("filebytes");
    std::string bytes(100000, '\0');
    for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = char((i * 7919) % 251);
    {
        std::ofstream(dir / "data.bin", std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
        std::ofstream(dir / "empty.bin", std::ios::binary);
    }
    std::optional<endocast::FileBytes> f = endocast::FileBytes::open(dir / "data.bin");
    ASSERT_TRUE(f);
    EXPECT_EQ(f->view(), bytes);
    endocast::FileBytes moved = std::move(*f);
    EXPECT_EQ(moved.view(), bytes);
    f.reset();
    EXPECT_EQ(moved.view(), bytes);
    const std::optional<endocast::FileBytes> empty = endocast::FileBytes::open(dir / "empty.bin");
    ASSERT_TRUE(empty);
    EXPECT_TRUE(empty->view().empty());
    EXPECT_FALSE(endocast::FileBytes::open(dir / "missing.bin"));
}

// ---------------------------------------------------------------------------------------------
// Errors of the ITK readers.

TEST(IoErrors, MissingFile) {
    EXPECT_THROW_MSG(read_volume({"/nonexistent/dir/scan.nrrd"}), IoError, "/nonexistent/dir/scan.nrrd");
}

TEST(IoErrors, DirectoryWithoutDicom) {
    TempDir dir("nodicom");
    write_text(dir / "notes.txt", "not a DICOM file\n");
    EXPECT_THROW_MSG(read_volume({dir.str()}), IoError, dir.str());
}

TEST(IoErrors, UnknownExtension) {
    TempDir dir("unknownext");
    write_text(dir / "scan.xyz", "something");
    EXPECT_THROW_MSG(read_volume({dir / "scan.xyz"}), IoError, "scan.xyz");
}

/// gzip bytes (one member) of `data`, as teem writes them.
std::string gzip_bytes(const std::string& data) {
    z_stream z{};
    EXPECT_EQ(deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    std::string out(deflateBound(&z, data.size()) + 64, '\0');
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    z.avail_in = static_cast<uInt>(data.size());
    z.next_out = reinterpret_cast<Bytef*>(out.data());
    z.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
    out.resize(z.total_out);
    deflateEnd(&z);
    return out;
}

/// Reads `path` with the direct NRRD / MetaImage / DICOM reader and with ITK's; both must give the same
/// geometry and the same voxels, bit for bit.
void expect_fast_equals_itk(const std::string& path, bool direct = true) {
    const ReadResult fast = read_volume({path});
    const ReadResult slow = read_volume({path}, {}, DirectReaders{false, false, false});
    EXPECT_EQ(fast.info.read_directly, direct) << path;
    EXPECT_FALSE(slow.info.read_directly) << path;
    const Geometry &a = fast.volume.geometry(), &b = slow.volume.geometry();
    EXPECT_EQ(a.dims, b.dims) << path;
    EXPECT_EQ(a.spacing, b.spacing) << path;
    EXPECT_EQ(a.origin, b.origin) << path;
    EXPECT_EQ(a.direction, b.direction) << path;
    EXPECT_EQ(fast.info.voxel_type, slow.info.voxel_type) << path;
    ASSERT_EQ(fast.volume.size(), slow.volume.size()) << path;
    EXPECT_EQ(std::memcmp(fast.volume.data(), slow.volume.data(), fast.volume.size() * sizeof(float)), 0)
        << path;
    const std::string ext = std::filesystem::path(path).extension().string();
    const bool dicom = std::filesystem::is_directory(path);
    if (!direct || (!dicom && ext != ".nrrd" && ext != ".nhdr")) return;
    // ReadOptions::int16: data of 8- or 16-bit integers (a DICOM series: values, after the rescale)
    // whose every value fits int16 comes in volume16 with the same values (the float volume only
    // its geometry); anything else as float.
    ReadOptions want16;
    want16.int16 = true;
    const ReadResult r16 = read_volume({path}, want16);
    const std::string& type = slow.info.voxel_type;
    const bool small_int = type == "int8" || type == "uint8" || type == "int16" || type == "uint16";
    bool fits = true;
    for (size_t i = 0; i < slow.volume.size(); ++i)
        fits = fits && slow.volume[i] <= 32767.0f && slow.volume[i] >= -32768.0f;
    EXPECT_EQ(r16.volume16.empty(), !((small_int || dicom) && fits)) << path << " " << type;
    EXPECT_EQ(r16.info.read_directly, true) << path;
    if (!r16.volume16.empty()) {
        EXPECT_TRUE(r16.volume.empty()) << path;
        EXPECT_EQ(r16.volume.geometry().dims, b.dims) << path;
        EXPECT_EQ(r16.volume16.geometry().origin, b.origin) << path;
        ASSERT_EQ(r16.volume16.size(), slow.volume.size()) << path;
        for (size_t i = 0; i < slow.volume.size(); ++i)
            ASSERT_EQ(float(r16.volume16[i]), slow.volume[i]) << path << " voxel " << i;
    } else {
        ASSERT_EQ(r16.volume.size(), slow.volume.size()) << path;
        EXPECT_EQ(std::memcmp(r16.volume.data(), slow.volume.data(), slow.volume.size() * sizeof(float)), 0) << path;
    }
    if (dicom) return;
    // A NRRD read in slabs (slice_source.h) of one slice, cropped to the whole grid: ITK's voxels too.
    ShrinkParams whole_box;
    whole_box.crop = CropBox{{0, 0, 0}, b.dims};
    const ReadResult slabs = read_shrunk({path}, {}, whole_box, 1);
    EXPECT_EQ(slabs.info.read_path, "slabs") << path;
    ASSERT_EQ(slabs.volume.size(), slow.volume.size()) << path;
    EXPECT_EQ(slabs.volume.geometry().origin, b.origin) << path;
    EXPECT_EQ(std::memcmp(slabs.volume.data(), slow.volume.data(), slow.volume.size() * sizeof(float)), 0)
        << path << " read in slabs";
}

/// One CT slice written as a DICOM file from scratch (implicit or explicit VR little endian).
struct DicomSlice {
    bool explicit_vr = false;
    int rows = 6, columns = 5, bits_stored = 12, pixel_representation = 0;
    std::string slope = "1", intercept = "-1024", photometric = "MONOCHROME2";
    double z = 0;
    int instance = 1;
    bool nested_sequence = false;  ///< a sequence of undefined length holding a decoy Rows
    std::vector<uint16_t> pixels;  ///< rows * columns stored words
};

void write_dicom(const std::string& path, const DicomSlice& s) {
    auto u16 = [](uint16_t v) { return std::string{char(v & 0xFF), char(v >> 8)}; };
    auto u32 = [](uint32_t v) {
        return std::string{char(v & 0xFF), char((v >> 8) & 0xFF), char((v >> 16) & 0xFF), char(v >> 24)};
    };
    auto element = [&](bool expl, uint16_t g, uint16_t e, const char* vr, std::string v) {
        if (v.size() % 2) v += std::strcmp(vr, "UI") == 0 ? '\0' : ' ';
        std::string o = u16(g) + u16(e);
        const std::string r(vr);
        const bool long_form = r == "OB" || r == "OW" || r == "SQ" || r == "UN" || r == "UT";
        if (!expl) o += u32(uint32_t(v.size()));
        else if (long_form) o += std::string(vr) + u16(0) + u32(uint32_t(v.size()));
        else o += std::string(vr) + u16(uint16_t(v.size()));
        return o + v;
    };
    const std::string ct = "1.2.840.10008.5.1.4.1.1.2";
    const std::string uid = "1.2.3.4.5." + std::to_string(s.instance);
    const std::string syntax = s.explicit_vr ? "1.2.840.10008.1.2.1" : "1.2.840.10008.1.2";
    std::string meta = element(true, 2, 1, "OB", std::string("\0\1", 2)) + element(true, 2, 2, "UI", ct) +
                       element(true, 2, 3, "UI", uid) + element(true, 2, 0x10, "UI", syntax) +
                       element(true, 2, 0x12, "UI", "1.2.3.4");
    meta = element(true, 2, 0, "UL", u32(uint32_t(meta.size()))) + meta;
    const bool x = s.explicit_vr;
    std::string ds = element(x, 8, 0x16, "UI", ct) + element(x, 8, 0x18, "UI", uid) + element(x, 8, 0x60, "CS", "CT");
    if (s.nested_sequence) {
        // (0008,1140) SQ, undefined length: one item of undefined length holding Rows = 99.
        ds += u16(8) + u16(0x1140) + (x ? std::string("SQ") + u16(0) : std::string()) + u32(0xFFFFFFFF);
        ds += u16(0xFFFE) + u16(0xE000) + u32(0xFFFFFFFF);
        ds += element(x, 0x28, 0x10, "US", u16(99));
        ds += u16(0xFFFE) + u16(0xE00D) + u32(0);
        ds += u16(0xFFFE) + u16(0xE0DD) + u32(0);
    }
    std::ostringstream pos;
    pos << "-10.5\\4.25\\" << s.z;
    ds += element(x, 0x20, 0xD, "UI", "1.2.3.4.1") + element(x, 0x20, 0xE, "UI", "1.2.3.4.2") +
          element(x, 0x20, 0x13, "IS", std::to_string(s.instance)) + element(x, 0x20, 0x32, "DS", pos.str()) +
          element(x, 0x20, 0x37, "DS", "1\\0\\0\\0\\1\\0") + element(x, 0x28, 2, "US", u16(1)) +
          element(x, 0x28, 4, "CS", s.photometric) + element(x, 0x28, 0x10, "US", u16(uint16_t(s.rows))) +
          element(x, 0x28, 0x11, "US", u16(uint16_t(s.columns))) + element(x, 0x28, 0x30, "DS", "0.5\\0.75") +
          element(x, 0x28, 0x100, "US", u16(16)) + element(x, 0x28, 0x101, "US", u16(uint16_t(s.bits_stored))) +
          element(x, 0x28, 0x102, "US", u16(uint16_t(s.bits_stored - 1))) +
          element(x, 0x28, 0x103, "US", u16(uint16_t(s.pixel_representation))) +
          element(x, 0x28, 0x1052, "DS", s.intercept) + element(x, 0x28, 0x1053, "DS", s.slope);
    std::string px;
    for (uint16_t v : s.pixels) px += u16(v);
    ds += element(x, 0x7FE0, 0x10, "OW", px);
    write_text(path, std::string(128, '\0') + "DICM" + meta + ds);
}

/// Three slices of `s` (pixels varied per slice) in a new directory under `dir`.
std::string write_dicom_series(const TempDir& dir, const std::string& name, DicomSlice s) {
    const fs::path d = dir / name;
    fs::create_directories(d);
    for (int k = 0; k < 3; ++k) {
        s.instance = k + 1;
        s.z = 1.5 * k;
        s.pixels.resize(size_t(s.rows * s.columns));
        // Every bit pattern class: high (overlay) bits set, the sign bit of a 12-bit value set,
        // small and large values.
        for (size_t i = 0; i < s.pixels.size(); ++i)
            s.pixels[i] = uint16_t(i * 2654435761u + 977u * unsigned(k));
        write_dicom((d / ("s" + std::to_string(k) + ".dcm")).string(), s);
    }
    return d.string();
}

TEST(IoDicomDirect, SameVoxelsAsGdcm) {
    TempDir dir("dicomdirect");
    int n = 0;
    for (bool expl : {false, true})
        for (int rep : {0, 1})
            for (int bits : {12, 16})
                for (const auto& [slope, intercept] :
                     {std::pair<std::string, std::string>{"1", "-1024"}, {"2", "7"}, {"1", "0"}}) {
                    DicomSlice s;
                    s.explicit_vr = expl;
                    s.pixel_representation = rep;
                    s.bits_stored = bits;
                    s.slope = slope;
                    s.intercept = intercept;
                    s.nested_sequence = (n % 2) == 1;
                    SCOPED_TRACE("explicit " + std::to_string(expl) + " signed " + std::to_string(rep) + " bits " +
                                 std::to_string(bits) + " slope " + slope + " intercept " + intercept);
                    expect_fast_equals_itk(write_dicom_series(dir, "s" + std::to_string(n++), s));
                }
}

TEST(IoDicomDirect, LeavesOtherSlicesToGdcm) {
    TempDir dir("dicomdirect2");
    DicomSlice s;
    s.slope = "0.5";  // values no longer integers: GDCM's rounding is its own
    expect_fast_equals_itk(write_dicom_series(dir, "slope", s), false);
    s = DicomSlice{};
    s.photometric = "MONOCHROME1";
    expect_fast_equals_itk(write_dicom_series(dir, "mono1", s), false);
    s = DicomSlice{};
    s.bits_stored = 8;  // in 16 allocated bits, still the direct reader's case
    expect_fast_equals_itk(write_dicom_series(dir, "bits8", s));
}

/// `n` voxels of `bytes` bytes each (integers, or floats when `is_float`), big-endian when `big`:
/// values that use the type's range and, for floats, fractions.
std::string typed_bytes(size_t n, size_t bytes, bool is_float, bool big) {
    std::string data(n * bytes, '\0');
    for (size_t i = 0; i < n; ++i) {
        unsigned char b[8] = {};
        if (is_float && bytes == 4) {
            const float v = float(i) * 1.25f - 40.5f;
            std::memcpy(b, &v, 4);
        } else if (is_float) {
            const double v = double(i) * 3.5 - 99.25;
            std::memcpy(b, &v, 8);
        } else {
            for (size_t j = 0; j < bytes; ++j) b[j] = uint8_t(i * 37 + j * 101 + 3);
        }
        if (big) std::reverse(b, b + bytes);
        std::memcpy(&data[i * bytes], b, bytes);
    }
    return data;
}

TEST(IoNrrdFast, SameVoxelsAsItkForEveryTypeEncodingAndLayout) {
    TempDir dir("nrrdfast");
    struct Type {
        const char* nrrd;
        size_t bytes;
        bool is_float;
    };
    const Type types[] = {{"uint8", 1, false},  {"int8", 1, false},  {"int16", 2, false},
                          {"uint16", 2, false}, {"int32", 4, false}, {"uint32", 4, false},
                          {"float", 4, true},   {"double", 8, true}};
    const size_t nx = 7, ny = 5, nz = 4, n = nx * ny * nz;
    int k = 0;
    for (const Type& t : types)
        for (const char* endian : {"little", "big"})
            for (const char* encoding : {"raw", "gzip"})
                for (bool detached : {false, true}) {
                    const std::string data = typed_bytes(n, t.bytes, t.is_float, std::string(endian) == "big");
                    const bool gz = std::string(encoding) == "gzip";
                    const std::string payload = gz ? gzip_bytes(data) : data;
                    std::string header = std::string("NRRD0004\n# a comment\ntype: ") + t.nrrd +
                                         "\ndimension: 3\nspace: right-anterior-superior\nsizes: 7 5 4\n"
                                         "space directions: (0.5,0,0) (0,0.75,0) (0,0,2)\n"
                                         "space origin: (10,-20,30)\nkinds: domain domain domain\n"
                                         "endian: " + endian + "\nencoding: " + encoding + "\n";
                    const std::string name = "v" + std::to_string(k++);
                    if (detached) {
                        write_text(dir / (name + ".nhdr"), header + "data file: " + name + ".dat\n");
                        write_text(dir / (name + ".dat"), payload);
                        expect_fast_equals_itk(dir / (name + ".nhdr"));
                    } else {
                        write_text(dir / (name + ".nrrd"), header + "\n" + payload);
                        expect_fast_equals_itk(dir / (name + ".nrrd"));
                    }
                }
}

TEST(IoNrrdFast, TwoGzipMembersAndWhatItLeavesToItk) {
    TempDir dir("nrrdfast2");
    std::string data(6 * 6 * 6, '\0');
    for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 7);
    const std::string head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 6 6 6\nspacings: 1 1 1.5\n";
    // A gzip file of two members (zlib's gzread, in ITK, reads both).
    write_text(dir / "two.nrrd", head + "encoding: gzip\n\n" + gzip_bytes(data.substr(0, 100)) +
                                     gzip_bytes(data.substr(100)));
    expect_fast_equals_itk(dir / "two.nrrd");
    // Left to ITK: a byte skip, a line skip.
    write_text(dir / "skip.nrrd", head + "encoding: raw\nbyte skip: 3\n\nabc" + data);
    expect_fast_equals_itk(dir / "skip.nrrd", false);
    write_text(dir / "skip.nhdr", head + "encoding: raw\nline skip: 1\ndata file: skip.dat\n");
    write_text(dir / "skip.dat", "a text line\n" + data);
    expect_fast_equals_itk(dir / "skip.nhdr", false);
    // Data shorter or longer than the header says: ITK's error, naming the file.
    write_text(dir / "short.nrrd", head + "encoding: gzip\n\n" + gzip_bytes(data.substr(0, 100)));
    EXPECT_THROW_MSG(read_volume({dir / "short.nrrd"}), IoError, "short.nrrd");
    write_text(dir / "shortraw.nrrd", head + "encoding: raw\n\n" + data.substr(0, 100));
    EXPECT_THROW_MSG(read_volume({dir / "shortraw.nrrd"}), IoError, "shortraw.nrrd");
}

// A .nrrd is written with gzip data in members of 4 MiB, each indexed by its size in an extra
// subfield, compressed and inflated on all threads: ITK (zlib) reads it as any gzip, the same bytes
// for 1 and 2 threads, a corrupt member is ITK's error naming the file.
TEST(IoNrrdFast, IndexedGzipMembersReadAsItkReadsThem) {
    TempDir dir("nrrdmembers");
    Volume<float> v(endocast::testing::grid(128, 128, 160, {0.5, 0.5, 0.8}));
    for (size_t i = 0; i < v.size(); ++i) v[i] = float(int64_t(i * 2654435761u % 4001) - 2000) * 0.25f;
    write_volume(v, dir / "a.nrrd");
    expect_fast_equals_itk(dir / "a.nrrd");
    const ReadResult r = read_volume({dir / "a.nrrd"});
    ASSERT_EQ(r.volume.size(), v.size());
    EXPECT_EQ(std::memcmp(r.volume.data(), v.data(), v.size() * sizeof(float)), 0);
    // Three members (10.5 MB of floats), each's size in its "EC" subfield, ending at the file's end.
    const std::vector<uint8_t> raw = read_bytes(dir / "a.nrrd");
    const std::string bytes(raw.begin(), raw.end());
    size_t at = bytes.find("\n\n") + 2, members = 0;
    while (at + 20 <= bytes.size()) {
        ASSERT_EQ(bytes.substr(at, 4), std::string("\x1f\x8b\x08\x04", 4));
        ASSERT_EQ(bytes.substr(at + 12, 2), "EC");
        uint32_t n = 0;
        for (int k = 3; k >= 0; --k) n = n << 8 | uint8_t(bytes[at + 16 + size_t(k)]);
        at += n;
        ++members;
    }
    EXPECT_EQ(at, bytes.size());
    EXPECT_EQ(members, 3u);
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    write_volume(v, dir / "b.nrrd");
    omp_set_num_threads(threads);
    EXPECT_EQ(read_bytes(dir / "b.nrrd"), raw);
    // The indexed members inflate on all threads; a zlib stream without the index, a member size
    // past the end, or fewer bytes than asked are left to the serial inflate (false).
    const unsigned char* data = reinterpret_cast<const unsigned char*>(bytes.data()) + bytes.find("\n\n") + 2;
    const size_t stored = bytes.size() - (bytes.find("\n\n") + 2), want = v.size() * sizeof(float);
    std::string out(want, '\0');
    EXPECT_TRUE(inflate_gzip_members(data, stored, out.data(), want));
    EXPECT_EQ(std::memcmp(out.data(), v.data(), want), 0);
    EXPECT_FALSE(inflate_gzip_members(data, stored - 1, out.data(), want));
    EXPECT_FALSE(inflate_gzip_members(data, stored, out.data(), want - 1));
    const std::string plain = gzip_bytes(std::string(reinterpret_cast<const char*>(v.data()), want));
    EXPECT_FALSE(inflate_gzip_members(reinterpret_cast<const unsigned char*>(plain.data()), plain.size(), out.data(), want));
    // A byte of the second member's deflate data changed: its CRC fails, the file is refused.
    std::string bad = bytes;
    const size_t first = bytes.find("\n\n") + 2;
    uint32_t first_size = 0;
    for (int k = 3; k >= 0; --k) first_size = first_size << 8 | uint8_t(bytes[first + 16 + size_t(k)]);
    const size_t second = first + first_size;
    bad[second + 1000] = char(bad[second + 1000] ^ 0x5a);
    write_text(dir / "bad.nrrd", bad);
    EXPECT_THROW_MSG(read_volume({dir / "bad.nrrd"}), IoError, "bad.nrrd");
}

/// zlib bytes of `data`, as MetaIO writes CompressedData.
std::string zlib_bytes(const std::string& data) {
    uLongf n = compressBound(uLong(data.size()));
    std::string out(n, '\0');
    EXPECT_EQ(compress2(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(data.data()),
                        uLong(data.size()), 6),
              Z_OK);
    out.resize(n);
    return out;
}

/// A MetaImage header of a 7 x 5 x 4 volume, up to and without its ElementDataFile line.
std::string mha_header(const std::string& type, bool msb, const std::string& extra = "") {
    return "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = " +
           std::string(msb ? "True" : "False") +
           "\nTransformMatrix = 0 1 0 -1 0 0 0 0 1\nOffset = 10 -20 30\nElementSpacing = 0.5 0.75 2\n"
           "DimSize = 7 5 4\n" + extra + "ElementType = " + type + "\n";
}

TEST(IoMetaImageDirect, SameVoxelsAsItkForEveryTypeCompressionAndLayout) {
    TempDir dir("mhadirect");
    struct Type {
        const char* met;
        size_t bytes;
        bool is_float;
    };
    const Type types[] = {{"MET_UCHAR", 1, false}, {"MET_CHAR", 1, false},  {"MET_SHORT", 2, false},
                          {"MET_USHORT", 2, false}, {"MET_INT", 4, false},  {"MET_UINT", 4, false},
                          {"MET_FLOAT", 4, true},   {"MET_DOUBLE", 8, true},  {"MET_LONG", 4, false},
                          {"MET_ULONG", 4, false},  {"MET_LONG_LONG", 8, false}, {"MET_ULONG_LONG", 8, false}};
    const size_t n = 7 * 5 * 4;
    int k = 0;
    for (const Type& t : types)
        for (bool msb : {false, true})
            for (int packing = 0; packing < 3; ++packing)  // raw, zlib (CompressedDataSize), zlib without size
                for (bool detached : {false, true}) {
                    const std::string data = typed_bytes(n, t.bytes, t.is_float, msb);
                    const std::string payload = packing ? zlib_bytes(data) : data;
                    const std::string extra =
                        packing == 0 ? "" : packing == 1 ? "CompressedData = True\nCompressedDataSize = " +
                                                               std::to_string(payload.size()) + "\n"
                                                         : "CompressedData = True\n";
                    const std::string name = "m" + std::to_string(k++);
                    const std::string head = mha_header(t.met, msb, extra);
                    if (detached) {
                        write_text(dir / (name + ".mhd"), head + "ElementDataFile = " + name + ".raw\n");
                        write_text(dir / (name + ".raw"), payload);
                        expect_fast_equals_itk(dir / (name + ".mhd"));
                    } else if (packing < 2) {
                        write_text(dir / (name + ".mha"), head + "ElementDataFile = LOCAL\n" + payload);
                        expect_fast_equals_itk(dir / (name + ".mha"));
                    } else {
                        // LOCAL compressed data without CompressedDataSize: ITK 5.2 inflates from the
                        // file's first byte (the header) and fails; read here as the rest of the file.
                        write_text(dir / (name + ".mha"), head + "ElementDataFile = LOCAL\n" + payload);
                        write_text(dir / (name + "raw.mha"), mha_header(t.met, msb) + "ElementDataFile = LOCAL\n" + data);
                        const ReadResult a = read_volume({dir / (name + ".mha")});
                        const ReadResult b = read_volume({dir / (name + "raw.mha")});
                        EXPECT_TRUE(a.info.read_directly);
                        ASSERT_EQ(a.volume.size(), b.volume.size());
                        EXPECT_EQ(std::memcmp(a.volume.data(), b.volume.data(), a.volume.size() * sizeof(float)), 0)
                            << name;
                    }
                }
}

TEST(IoMetaImageDirect, HeaderSizeGzipDataFileAsciiSlicePatternAndList) {
    TempDir dir("mhadirect2");
    std::string data(7 * 5 * 4, '\0');
    for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 7 + 1);
    const std::string head = mha_header("MET_UCHAR", false);
    // HeaderSize: skip that many bytes of the data file; -1: the data are its last bytes.
    write_text(dir / "skip.mhd", mha_header("MET_UCHAR", false, "HeaderSize = 5\n") + "ElementDataFile = skip.raw\n");
    write_text(dir / "skip.raw", "abcde" + data + "tail");
    expect_fast_equals_itk(dir / "skip.mhd");
    write_text(dir / "end.mhd", mha_header("MET_UCHAR", false, "HeaderSize = -1\n") + "ElementDataFile = end.raw\n");
    write_text(dir / "end.raw", "a header of some other program" + data);
    expect_fast_equals_itk(dir / "end.mhd");
    // A data file NAME that is missing is read as NAME.gz, compressed (as MetaIO does).
    write_text(dir / "gz.mhd", head + "ElementDataFile = gz.raw\n");
    write_text(dir / "gz.raw.gz", gzip_bytes(data));
    expect_fast_equals_itk(dir / "gz.mhd");
    // ASCII voxels (BinaryData = False): one separator character after each number, as MetaIO reads.
    std::string ascii;
    for (size_t i = 0; i < data.size(); ++i)
        ascii += std::to_string(int(uint8_t(data[i])) - 100) + (i % 7 == 6 ? "\n" : i % 2 ? "," : " ");
    write_text(dir / "ascii.mha", "ObjectType = Image\nNDims = 3\nBinaryData = False\nDimSize = 7 5 4\n"
                                  "ElementType = MET_SHORT\nElementDataFile = LOCAL\n" + ascii);
    expect_fast_equals_itk(dir / "ascii.mha");
    write_text(dir / "ascii64.mha", "ObjectType = Image\nNDims = 3\nBinaryData = False\nDimSize = 7 5 4\n"
                                    "ElementType = MET_LONG_LONG\nElementDataFile = LOCAL\n" + ascii);
    expect_fast_equals_itk(dir / "ascii64.mha");
    write_text(dir / "asciif.mhd", "ObjectType = Image\nNDims = 3\nBinaryData = False\nDimSize = 7 5 4\n"
                                   "ElementType = MET_FLOAT\nElementDataFile = asciif.txt\n");
    std::string floats;
    for (size_t i = 0; i < data.size(); ++i) floats += std::to_string(double(i) * 0.37 - 5.5) + "  \n";
    write_text(dir / "asciif.txt", floats);
    expect_fast_equals_itk(dir / "asciif.mhd");
    // Slice files: a pattern (with and without FIRST LAST STEP) and a LIST.
    write_text(dir / "pat.mhd", head + "ElementDataFile = pat%d.raw 2 8 2\n");
    write_text(dir / "pat1.mhd", head + "ElementDataFile = pat%d.raw\n");
    std::string names;
    for (int z = 1; z <= 4; ++z) {
        write_text(dir / ("pat" + std::to_string(2 * z) + ".raw"), data.substr(size_t(z - 1) * 35, 35));
        write_text(dir / ("pat" + std::to_string(z) + ".raw"), data.substr(size_t(4 - z) * 35, 35));
        names += "pat" + std::to_string(2 * z) + ".raw\n";
    }
    expect_fast_equals_itk(dir / "pat.mhd");
    expect_fast_equals_itk(dir / "pat1.mhd");
    write_text(dir / "list.mha", head + "ElementDataFile = LIST\n" + names);
    expect_fast_equals_itk(dir / "list.mha");
    EXPECT_EQ(std::memcmp(read_volume({dir / "list.mha"}).volume.data(), read_volume({dir / "pat.mhd"}).volume.data(),
                          data.size() * sizeof(float)),
              0);
}

TEST(IoMetaImageDirect, WhatItkWritesCompressedOrNotLocalOrDetached) {
    // MetaImages as ITK 5.2 (3D Slicer, elastix) writes them: CompressedDataSize, .zraw, geometry.
    TempDir dir("mhaitk");
    using Image = itk::Image<int16_t, 3>;
    auto img = Image::New();
    Image::RegionType region;
    region.SetSize({{9, 6, 5}});
    img->SetRegions(region);
    img->Allocate();
    const double spacing[3] = {0.4, 0.45, 1.25}, origin[3] = {-12.5, 30, 7};
    img->SetSpacing(spacing);
    img->SetOrigin(origin);
    Image::DirectionType dir_m;
    dir_m.SetIdentity();
    dir_m(0, 0) = 0.8;
    dir_m(1, 0) = 0.6;
    dir_m(0, 1) = -0.6;
    dir_m(1, 1) = 0.8;
    img->SetDirection(dir_m);
    int16_t* p = img->GetBufferPointer();
    for (size_t i = 0; i < 9 * 6 * 5; ++i) p[i] = int16_t(int(i * 397 % 4000) - 1024);
    for (const char* name : {"a.mha", "b.mhd", "c.mha", "d.mhd"}) {
        auto w = itk::ImageFileWriter<Image>::New();
        w->SetImageIO(itk::MetaImageIO::New());
        w->SetFileName(dir / name);
        w->SetInput(img);
        w->SetUseCompression(name[0] == 'c' || name[0] == 'd');
        w->Update();
        expect_fast_equals_itk(dir / name);
    }
}

TEST(IoMetaImageHeader, ReadsTheFieldsAsMetaIoDoes) {
    // Our header reader (metaimage_header.cpp) against ITK's MetaIO on the forms real files use:
    // synonyms (ElementSize, Position, Origin, Rotation, Orientation, ElementByteOrderMSB), ':' as
    // separator, CRLF line ends, blank lines, fields in another order, unknown fields, extra blanks.
    TempDir dir("mhaheader");
    std::string data(7 * 5 * 4 * 2, '\0');
    for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 29 + 3);
    const std::string tail = "ElementType = MET_SHORT\nElementDataFile = LOCAL\n";
    const std::string heads[] = {
        "ObjectType = Image\nNDims = 3\nDimSize = 7 5 4\nElementSize = 0.5 0.6 0.7\nPosition = 1 2 3\n"
        "Rotation = 0 0 1 0 1 0 -1 0 0\nElementByteOrderMSB = True\n",
        "NDims: 3\nDimSize: 7 5 4\nOrigin: -1.5 2e1 3\nOrientation: 1 0 0 0 0.6 0.8 0 -0.8 0.6\n",
        "ObjectType = Image\r\nNDims = 3\r\n\r\nDimSize = 7 5 4\r\nElementSpacing = 1 1 2\r\n",
        "  NDims   =   3  \nDimSize = 7 5 4\nAnatomicalOrientation = RAI\nCenterOfRotation = 0 0 0\n"
        "Comment = anything = here: at all\nITK_InputFilterName = MetaImageIO\nElementSpacing = 0.25 0.25 0.5\n"
        "ElementSize = 9 9 9\nBinaryDataByteOrderMSB = False\n",
        // An orientation code without a matrix: ITK keeps the identity (so do we).
        "NDims = 3\nDimSize = 7 5 4\nAnatomicalOrientation = LPI\nElementNumberOfChannels = 1\nHeaderSize = 0\n",
    };
    int k = 0;
    for (const std::string& head : heads) {
        const std::string name = "h" + std::to_string(k++) + ".mha";
        write_text(dir / name, head + tail + data);
        expect_fast_equals_itk(dir / name);
    }
    // The same in CRLF up to the data: the data start after the ElementDataFile line's '\n'.
    write_text(dir / "crlf.mha", "NDims = 3\r\nDimSize = 7 5 4\r\nElementType = MET_SHORT\r\nElementDataFile = LOCAL\r\n" + data);
    expect_fast_equals_itk(dir / "crlf.mha");
    // A negative spacing: ITK makes it positive and reverses that axis.
    write_text(dir / "neg.mha", "NDims = 3\nDimSize = 7 5 4\nElementSpacing = 1 -2 3\n"
                                "TransformMatrix = 0 1 0 -1 0 0 0 0 1\n" + tail + data);
    expect_fast_equals_itk(dir / "neg.mha");
    // Four dimensions of which the last is 1 (a 3-D volume to ITK as well, its matrix dropped).
    write_text(dir / "four.mha", "NDims = 4\nDimSize = 7 5 4 1\nElementSpacing = 1 2 3 4\nOffset = 1 2 3 4\n"
                                 "TransformMatrix = 0 1 0 0 1 0 0 0 0 0 1 0 0 0 0 1\n" + tail + data);
    expect_fast_equals_itk(dir / "four.mha");
}

TEST(IoMetaImageHeader, RefusesWhatIsNotAHeaderNamingTheLine) {
    TempDir dir("mhaheaderbad");
    const std::string data(7 * 5 * 4, '\1');
    const auto refused = [&](const std::string& name, const std::string& head, const std::string& what) {
        write_text(dir / name, head + data);
        EXPECT_THROW_MSG(read_volume({dir / name}), Error, what);
    };
    const std::string ok = "NDims = 3\nDimSize = 7 5 4\nElementType = MET_UCHAR\n";
    refused("word.mha", "NDims = 3\nDimSize = 7 5 4\njust words\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "header line 3 'just words' is not a field");
    refused("ctl.mha", "NDims = 3\nDimSize = 7 5\x02 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "header line 2 holds the control character 0x02");
    refused("twice.mha", ok + "ElementType = MET_SHORT\nElementDataFile = LOCAL\n",
            "line 4 gives ElementType = MET_SHORT after line 3 gave MET_UCHAR, expected each field once");
    refused("count.mha", "NDims = 3\nDimSize = 7 5 4 1\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "line 2: DimSize = 7 5 4 1 holds 4 values, expected 3 (from NDims)");
    refused("matrix.mha", ok + "TransformMatrix = 1 0 0 0 1 0 0 0\nElementDataFile = LOCAL\n",
            "TransformMatrix = 1 0 0 0 1 0 0 0 holds 8 values, expected 9");
    refused("nan.mha", ok + "ElementSpacing = 1 nan 1\nElementDataFile = LOCAL\n",
            "line 4: ElementSpacing holds 'nan', expected a finite number");
    refused("frac.mha", "NDims = 3\nDimSize = 7 5.5 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "DimSize holds '5.5', expected a whole number");
    refused("nondims.mha", "DimSize = 7 5 4\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "declares NDims = nothing, expected a number of dimensions from 1 to 16");
    refused("nodims.mha", "NDims = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n", "has no DimSize");
    refused("notype.mha", "NDims = 3\nDimSize = 7 5 4\nElementDataFile = LOCAL\n", "has no ElementType");
    refused("type.mha", "NDims = 3\nDimSize = 7 5 4\nElementType = MET_STRING\nElementDataFile = LOCAL\n",
            "ElementType = MET_STRING is not supported");
    write_text(dir / "nofile.mha", "NDims = 3\nDimSize = 7 5 4\nElementType = MET_UCHAR\n");
    EXPECT_THROW_MSG(read_volume({dir / "nofile.mha"}), IoError, "has no ElementDataFile line");
    refused("flat.mha", "NDims = 2\nDimSize = 7 5\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "image has 2 dimensions (7 x 5), expected a 3-D volume");
    refused("rgb.mha", ok + "ElementNumberOfChannels = 3\nElementDataFile = LOCAL\n", "3 components per voxel");
    refused("singular.mha", ok + "TransformMatrix = 1 0 0 1 0 0 0 0 1\nElementDataFile = LOCAL\n",
            "TransformMatrix (1, 0, 1)... is singular");
    refused("skip.mha", ok + "HeaderSize = -2\nElementDataFile = LOCAL\n", "HeaderSize = -2");
    refused("big.mha", ok + "CompressedDataSize = 9223372036854775807\nElementDataFile = LOCAL\n",
            "CompressedDataSize holds '9223372036854775807', expected a whole number (of at most 2^53)");
    refused("zsize.mha", ok + "CompressedData = True\nCompressedDataSize = -5\nElementDataFile = LOCAL\n",
            "CompressedDataSize = -5");
    // Refused before anything is allocated: the declared size is checked first.
    refused("huge.mha", "NDims = 3\nDimSize = 100000 100000 100000\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
            "huge.mha");
}

TEST(IoMetaImageHeader, EveryFuzzReproducerIsRefusedOrReadByUs) {
    // Every MetaImage fuzz reproducer (each once crashed or misled MetaIO) is refused with an
    // endocast::Error naming the file, or read by our own reader (read_directly), never by ITK.
    const std::string corpus = std::string(ENDOCAST_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_mhd";
    int files = 0;
    for (const auto& e : std::filesystem::directory_iterator(corpus)) {
        if (e.path().filename().string().rfind("regress_", 0) != 0) continue;
        ++files;
        try {
            const ReadResult r = read_volume({e.path().string()});
            EXPECT_TRUE(r.info.read_directly) << e.path();
        } catch (const Error& err) {
            EXPECT_NE(std::string(err.what()).find(e.path().filename().string()), std::string::npos) << err.what();
        }
    }
    EXPECT_GE(files, 15);
}

TEST(IoErrors, TruncatedOrShortMetaImageDataIsAnIoError) {
    // ITK 5.2's MetaIO prints "data not read completely" (or "Uncompress failed") and returns
    // success: the voxels it did not read were uninitialised memory (found by fuzz_mhd under
    // valgrind). Each case is an IoError naming the file.
    TempDir dir("mhashort");
    std::string data(7 * 5 * 4 * 2, '\0');
    for (size_t i = 0; i < data.size(); ++i) data[i] = char(i * 13 + 5);
    const std::string head = mha_header("MET_USHORT", false);
    write_text(dir / "local.mha", head + "ElementDataFile = LOCAL\n" + data.substr(0, 199));
    EXPECT_THROW_MSG(read_volume({dir / "local.mha"}), IoError, "holds 199 bytes of voxel data from byte");
    write_text(dir / "det.mhd", head + "ElementDataFile = det.raw\n");
    write_text(dir / "det.raw", data.substr(0, 100));
    EXPECT_THROW_MSG(read_volume({dir / "det.mhd"}), IoError, "det.raw: holds 100 bytes of voxel data");
    write_text(dir / "end.mhd", mha_header("MET_USHORT", false, "HeaderSize = -1\n") + "ElementDataFile = end.raw\n");
    write_text(dir / "end.raw", data.substr(1));
    EXPECT_THROW_MSG(read_volume({dir / "end.mhd"}), IoError, "file truncated");
    const std::string z = zlib_bytes(data);
    const std::string zhead = mha_header("MET_USHORT", false, "CompressedData = True\nCompressedDataSize = " +
                                                                  std::to_string(z.size()) + "\n");
    write_text(dir / "cut.mha", zhead + "ElementDataFile = LOCAL\n" + z.substr(0, z.size() / 2));
    EXPECT_THROW_MSG(read_volume({dir / "cut.mha"}), IoError, "bytes of CompressedDataSize");
    write_text(dir / "cut2.mha", mha_header("MET_USHORT", false, "CompressedData = True\n") +
                                     "ElementDataFile = LOCAL\n" + z.substr(0, z.size() / 2));
    EXPECT_THROW_MSG(read_volume({dir / "cut2.mha"}), IoError, "do not inflate");
    const std::string zshort = zlib_bytes(data.substr(0, 150));
    write_text(dir / "few.mha", mha_header("MET_USHORT", false, "CompressedData = True\n") +
                                    "ElementDataFile = LOCAL\n" + zshort);
    EXPECT_THROW_MSG(read_volume({dir / "few.mha"}), IoError, "inflate to 150 bytes, expected 280");
    // The data file is a directory (MetaIO opened it and read nothing).
    std::filesystem::create_directory(dir / "folder.raw");
    write_text(dir / "folder.mhd", head + "ElementDataFile = folder.raw\n");
    EXPECT_THROW_MSG(read_volume({dir / "folder.mhd"}), IoError, "is not a regular file");
    write_text(dir / "none.mhd", head + "ElementDataFile = none.raw\n");
    EXPECT_THROW_MSG(read_volume({dir / "none.mhd"}), IoError, "does not exist");
    // A slice file missing or short (MetaIO: "cannot construct file", the slice uninitialised), a
    // pattern naming fewer slices than DimSize, a LIST with too few names.
    for (int z = 1; z <= 3; ++z) write_text(dir / ("s" + std::to_string(z) + ".raw"), data.substr(0, 70));
    write_text(dir / "pat.mhd", head + "ElementDataFile = s%d.raw\n");
    EXPECT_THROW_MSG(read_volume({dir / "pat.mhd"}), IoError, "s4.raw does not exist, expected the file of slice 4");
    write_text(dir / "s4.raw", data.substr(0, 69));
    EXPECT_THROW_MSG(read_volume({dir / "pat.mhd"}), IoError, "s4.raw: holds 69 bytes");
    write_text(dir / "pat3.mhd", head + "ElementDataFile = s%d.raw 1 3 1\n");
    EXPECT_THROW_MSG(read_volume({dir / "pat3.mhd"}), IoError, "names 3 slice files, expected 4");
    write_text(dir / "list.mha", head + "ElementDataFile = LIST\ns1.raw\ns2.raw\n");
    EXPECT_THROW_MSG(read_volume({dir / "list.mha"}), IoError, "LIST names 2 files");
    write_text(dir / "few.txt", "1 2 3 4\n5 6\n");
    write_text(dir / "ascii.mhd", "ObjectType = Image\nNDims = 3\nBinaryData = False\nDimSize = 7 5 4\n"
                                  "ElementType = MET_SHORT\nElementDataFile = few.txt\n");
    EXPECT_THROW_MSG(read_volume({dir / "ascii.mhd"}), IoError, "holds 6 ASCII voxel values");
    write_text(dir / "zend.mhd", mha_header("MET_USHORT", false, "CompressedData = True\nHeaderSize = -1\n") +
                                     "ElementDataFile = det.raw\n");
    EXPECT_THROW_MSG(read_volume({dir / "zend.mhd"}), IoError, "HeaderSize = -1");
    // More compressed data than the voxels (MetaIO: "Uncompress failed", the voxels uninitialised).
    write_text(dir / "more.mha", mha_header("MET_UCHAR", false, "CompressedData = True\n") +
                                     "ElementDataFile = LOCAL\n" + z);
    EXPECT_THROW_MSG(read_volume({dir / "more.mha"}), IoError, "inflate to more bytes");
    // (The fuzz reproducer of this, regress_compressed_longer_than_voxels.mha, holds NUL bytes in
    // its header lines: refused by the header reader now, IoMetaImageHeader.EveryFuzzReproducer...)
    // "ElementDataFile" without a value at the end of the file: no data file at all (fuzz_mhd under
    // valgrind; MetaIO opened the header's directory as the data file).
    write_text(dir / "novalue.mha", mha_header("MET_UCHAR", false) + "ElementDataFile");
    EXPECT_THROW_MSG(read_volume({dir / "novalue.mha"}), IoError, "novalue.mha");
    EXPECT_THROW_MSG(read_volume({std::string(ENDOCAST_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_mhd/regress_no_data_file_value.mha"}), IoError,
                     "regress_no_data_file_value.mha");
}

TEST(IoErrors, CorruptGzipInDetachedNrrd) {
    TempDir dir("corruptgz");
    write_text(dir / "bad.nhdr",
               "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 8 8 4\n"
               "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\n"
               "endian: little\nencoding: gzip\ndata file: bad.raw.gz\n\n");
    std::vector<uint8_t> garbage(300);
    for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<uint8_t>(i * 37 + 11);
    garbage[0] = 0x1f;  // looks like gzip at first
    garbage[1] = 0x8b;
    write_bytes(dir / "bad.raw.gz", garbage);
    const std::string m = error_message<IoError>([&] { read_volume({dir / "bad.nhdr"}); });
    EXPECT_NE(m.find("bad.nhdr"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;     // one line
    EXPECT_EQ(m.find("(0x"), std::string::npos) << m;     // no object address from ITK
}

TEST(IoErrors, GarbageHeader) {
    TempDir dir("garbage");
    write_text(dir / "junk.nrrd", "this is not a NRRD header\n");
    write_text(dir / "junk.mha", "NDims = banana\n");
    EXPECT_THROW_MSG(read_volume({dir / "junk.nrrd"}), IoError, "junk.nrrd");
    EXPECT_THROW_MSG(read_volume({dir / "junk.mha"}), IoError, "junk.mha");
}

TEST(IoErrors, RejectsTwoDimensionalAndVectorImages) {
    TempDir dir("not3d");
    write_text(dir / "flat.nrrd",
               "NRRD0004\ntype: uint8\ndimension: 2\nsizes: 2 2\nencoding: raw\n\n\x01\x02\x03\x04");
    EXPECT_THROW_MSG(read_volume({dir / "flat.nrrd"}), InvalidParameter, "flat.nrrd");
    std::string vec = "NRRD0004\ntype: uint8\ndimension: 4\nsizes: 3 2 2 2\n"
                      "kinds: vector domain domain domain\nencoding: raw\n\n";
    vec += std::string(24, '\x05');
    write_text(dir / "rgb.nrrd", vec);
    EXPECT_THROW_MSG(read_volume({dir / "rgb.nrrd"}), InvalidParameter, "rgb.nrrd");
}

TEST(IoErrors, NanVoxelsAndBadSpacing) {
    TempDir dir("nanfile");
    std::vector<uint8_t> data;
    for (int i = 0; i < 8; ++i)
        append(data, i == 5 ? std::numeric_limits<float>::quiet_NaN() : 1.0f, Endian::Little);
    std::string h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n\n";
    std::string nan = h + std::string(data.begin(), data.end());
    write_text(dir / "nan.nrrd", nan);
    const std::string msg = error_message<InvalidParameter>([&] { read_volume({dir / "nan.nrrd"}); });
    EXPECT_NE(msg.find("nan.nrrd"), std::string::npos) << msg;
    EXPECT_NE(msg.find("1 voxels"), std::string::npos) << msg;

    std::string zero = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\n"
                       "space directions: (0,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\n"
                       "encoding: raw\n\n" + std::string(8, '\x01');
    write_text(dir / "zero.nrrd", zero);
    EXPECT_THROW(read_volume({dir / "zero.nrrd"}), Error);  // ITK or our spacing check
}

// Reproducers found by the fuzz targets (tests/fuzz/fuzz_itk.cpp, also kept in their corpora as
// tests/fuzz/corpus/fuzz_*/regress_*): each must be a clean endocast::Error.
namespace {
std::string mhd_regression(const std::string& name) {
    return std::string(ENDOCAST_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_mhd/" + name;
}
}  // namespace

TEST(IoErrors, FuzzNiftiHugeVoxOffset) {
    // vox_offset 4.7e27 was converted to uint64_t (undefined behaviour, UBSan) before the length check.
    TempDir dir("fuzzniivox");
    const std::string path = dir / "vol.nii";
    write_volume(test_volume<int16_t>(1.0, 0.0), path);
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    const float huge = 4.68938e27f;  // host order, as ITK wrote the header
    f.seekp(108);
    f.write(reinterpret_cast<const char*>(&huge), sizeof huge);
    f.close();
    const std::string m = error_message<IoError>([&] { read_volume({path}); });
    EXPECT_NE(m.find("vox_offset"), std::string::npos) << m;
    EXPECT_NE(m.find("vol.nii"), std::string::npos) << m;
}

TEST(IoErrors, FuzzNrrdAsciiGarbageAndMetaImageMissingDataFile) {
    // Both leak a few hundred bytes inside ITK 5.2 on its error path (suppressed in the fuzz target,
    // docs/reliability.md); here: each is one IoError naming the file.
    TempDir dir("fuzzitkleaks");
    std::string ascii = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 3\nencoding: ascii\n\n";
    for (int i = 0; i < 48; ++i) ascii += (i == 20 ? std::string("\xff\xff ") : std::to_string(i) + " ");
    write_text(dir / "ascii.nrrd", ascii);
    EXPECT_THROW_MSG(read_volume({dir / "ascii.nrrd"}), IoError, "ascii.nrrd");
    write_text(dir / "nodata.mha",
               "ObjectType = Image\nNDims = 3\nBinaryData = True\nDimSize = 4 4 3\n"
               "ElementType = MET_UCHAR\nElementDataFile =\xbb" "data.raw\n");
    EXPECT_THROW_MSG(read_volume({dir / "nodata.mha"}), IoError, "nodata.mha");
}

TEST(IoErrors, FuzzNiftiNanOrientationIsRejectedBeforeItk) {
    // A NaN in srow_y made ITK 5.2's vnl_svd call abort(); checked before ITK reads the header,
    // for .nii and .nii.gz.
    TempDir dir("fuzzniinan");
    const std::string path = dir / "vol.nii";
    write_volume(test_volume<int16_t>(1.0, 0.0), path);
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    const int16_t sform_code = 1;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    f.seekp(254);
    f.write(reinterpret_cast<const char*>(&sform_code), sizeof sform_code);
    f.seekp(280 + 4 * 6);  // srow_y[2]
    f.write(reinterpret_cast<const char*>(&nan), sizeof nan);
    f.close();
    EXPECT_THROW_MSG(read_volume({path}), IoError, "srow");
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string gz = dir / "vol.nii.gz";
    gzFile out = gzopen(gz.c_str(), "wb");
    ASSERT_NE(out, nullptr);
    gzwrite(out, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(out);
    EXPECT_THROW_MSG(read_volume({gz}), IoError, "srow");
    // nifti_clib takes the byte order from dim[0] and ignores a wrong sizeof_hdr: so must we.
    std::fstream g(path, std::ios::in | std::ios::out | std::ios::binary);
    const int32_t wrong_size = 234;
    g.write(reinterpret_cast<const char*>(&wrong_size), sizeof wrong_size);
    g.close();
    EXPECT_THROW_MSG(read_volume({path}), IoError, "srow");
}

TEST(IoErrors, FuzzMetaImageStdExceptionFromItkIsAnIoError) {
    // In the fuzz build (clang + ASan), ITK 5.2's MetaImage reader threw std::length_error out of
    // read_volume for this header (a file pattern "%%% LOCAL" without its numbers, truncated data);
    // the GCC build reads it, so ITK depends on memory it did not set. Either way: a volume or an
    // endocast::Error, never another exception.
    TempDir dir("fuzzmhalength");
    std::string mha = "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
                      "CompressedData = False\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = 0 0 0\n"
                      "ElementSpccing = 1 1 2\nDimSize = 4 4 3\nElementType = MET_USHORT\n"
                      "ElementDataFile =%%% LOCAL\n";
    const uint8_t data[35] = {0x00, 0x93, 0x00, 0xb8, 0x00, 0x15, 0x00, 0x3a, 0x00, 0x5f, 0x00, 0x84,
                              0x00, 0xa9, 0x00, 0x06, 0x00, 0x2b, 0x00, 0x50, 0x00, 0x75, 0x00, 0x9a,
                              0x00, 0xbf, 0x00, 0x1c, 0x00, 0x41, 0x00, 0x66, 0x00, 0x8b, 0x00};
    mha.append(reinterpret_cast<const char*>(data), sizeof data);  // truncated: 96 bytes expected
    write_text(dir / "len.mha", mha);
    try {
        read_volume({dir / "len.mha"});
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("len.mha"), std::string::npos) << e.what();
    }  // anything else fails the test
}

TEST(IoErrors, FuzzMetaImageHugeNDimsIsRejectedQuickly) {
    // ITK 5.2 spent minutes on "NDims = 5555...5" (NDims x NDims transform values); checked first.
    TempDir dir("fuzzmhandims");
    write_text(dir / "ndims.mha", "ObjectType = Image\nNDims =" + std::string(56, '5') +
                                      " 3\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nDimSize = 2 4 3\n"
                                      "ElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
                                      std::string(48, '\x01'));
    EXPECT_THROW_MSG(read_volume({dir / "ndims.mha"}), IoError, "NDims");
    // A second, different NDims: MetaIO took the fourth dimension it never read, uninitialised
    // (fuzz_mhd under valgrind).
    write_text(dir / "twice.mha", "ObjectType = Image\nNDims = 3\nDimSize = 3 4 4\nNDims = 4\n"
                                  "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" + std::string(48, '\1'));
    EXPECT_THROW_MSG(read_volume({dir / "twice.mha"}), IoError, "declares NDims twice (3, then 4)");
}

TEST(IoErrors, FuzzMetaImageEmptyDataFileIsRejectedBeforeItk) {
    // ITK 5.2's MetaIO opened "" as the data file of compressed data without CompressedDataSize and
    // allocated its size, -1 (fuzz_mhd in .ci/run, 2026-12-02). Found before ITK sees the file.
    TempDir dir("fuzzmhaempty");
    write_text(dir / "empty.mha", "ObjectType = Image\nNDims = 3\nBinaryData = True\nCompressedData = True\n"
                                  "DimSize = 4 4 3\nElementType = MET_SHORT\nElementDataFile = \n" +
                                      std::string(48, '\x01'));
    EXPECT_THROW_MSG(read_volume({dir / "empty.mha"}), IoError, "ElementDataFile is empty");
    const std::string repro = mhd_regression("regress_empty_data_file.mha");
    EXPECT_THROW_MSG(read_volume({repro}), IoError, "ElementDataFile is empty");
}

TEST(IoErrors, FuzzMetaImageLongFieldNameIsRejectedBeforeItk) {
    // ITK 5.2's MetaIO strcpy'd a 281-character line without '=' into a 255-byte field name
    // (fuzz_mhd; fortify abort, memory corruption without it). Found before ITK sees the file.
    TempDir dir("fuzzmhakey");
    const std::string tail = "DimSize = 2 4 3\nElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
                             std::string(48, '\x01');
    write_text(dir / "key.mha",
               "ObjectType = Image\nNDims = 3\n" + std::string(281, 'k') + "\n" + tail);
    EXPECT_THROW_MSG(read_volume({dir / "key.mha"}), IoError, "field name ending on line 4 is 292");
    // The same run of text after a value MetaIO has consumed ("DimSize = 2 4 3 kkkk...").
    write_text(dir / "rest.mha", "ObjectType = Image\nNDims = 3\nDimSize = 2 4 3 " +
                                     std::string(300, 'k') + "\nElementType = MET_SHORT\n" +
                                     "ElementDataFile = LOCAL\n" + std::string(48, '\x01'));
    EXPECT_THROW_MSG(read_volume({dir / "rest.mha"}), IoError, "field name ending on line 4");
    // The checked-in reproducer from the fuzzer.
    const std::string repro = mhd_regression("regress_key_strcpy_overflow.mha");
    EXPECT_THROW_MSG(read_volume({repro}), IoError, "characters long");
    // A control byte before "ElementDataFile" on its line: MetaIO need not take it for the data
    // file, reads on as header and strcpy'd the 300-byte name after it (fuzz_mhd in .ci/run,
    // 2026-12-01): the names after such a candidate are checked too.
    write_text(dir / "ctl.mha", "ObjectType = Image\nNDims = 3\nDimSize = 2 4 3\nElementType = MET_SHORT\n"
                                "\bElementDataFile = LOCAL\n" + std::string(300, 'k') + " = 1\n" +
                                std::string(48, '\x01'));
    EXPECT_THROW_MSG(read_volume({dir / "ctl.mha"}), IoError, "field name ending on line 6");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_control_char_before_data_file_strcpy.mha")}), IoError,
                     "characters long");
    // A line of other text between the previous value and "ElementDataFile": MetaIO reads the two
    // lines as one unknown name and reads on as header (fuzz_mhd in .ci/run, 2026-12-05).
    write_text(dir / "word.mha", "ObjectType = Image\nNDims = 3\nDimSize = 2 4 3\nElementType = MET_SHORT\n"
                                 "Word\nElementDataFile = LOCAL\n" + std::string(300, 'k') + " = 1\n" +
                                 std::string(48, '\x01'));
    EXPECT_THROW_MSG(read_volume({dir / "word.mha"}), IoError, "field name ending on line 7");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_text_before_data_file_strcpy.mha")}), IoError,
                     "characters long");
    // The same before the first separator: "3\nElementDataFile = ..." is one name, "3", to MetaIO,
    // whose value it seeks past that line (fuzz_mhd in .ci/run, 2026-12-06).
    write_text(dir / "first.mha", "3\nElementDataFile = LOCAL\n" + std::string(300, 'k') + "\n = 1\n" +
                                      std::string(48, '\x01'));
    EXPECT_THROW_MSG(read_volume({dir / "first.mha"}), IoError, "field name ending on line 4");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_text_before_first_field_strcpy.mha")}), IoError,
                     "characters long");
    // A header with no ElementDataFile in its first 64 KiB is not a MetaImage header.
    write_text(dir / "nodata.mha", "ObjectType = Image\n" + std::string(70000, '\n'));
    EXPECT_THROW_MSG(read_volume({dir / "nodata.mha"}), IoError, "no ElementDataFile");
    // Field names and values up to 254 characters are fine (a long comment).
    write_text(dir / "ok.mha", "ObjectType = Image\nNDims = 3\nComment = " + std::string(250, 'c') +
                                   "\nBinaryData = True\n" + tail);
    EXPECT_EQ(read_volume({dir / "ok.mha"}).volume.dims()[2], 3);
}

TEST(IoErrors, FuzzMetaImageDataFilePatternWithAStringConversion) {
    // ITK 5.2 formats a '%' ElementDataFile with one int: "%s" made it read a bad pointer (SEGV).
    TempDir dir("fuzzmhapattern");
    const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 3\nElementType = MET_USHORT\n";
    write_text(dir / "s.mha", head + "ElementDataFile =%%%s1\n");
    EXPECT_THROW_MSG(read_volume({dir / "s.mha"}), IoError, "ElementDataFile");
    write_text(dir / "two.mha", head + "ElementDataFile = a%d%d.raw 1 3 1\n");
    EXPECT_THROW_MSG(read_volume({dir / "two.mha"}), IoError, "ElementDataFile");
    // A pattern needs no numbers or exactly FIRST LAST STEP as whole numbers: MetaIO divided by a
    // step of 0 derived from a word that is not a number (fuzz_mhd: FPE in ReadStream).
    write_text(dir / "fpe.mha", head + "ElementDataFile = a%d.raw LPos\n");
    EXPECT_THROW_MSG(read_volume({dir / "fpe.mha"}), IoError, "FIRST LAST STEP");
    write_text(dir / "step0.mha", head + "ElementDataFile = a%d.raw 1 3 0\n");
    EXPECT_THROW_MSG(read_volume({dir / "step0.mha"}), IoError, "STEP >= 1");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_pattern_step_fpe.mha")}),
                     IoError, "ElementDataFile");
    // Any '%' makes a slice series for MetaIO, "%%" alone too (fuzz_mhd: FPE).
    write_text(dir / "pp.mha", head + "ElementDataFile = a%%.raw LPMatrix = 1 0 0\n");
    EXPECT_THROW_MSG(read_volume({dir / "pp.mha"}), IoError, "FIRST LAST STEP");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_percent_percent_pattern_fpe.mha")}),
                     IoError, "ElementDataFile");
    // MetaIO splits a pattern at single spaces into 80-byte words (fuzz_mhd: heap overflow).
    write_text(dir / "long.mha", head + "ElementDataFile = " + std::string(90, 'a') + "%d.raw 0 1 2\n");
    EXPECT_THROW_MSG(read_volume({dir / "long.mha"}), IoError, "1 to 79 characters");
    write_text(dir / "spaces.mha", head + "ElementDataFile = a%d.raw   1 3 1\n");
    EXPECT_THROW_MSG(read_volume({dir / "spaces.mha"}), IoError, "single spaces");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_pattern_long_word_overflow.mha")}),
                     IoError, "ElementDataFile");
    // MetaIO's value runs to '\n', a '\r' inside it kept: "a\rb%d.raw 0 1 2" is a pattern whose first
    // word holds a '\r' (fuzz_mhd: a 123-byte word overflowed MET_StringToWordArray's buffer, our
    // check had stopped the value at the '\r'). A CRLF header stays fine (trailing '\r' stripped).
    write_text(dir / "cr.mha", head + "ElementDataFile = " + std::string(100, 'a') + "\rb%%.raw 0 1 2\n");
    EXPECT_THROW_MSG(read_volume({dir / "cr.mha"}), IoError, "1 to 79 characters");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_cr_in_pattern_word_overflow.mha")}),
                     IoError, "ElementDataFile");
    write_text(dir / "crlf.mha", "ObjectType = Image\r\nNDims = 3\r\nDimSize = 4 4 3\r\n"
                                 "ElementType = MET_USHORT\r\nElementDataFile = slice%03d.raw 1 3 1\r\n");
    try {
        read_volume({dir / "crlf.mha"});
    } catch (const IoError& e) {
        EXPECT_EQ(std::string(e.what()).find("ElementDataFile '"), std::string::npos) << e.what();
    }
    // MetaIO reads a name across lines up to the next '=' ("ElementDataFile\0junk\n\0x =%s";
    // fuzz_mhd: a SEGV in snprintf).
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_name_across_lines_percent_s.mha")}),
                     IoError, "ElementDataFile");
    write_text(dir / "across.mha", head + std::string("ElementDataFile\0junk\n\0x =%s\n", 28));
    EXPECT_THROW_MSG(read_volume({dir / "across.mha"}), IoError, "ElementDataFile");
    // MetaIO compares names as C strings: "ElementDataFile\0junk =%s" is still its data file.
    write_text(dir / "nul.mha", head + std::string("ElementDataFile\0\0junk =%%%s\n", 28));
    EXPECT_THROW_MSG(read_volume({dir / "nul.mha"}), IoError, "ElementDataFile");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_nul_in_key_percent_s.mha")}),
                     IoError, "ElementDataFile");
    // A slice pattern with one %03d passes this check (and fails later only for its missing files).
    write_text(dir / "ok.mha", head + "ElementDataFile = slice%03d.raw 1 3 1\n");
    try {
        read_volume({dir / "ok.mha"});
    } catch (const IoError& e) {
        EXPECT_EQ(std::string(e.what()).find("is not a file name"), std::string::npos) << e.what();
    }
}

TEST(IoErrors, FuzzMetaImageDataFileNameEndingAtItsLine) {
    // "ElementDataFile \nx = pattern": MetaIO's name ends at the line end and it seeks the value
    // past the next '=', so the pattern is the data file's and is checked (fuzz_mhd, 2026-12-06: a
    // 100-byte word of a slice pattern overflowed MET_StringToWordArray's 80-byte word).
    TempDir dir("fuzzmhaeol");
    const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 3\nElementType = MET_USHORT\n";
    write_text(dir / "eol.mha", head + "ElementDataFile \nx = " + std::string(100, 'T') + "%03d.raw 1 3 1\n");
    EXPECT_THROW_MSG(read_volume({dir / "eol.mha"}), IoError, "words of 1 to 79 characters");
    EXPECT_THROW_MSG(read_volume({mhd_regression("regress_data_file_name_ends_at_line_end.mha")}), IoError,
                     "ElementDataFile");
}

TEST(IoErrors, SeveralInputsWithoutRawOptions) {
    EXPECT_THROW(read_volume({"a.nrrd", "b.nrrd"}), InvalidParameter);
    EXPECT_THROW(read_volume({}), InvalidParameter);
}

// ---------------------------------------------------------------------------------------------
// Raw data.

TEST(RawType, NamesAndSizes) {
    EXPECT_EQ(to_string(RawType::Int8), "int8");
    EXPECT_EQ(to_string(RawType::UInt16), "uint16");
    EXPECT_EQ(to_string(RawType::Float64), "float64");
    EXPECT_EQ(raw_type_size(RawType::UInt8), 1u);
    EXPECT_EQ(raw_type_size(RawType::Int16), 2u);
    EXPECT_EQ(raw_type_size(RawType::Float32), 4u);
    EXPECT_EQ(raw_type_size(RawType::Float64), 8u);
}

TEST(RawRead, EveryTypeAndEndian) {
    TempDir dir("rawtypes");
    const Dims size{3, 2, 4};
    for (RawType t : {RawType::Int8, RawType::UInt8, RawType::Int16, RawType::UInt16, RawType::Int32,
                      RawType::UInt32, RawType::Float32, RawType::Float64}) {
        const bool is_signed = t == RawType::Int8 || t == RawType::Int16 || t == RawType::Int32 ||
                               t == RawType::Float32 || t == RawType::Float64;
        const bool is_float = t == RawType::Float32 || t == RawType::Float64;
        for (Endian e : {Endian::Little, Endian::Big}) {
            std::vector<double> values;
            std::vector<uint8_t> bytes;
            for (int i = 0; i < 24; ++i) {
                double v = (i * 5) % 120 + (is_float ? 0.5 : 0.0);
                if (is_signed && i % 3 == 0) v = -v;
                if (t == RawType::UInt16 && i == 7) v = 65535;
                if (t == RawType::Int16 && i == 7) v = -32768;
                if (t == RawType::Int32 && i == 8) v = -1000000;
                values.push_back(v);
                append_as(bytes, t, v, e);
            }
            const std::string path =
                dir / (to_string(t) + (e == Endian::Big ? "_be" : "_le") + ".raw");
            write_bytes(path, bytes);
            RawOptions o;
            o.size = size;
            o.type = t;
            o.endian = e;
            o.spacing = {0.5, 0.5, 2};
            o.origin = {1, 2, 3};
            ReadOptions ro;
            ro.raw = o;
            const ReadResult r = read_volume({path}, ro);
            EXPECT_EQ(r.info.format, "raw");
            EXPECT_EQ(r.info.voxel_type, to_string(t));
            EXPECT_EQ(r.info.files_read, 1u);
            EXPECT_EQ(r.volume.dims(), size);
            EXPECT_EQ(r.volume.geometry().spacing, (Vec3{0.5, 0.5, 2}));
            EXPECT_EQ(r.volume.geometry().origin, (Vec3{1, 2, 3}));
            ASSERT_EQ(r.volume.size(), values.size());
            for (size_t i = 0; i < values.size(); ++i)
                EXPECT_EQ(r.volume[i], static_cast<float>(values[i])) << path << " voxel " << i;
        }
    }
}

namespace {

/// Writes CThead.1 .. CThead.<n> (big-endian uint16 slices of 4 x 3, value 100*slice + i).
void write_cthead_stack(const TempDir& dir, int n, uint64_t header = 0) {
    for (int s = 1; s <= n; ++s) {
        std::vector<uint8_t> bytes(header, 0xAB);
        for (int i = 0; i < 12; ++i) append(bytes, static_cast<uint16_t>(100 * s + i), Endian::Big);
        write_bytes(dir / ("CThead." + std::to_string(s)), bytes);
    }
}

RawOptions cthead_options(int nz) {
    RawOptions o;
    o.size = {4, 3, nz};
    o.type = RawType::UInt16;
    o.endian = Endian::Big;
    o.spacing = {1, 1, 2};
    return o;
}

void expect_stack_order(const ReadResult& r, int n) {
    ASSERT_EQ(r.volume.dims(), (Dims{4, 3, n}));
    for (int z = 0; z < n; ++z)
        for (int i = 0; i < 12; ++i)
            ASSERT_EQ(r.volume(i % 4, i / 4, z), static_cast<float>(100 * (z + 1) + i)) << "slice " << z;
}

}  // namespace

TEST(RawRead, SliceStackByGlobPrintfAndListInNaturalOrder) {
    TempDir dir("stack");
    write_cthead_stack(dir, 12);
    const RawOptions o = cthead_options(12);

    const ReadResult g = read_raw({dir / "CThead.*"}, o);
    EXPECT_EQ(g.info.files_read, 12u);
    expect_stack_order(g, 12);

    expect_stack_order(read_raw({dir / "CThead.%d"}, o), 12);

    // An explicit list in the shell's (lexicographic) order: CThead.1, CThead.10, ..., CThead.2.
    std::vector<std::string> list;
    for (int s = 1; s <= 12; ++s) list.push_back(dir / ("CThead." + std::to_string(s)));
    std::sort(list.begin(), list.end());
    ASSERT_EQ(list[1], dir / "CThead.10");
    ReadOptions ro;
    ro.raw = o;
    const ReadResult l = read_volume(list, ro);
    EXPECT_EQ(l.info.files_read, 12u);
    expect_stack_order(l, 12);
    EXPECT_EQ(l.volume.buffer(), g.volume.buffer());
}

TEST(RawRead, PrintfPatternFromZeroWithWidth) {
    TempDir dir("printf0");
    for (int s = 0; s < 3; ++s) {
        std::vector<uint8_t> bytes;
        for (int i = 0; i < 4; ++i) append(bytes, static_cast<uint8_t>(10 * s + i), Endian::Little);
        char name[32];
        std::snprintf(name, sizeof name, "slice%03d.raw", s);
        write_bytes(dir / name, bytes);
    }
    RawOptions o;
    o.size = {2, 2, 3};
    o.type = RawType::UInt8;
    const ReadResult r = read_raw({dir / "slice%03d.raw"}, o);
    EXPECT_EQ(r.info.files_read, 3u);
    EXPECT_EQ(r.volume(1, 1, 2), 23.0f);
    EXPECT_EQ(r.volume(0, 0, 0), 0.0f);
    EXPECT_THROW_MSG(read_raw({dir / "none%d.raw"}, o), IoError, "none%d.raw");
    EXPECT_THROW_MSG(read_raw({dir / "none*.raw"}, o), IoError, "none*.raw");
}

TEST(RawRead, SlabsAndHeaderBytes) {
    TempDir dir("slabs");
    write_cthead_stack(dir, 12, 17);
    RawOptions o = cthead_options(12);
    o.header_bytes = 17;
    expect_stack_order(read_raw({dir / "CThead.*"}, o), 12);

    // Three slabs of four slices each, each with a 5-byte header.
    TempDir slabs("slabs3");
    for (int f = 0; f < 3; ++f) {
        std::vector<uint8_t> bytes(5, 0xEE);
        for (int s = 4 * f + 1; s <= 4 * f + 4; ++s)
            for (int i = 0; i < 12; ++i) append(bytes, static_cast<uint16_t>(100 * s + i), Endian::Big);
        write_bytes(slabs / ("slab" + std::to_string(f + 1) + ".bin"), bytes);
    }
    o.header_bytes = 5;
    const ReadResult r = read_raw({slabs / "slab?.bin"}, o);
    EXPECT_EQ(r.info.files_read, 3u);
    expect_stack_order(r, 12);

    o.size[2] = 13;  // 13 slices cannot be split over 3 files
    EXPECT_THROW(read_raw({slabs / "slab?.bin"}, o), InvalidParameter);
}

TEST(RawRead, SingleFileWithHeader) {
    TempDir dir("header");
    std::vector<uint8_t> bytes(64, 0xFF);
    for (int i = 0; i < 8; ++i) append(bytes, static_cast<int16_t>(-i), Endian::Little);
    write_bytes(dir / "vol.raw", bytes);
    RawOptions o;
    o.size = {2, 2, 2};
    o.type = RawType::Int16;
    o.header_bytes = 64;
    const ReadResult r = read_raw({dir / "vol.raw"}, o);
    EXPECT_EQ(r.volume(1, 1, 1), -7.0f);
    EXPECT_EQ(r.volume(0, 0, 0), 0.0f);
}

TEST(RawRead, TruncatedAndOversizedFiles) {
    TempDir dir("sizes");
    RawOptions o;
    o.size = {4, 4, 2};
    o.type = RawType::UInt16;
    o.header_bytes = 10;
    write_bytes(dir / "short.raw", std::vector<uint8_t>(10 + 4 * 4 * 2 * 2 - 1));
    write_bytes(dir / "long.raw", std::vector<uint8_t>(10 + 4 * 4 * 2 * 2 + 2));
    write_bytes(dir / "exact.raw", std::vector<uint8_t>(10 + 4 * 4 * 2 * 2));
    const std::string m = error_message<IoError>([&] { read_raw({dir / "short.raw"}, o); });
    EXPECT_NE(m.find("short.raw: holds 73 bytes, expected 74 (4 x 4 x 2 uint16 + header 10)"),
              std::string::npos)
        << m;
    EXPECT_THROW_MSG(read_raw({dir / "long.raw"}, o), IoError, "long.raw: holds 76 bytes");
    EXPECT_NO_THROW(read_raw({dir / "exact.raw"}, o));
    // One short slice in a stack.
    TempDir stack("shortstack");
    write_cthead_stack(stack, 4);
    write_bytes(stack / "CThead.3", std::vector<uint8_t>(20));
    EXPECT_THROW_MSG(read_raw({stack / "CThead.*"}, cthead_options(4)), IoError, "CThead.3");
    EXPECT_THROW_MSG(read_raw({dir / "nothere.raw"}, o), IoError, "nothere.raw: no such file");
}

TEST(RawRead, RejectsBadOptionsBeforeReading) {
    TempDir dir("badopts");
    write_bytes(dir / "v.raw", std::vector<uint8_t>(8));
    RawOptions o;
    o.type = RawType::UInt8;
    for (Dims d : {Dims{0, 2, 2}, Dims{2, -1, 2}, Dims{2, 2, 0}}) {
        o.size = d;
        EXPECT_THROW(read_raw({dir / "v.raw"}, o), InvalidParameter);
    }
    // 10^15 voxels: rejected before any file access or allocation (the file does not exist).
    o.size = {100000, 100000, 100000};
    EXPECT_THROW_MSG(read_raw({dir / "missing.raw"}, o), InvalidParameter, "100000 x 100000 x 100000");
    o.size = {int64_t{1} << 40, int64_t{1} << 40, int64_t{1} << 40};  // would overflow 64 bits
    EXPECT_THROW(read_raw({dir / "missing.raw"}, o), InvalidParameter);
    o.size = {2, 2, 2};
    o.spacing = {1, 0, 1};
    EXPECT_THROW(read_raw({dir / "v.raw"}, o), InvalidParameter);
    o.spacing = {1, std::nan(""), 1};
    EXPECT_THROW(read_raw({dir / "v.raw"}, o), InvalidParameter);
    o.spacing = {1, -2, 1};
    EXPECT_THROW(read_raw({dir / "v.raw"}, o), InvalidParameter);
    o.spacing = {1, 1, 1};
    EXPECT_NO_THROW(read_raw({dir / "v.raw"}, o));
    EXPECT_THROW_MSG(read_raw({dir.str()}, o), IoError, "is a directory");
}

TEST(RawRead, NanInFloatDataRejected) {
    TempDir dir("rawnan");
    for (Endian e : {Endian::Little, Endian::Big}) {
        std::vector<uint8_t> bytes;
        for (int i = 0; i < 8; ++i)
            append(bytes, i == 3 || i == 6 ? std::numeric_limits<float>::quiet_NaN() : 1.5f, e);
        write_bytes(dir / "nan.raw", bytes);
        RawOptions o;
        o.size = {2, 2, 2};
        o.type = RawType::Float32;
        o.endian = e;
        const std::string m = error_message<InvalidParameter>([&] { read_raw({dir / "nan.raw"}, o); });
        EXPECT_NE(m.find("nan.raw"), std::string::npos) << m;
        EXPECT_NE(m.find("2 voxels are NaN or infinite, the first at voxel (1, 1, 0)"), std::string::npos) << m;
        EXPECT_NE(m.find("float32"), std::string::npos) << m;
    }
    std::vector<uint8_t> bytes;
    for (int i = 0; i < 8; ++i) append(bytes, i == 0 ? 1e300 : 0.0, Endian::Little);  // out of float range
    write_bytes(dir / "big.raw", bytes);
    RawOptions o;
    o.size = {2, 2, 2};
    o.type = RawType::Float64;
    EXPECT_THROW(read_raw({dir / "big.raw"}, o), InvalidParameter);
}

// ---------------------------------------------------------------------------------------------
// Real data from ../shared/data.

namespace {

bool have_data(const std::string& rel) { return fs::exists(kData + rel); }

/// A DICOM element's value in the first 64 KiB of `bytes` (implicit or explicit VR little
/// endian); empty if not found. `pos` receives the value's offset.
std::string dicom_value(const std::vector<uint8_t>& bytes, uint16_t group, uint16_t element,
                        size_t* pos = nullptr) {
    const uint8_t tag[4] = {static_cast<uint8_t>(group & 0xFF), static_cast<uint8_t>(group >> 8),
                            static_cast<uint8_t>(element & 0xFF), static_cast<uint8_t>(element >> 8)};
    const size_t end = std::min<size_t>(bytes.size(), 65536);
    for (size_t i = 132; i + 8 <= end; ++i) {
        if (std::memcmp(&bytes[i], tag, 4) != 0) continue;
        size_t len, start;
        if (std::isupper(bytes[i + 4]) && std::isupper(bytes[i + 5])) {  // explicit VR, short length
            len = bytes[i + 6] | (bytes[i + 7] << 8);
            start = i + 8;
        } else {
            len = bytes[i + 4] | (bytes[i + 5] << 8) | (bytes[i + 6] << 16) |
                  (static_cast<size_t>(bytes[i + 7]) << 24);
            start = i + 8;
        }
        if (start + len > bytes.size()) continue;
        if (pos) *pos = start;
        std::string v(bytes.begin() + static_cast<std::ptrdiff_t>(start),
                      bytes.begin() + static_cast<std::ptrdiff_t>(start + len));
        while (!v.empty() && (v.back() == '\0' || v.back() == ' ')) v.pop_back();
        return v;
    }
    return {};
}

std::vector<std::string> dicom_files(const std::string& dir) {
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().extension() == ".dcm") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    return files;
}

class DicomHeadPhantom : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        if (!have_data("/headphantom-dicom")) return;
        const auto t0 = std::chrono::steady_clock::now();
        result_ = std::make_unique<ReadResult>(read_volume({kData + "/headphantom-dicom"}));
        seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    static void TearDownTestSuite() { result_.reset(); }
    void SetUp() override {
        if (!have_data("/headphantom-dicom")) GTEST_SKIP() << "../shared/data not found";
        ASSERT_TRUE(result_);
    }
    static std::unique_ptr<ReadResult> result_;
    static double seconds_;
};
std::unique_ptr<ReadResult> DicomHeadPhantom::result_;
double DicomHeadPhantom::seconds_ = 0;

}  // namespace

TEST(IoRealData, CtheadNhdr) {
    if (!have_data("/cthead/cthead.nhdr")) GTEST_SKIP() << "../shared/data not found";
    const auto t0 = std::chrono::steady_clock::now();
    const ReadResult r = read_volume({kData + "/cthead/cthead.nhdr"});
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cout << "[ info ] cthead.nhdr read in " << s << " s\n";
    EXPECT_EQ(r.volume.dims(), (Dims{256, 256, 113}));
    EXPECT_EQ(r.volume.geometry().spacing, (Vec3{1, 1, 2}));
    EXPECT_EQ(r.info.voxel_type, "uint16");
    EXPECT_EQ(r.info.format, "nrrd");
    const auto [lo, hi] = std::minmax_element(r.volume.buffer().begin(), r.volume.buffer().end());
    EXPECT_GE(*lo, 0.0f);
    EXPECT_LE(*hi, 4095.0f);
    EXPECT_GT(*hi, 3000.0f);
    EXPECT_GT(r.volume(37, 128, 40), 1300.0f);  // skull, left side of slice 40
    EXPECT_LT(r.volume(128, 128, 40), 1300.0f);  // brain
    EXPECT_LT(r.volume(2, 2, 40), 200.0f);       // air
    expect_fast_equals_itk(kData + "/cthead/cthead.nhdr");
}

TEST_F(DicomHeadPhantom, SizeSpacingAndHU) {
    std::cout << "[ info ] headphantom-dicom read in " << seconds_ << " s\n";
    const ReadResult& r = *result_;
    EXPECT_EQ(r.volume.dims(), (Dims{512, 512, 209}));
    const Geometry& g = r.volume.geometry();
    EXPECT_NEAR(g.spacing[0], 0.9765625, 1e-6);
    EXPECT_NEAR(g.spacing[1], 0.9765625, 1e-6);
    EXPECT_NEAR(std::abs(g.spacing[2]), 2.0, 1e-4);
    EXPECT_EQ(r.info.format, "dicom");
    EXPECT_EQ(r.info.files_read, 209u);
    EXPECT_FALSE(r.info.series_uid.empty());
    EXPECT_EQ(r.info.voxel_type, "uint16");
    const auto [lo, hi] = std::minmax_element(r.volume.buffer().begin(), r.volume.buffer().end());
    EXPECT_NEAR(*lo, -1024.0f, 30.0f);  // rescale intercept applied: HU
    EXPECT_GT(*hi, 500.0f);
    // Air in a corner of a slice.
    EXPECT_LT(r.volume(3, 3, 100), -900.0f);
}

TEST_F(DicomHeadPhantom, DirectReadEqualsGdcm) {
    EXPECT_TRUE(result_->info.read_directly);
    expect_fast_equals_itk(kData + "/headphantom-dicom");
}

TEST_F(DicomHeadPhantom, SlicesOrderedByPosition) {
    const Geometry& g = result_->volume.geometry();
    // World z of slice k moves monotonically in 2 mm steps.
    double prev = g.index_to_world(0, 0, 0)[2];
    const double step = g.index_to_world(0, 0, 1)[2] - prev;
    EXPECT_NEAR(std::abs(step), 2.0, 1e-4);
    for (int k = 1; k < 209; ++k) {
        const Vec3 p = g.index_to_world(0, 0, k);
        ASSERT_NEAR(p[2] - prev, step, 1e-3) << "slice " << k;
        prev = p[2];
    }
    // First and last slices match the extreme ImagePositionPatient of the files.
    std::vector<Vec3> ipp;
    for (const auto& f : dicom_files(kData + "/headphantom-dicom")) {
        std::string v = dicom_value(read_bytes(f), 0x0020, 0x0032);
        std::replace(v.begin(), v.end(), '\\', ' ');
        std::istringstream is(v);
        Vec3 p{};
        is >> p[0] >> p[1] >> p[2];
        ASSERT_TRUE(is) << f << ": cannot parse ImagePositionPatient \"" << v << "\"";
        ipp.push_back(p);
    }
    ASSERT_EQ(ipp.size(), 209u);
    std::sort(ipp.begin(), ipp.end(), [](const Vec3& a, const Vec3& b) { return a[2] < b[2]; });
    const Vec3 first = g.index_to_world(0, 0, 0), last = g.index_to_world(0, 0, 208);
    const Vec3& lo = step > 0 ? ipp.front() : ipp.back();
    const Vec3& hi = step > 0 ? ipp.back() : ipp.front();
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(first[a], lo[a], 1e-3) << "axis " << a;
        EXPECT_NEAR(last[a], hi[a], 1e-3) << "axis " << a;
    }
}

TEST(DicomSeries, SeveralSeriesTheLongerByDefaultOrByUid) {
    if (!have_data("/headphantom-dicom")) GTEST_SKIP() << "../shared/data not found";
    const auto files = dicom_files(kData + "/headphantom-dicom");
    ASSERT_GE(files.size(), 20u);
    TempDir dir("twoseries");
    // Ten slices of the real series, linked ...
    for (size_t i = 0; i < 10; ++i)
        fs::create_symlink(files[i], dir / fs::path(files[i]).filename().string());
    // ... and five other slices copied with a different SeriesInstanceUID.
    const std::string uid_a = dicom_value(read_bytes(files[0]), 0x0020, 0x000E);
    ASSERT_GT(uid_a.size(), 10u);
    std::string uid_b = uid_a;
    char& last = uid_b.back();
    last = last == '9' ? '8' : static_cast<char>(last + 1);
    for (size_t i = 10; i < 15; ++i) {
        std::vector<uint8_t> bytes = read_bytes(files[i]);
        size_t replaced = 0;
        for (size_t p = 0; p + uid_a.size() <= bytes.size(); ++p)
            if (std::memcmp(&bytes[p], uid_a.data(), uid_a.size()) == 0) {
                std::memcpy(&bytes[p], uid_b.data(), uid_b.size());
                ++replaced;
            }
        ASSERT_GE(replaced, 1u);
        write_bytes(dir / ("copy" + std::to_string(i) + ".dcm"), bytes);
    }
    // By default the series with the most slices (both 2 mm), with a warning naming the other.
    const ReadResult d = read_volume({dir.str()});
    EXPECT_EQ(d.info.series_uid, uid_a);
    EXPECT_EQ(d.info.files_read, 10u);
    EXPECT_EQ(d.info.series_found.size(), 2u);
    ASSERT_EQ(d.info.warnings.size(), 1u);
    const std::string& m = d.info.warnings[0];
    EXPECT_NE(m.find(uid_a + " ('"), std::string::npos) << m;
    EXPECT_NE(m.find("10 files"), std::string::npos) << m;
    EXPECT_NE(m.find(uid_b + " ("), std::string::npos) << m;
    EXPECT_NE(m.find("fewer slices (5)"), std::string::npos) << m;
    EXPECT_NE(m.find(dir.str()), std::string::npos) << m;

    ReadOptions o;
    o.series_uid = uid_b;
    const ReadResult b = read_volume({dir.str()}, o);
    EXPECT_EQ(b.info.series_uid, uid_b);
    EXPECT_EQ(b.info.files_read, 5u);
    EXPECT_EQ(b.volume.dims(), (Dims{512, 512, 5}));
    o.series_uid = uid_a;
    const ReadResult a = read_volume({dir.str()}, o);
    EXPECT_EQ(a.info.files_read, 10u);
    EXPECT_EQ(a.volume.dims(), (Dims{512, 512, 10}));
    o.series_uid = "1.2.3.4";
    EXPECT_THROW_MSG(read_volume({dir.str()}, o), InvalidParameter, "1.2.3.4");
}

TEST(SlabWriter, NrrdAndTiffReadBackEqualAndNothingIsLeftUnfinished) {
    TempDir dir("slab_writer");
    Geometry g;
    g.dims = {11, 7, 9};
    g.spacing = {0.25, 0.5, 0.75};
    g.origin = {-3, 4.5, 10};
    Volume<int16_t> v(g);
    for (size_t i = 0; i < v.size(); ++i) v.data()[i] = int16_t(int(i * 37 % 4001) - 2000);
    const auto slab = [&](int64_t z0, int64_t n) {
        Geometry s = g;
        s.dims[2] = n;
        s.origin = g.index_to_world(0, 0, double(z0));
        Volume<int16_t> out(s);
        std::copy(v.data() + z0 * 77, v.data() + (z0 + n) * 77, out.data());
        return out;
    };
    for (const std::string name : {"a.nrrd", "a.tif", "pages%03d.tif"}) {
        SCOPED_TRACE(name);
        const std::string path = dir / name;
        {
            auto w = open_slab_writer(path, g);
            w->write(slab(0, 4));
            w->write(slab(4, 1));
            w->write(slab(5, 4));
            EXPECT_THROW(w->write(slab(0, 1)), InvalidParameter);  // one slice too many
            w->finish();
        }
        const std::string in = name.find('%') == std::string::npos ? path : dir / "pages*.tif";
        ReadOptions ro;
        if (name != "a.nrrd") ro.spacing = g.spacing, ro.origin = g.origin;
        const Volume<float> back = read_volume({in}, ro).volume;
        ASSERT_EQ(back.dims(), g.dims);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(back.geometry().spacing[size_t(c)], g.spacing[size_t(c)], 1e-12);
            EXPECT_NEAR(back.geometry().origin[size_t(c)], g.origin[size_t(c)], 1e-12);
        }
        for (size_t i = 0; i < v.size(); ++i) ASSERT_EQ(back.data()[i], float(v.data()[i])) << i;
    }
    // The NRRD's geometry without any option, from its own header.
    EXPECT_EQ(read_volume({dir / "a.nrrd"}).volume.geometry().origin, g.origin);
    // A writer destroyed before finish(), or one whose finish() finds slices missing, leaves nothing.
    TempDir part("slab_writer_part");
    for (const std::string name : {"b.nrrd", "b.tif", "p%02d.tif"}) {
        SCOPED_TRACE(name);
        {
            auto w = open_slab_writer(part / name, g);
            w->write(slab(0, 3));
        }
        EXPECT_TRUE(part.entries().empty()) << part.entries().front();
        {
            auto w = open_slab_writer(part / name, g);
            w->write(slab(0, 8));
            EXPECT_THROW(w->finish(), InvalidParameter);
        }
        EXPECT_TRUE(part.entries().empty()) << part.entries().front();
    }
    // Formats that cannot be written a slab at a time, and an unwritable place.
    EXPECT_THROW(open_slab_writer(part / "c.nii.gz", g), IoError);
    EXPECT_THROW(open_slab_writer(part / "c.mha", g), IoError);
    EXPECT_THROW(open_slab_writer(part / "no/such/dir/c.nrrd", g), IoError);
    // A slab of another width.
    auto w = open_slab_writer(part / "d.nrrd", g);
    Geometry narrow = g;
    narrow.dims[0] = 10;
    EXPECT_THROW(w->write(Volume<int16_t>(narrow)), InvalidParameter);
}
