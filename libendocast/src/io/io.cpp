// Reading and writing volumes with ITK: NRRD, NIfTI, MetaImage, DICOM series. ITK reads the
// headers of NRRD, NIfTI and DICOM; the data of a NRRD stored raw or gzip in one file is read
// directly (read_nrrd_fast: libdeflate, parallel conversion; the same voxels). A MetaImage is read
// here whole, header (metaimage_header.cpp) and voxels (read_metaimage_direct: ITK's MetaIO trusts
// its header and does not notice a truncated file); ITK only when asked (DirectReaders::metaimage
// = false, for tests that compare both). Headerless raw data is read by raw_io.cpp.
#include "endocast/io.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <regex>
#include <sstream>
#include <string_view>
#include <system_error>

#include <unistd.h>
#include <libdeflate.h>
#include <zlib.h>

#include <itkImage.h>
#include <itkImageFileReader.h>
#include <itkImageFileWriter.h>
#include <itkImageIOBase.h>
#include <itkImageSeriesReader.h>
#include <itkMetaDataObject.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>

#include "endocast/dicom_series.h"
#include "slice_stack.h"
#include "endocast/tiff.h"
#include "io/gdcm_api.h"
#include "io_internal.h"
#include "kernels/vec3.h"
#include "meshpost/text.h"

namespace endocast {

bool inflate_gzip_members(const unsigned char* data, size_t size, char* out, size_t want) {
    // The members' places from their "EC" subfields, each checked: the gzip magic, deflate, the
    // FEXTRA flag and the subfield first in an 8-byte extra field, a size that stays in the data.
    struct Member {
        size_t at, size, out_at, out_size;
    };
    std::vector<Member> members;
    size_t at = 0, out_at = 0;
    auto le = [&](size_t i, int bytes) {
        uint64_t v = 0;
        for (int k = bytes - 1; k >= 0; --k) v = v << 8 | data[i + size_t(k)];
        return v;
    };
    while (at < size) {
        if (size - at < kGzipMemberHeader + 8 || data[at] != 0x1f || data[at + 1] != 0x8b || data[at + 2] != 8 ||
            (data[at + 3] & 0x04) == 0 || le(at + 10, 2) != 8 || data[at + 12] != uint8_t(kGzipIndexId[0]) ||
            data[at + 13] != uint8_t(kGzipIndexId[1]) || le(at + 14, 2) != 4)
            return false;
        const size_t n = size_t(le(at + 16, 4));
        if (n < kGzipMemberHeader + 8 || n > size - at) return false;
        const size_t inflated = size_t(le(at + n - 4, 4));  // ISIZE (a member holds at most kGzipMemberBytes)
        if (inflated > kGzipMemberBytes || inflated > want - out_at) return false;
        members.push_back({at, n, out_at, inflated});
        at += n;
        out_at += inflated;
    }
    if (members.empty() || out_at != want) return false;
    struct Free {
        void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
    };
    bool ok = true;
    const int64_t count = int64_t(members.size());
#pragma omp parallel reduction(&& : ok)
    {
        std::unique_ptr<libdeflate_decompressor, Free> dec(libdeflate_alloc_decompressor());
        ok = ok && dec != nullptr;
#pragma omp for schedule(dynamic, 1)
        for (int64_t k = 0; k < count; ++k) {
            const Member& m = members[size_t(k)];
            size_t made = 0;
            ok = ok && dec && libdeflate_gzip_decompress(dec.get(), data + m.at, m.size, out + m.out_at, m.out_size, &made) ==
                                  LIBDEFLATE_SUCCESS &&
                 made == m.out_size;
        }
    }
    return ok;
}

namespace {

using meshpost::text::ends_with;
using meshpost::text::lower;

namespace fs = std::filesystem;
using FloatImage = itk::Image<float, 3>;
using HeaderCheck = std::function<void(const VolumeHeader&)>;

enum class FileFormat { Unknown, Nrrd, Nifti, MetaImage };

const char* const kKnownExtensions = ".nrrd, .nhdr, .nii, .nii.gz, .mha or .mhd";

FileFormat format_of(const std::string& path) {
    const std::string name = lower(fs::path(path).filename().string());
    if (ends_with(name, ".nrrd") || ends_with(name, ".nhdr")) return FileFormat::Nrrd;
    if (ends_with(name, ".nii") || ends_with(name, ".nii.gz")) return FileFormat::Nifti;
    if (ends_with(name, ".mha") || ends_with(name, ".mhd")) return FileFormat::MetaImage;
    return FileFormat::Unknown;
}

const char* format_name(FileFormat f) {
    switch (f) {
        case FileFormat::Nrrd: return "nrrd";
        case FileFormat::Nifti: return "nifti";
        case FileFormat::MetaImage: return "metaimage";
        case FileFormat::Unknown: break;
    }
    return "unknown";
}

itk::ImageIOBase::Pointer make_image_io(FileFormat f) {
    switch (f) {
        case FileFormat::Nrrd: return itk::NrrdImageIO::New().GetPointer();
        case FileFormat::Nifti: return itk::NiftiImageIO::New().GetPointer();
        case FileFormat::MetaImage: return itk::MetaImageIO::New().GetPointer();
        case FileFormat::Unknown: break;
    }
    return nullptr;
}

/// ITK's description of an exception on one line, whitespace collapsed.
std::string describe(const itk::ExceptionObject& e) {
    const char* d = e.GetDescription();
    std::string in = d ? d : "";
    if (in.empty()) in = e.what();
    std::string out;
    bool space = false;
    for (char c : in) {
        if (std::isspace(static_cast<unsigned char>(c))) {
            space = !out.empty();
        } else {
            if (space) out += ' ';
            space = false;
            out += c;
        }
    }
    // Drop ITK's "itk::ERROR: NrrdImageIO(0x55d0...): " prefix: the address varies between runs.
    static const std::regex prefix(R"(^(itk::ERROR: |ITK ERROR: )?(\w+\(0x[0-9a-fA-F]+\): )?)");
    out = std::regex_replace(out, prefix, "", std::regex_constants::format_first_only);
    static const std::regex address(R"( ?\(0x[0-9a-fA-F]+\))");  // "ImageRegion (0x7fff...)"
    out = std::regex_replace(out, address, "");
    return out.empty() ? std::string("unknown ITK error") : out;
}

/// Stored component type as "uint16", "float32", ...
std::string component_name(itk::IOComponentEnum c) {
    using C = itk::IOComponentEnum;
    auto sized = [](const char* prefix, size_t bytes) {
        return std::string(prefix) + std::to_string(8 * bytes);
    };
    switch (c) {
        case C::UCHAR: return sized("uint", sizeof(unsigned char));
        case C::CHAR: return sized("int", sizeof(char));
        case C::USHORT: return sized("uint", sizeof(unsigned short));
        case C::SHORT: return sized("int", sizeof(short));
        case C::UINT: return sized("uint", sizeof(unsigned int));
        case C::INT: return sized("int", sizeof(int));
        case C::ULONG: return sized("uint", sizeof(unsigned long));
        case C::LONG: return sized("int", sizeof(long));
        case C::ULONGLONG: return sized("uint", sizeof(unsigned long long));
        case C::LONGLONG: return sized("int", sizeof(long long));
        case C::FLOAT: return sized("float", sizeof(float));
        case C::DOUBLE: return sized("float", sizeof(double));
        default: break;
    }
    return "unknown";
}

/// Copies an ITK float image (geometry and voxels) into a Volume, validating it.
/// Rejects what a reader may leave us with but the method cannot use: sizes, spacing,
/// origin or direction that are not finite and positive, and non-finite voxels (looked for unless
/// the stored values were integers, which convert to finite floats).
void check_read_volume(const Volume<float>& v, const std::string& what, bool stored_integers = false) {
    const Geometry& g = v.geometry();
    for (int a = 0; a < 3; ++a) {
        if (g.dims[a] <= 0)
            throw InvalidParameter(what + ": size " + std::to_string(g.dims[0]) + " x " +
                                   std::to_string(g.dims[1]) + " x " + std::to_string(g.dims[2]) +
                                   ", expected every dimension > 0");
        if (!std::isfinite(g.spacing[a]) || g.spacing[a] <= 0)
            throw InvalidParameter(what + ": spacing " + meshpost::text::point(g.spacing) +
                                   ", expected finite values > 0");
        if (!std::isfinite(g.origin[a]))
            throw InvalidParameter(what + ": origin " + meshpost::text::point(g.origin) +
                                   ", expected finite values");
    }
    for (double d : g.direction)
        if (!std::isfinite(d))
            throw InvalidParameter(what + ": direction matrix has non-finite entries");
    if (stored_integers) return;
    const std::string bad = describe_non_finite(v);
    if (!bad.empty()) throw InvalidParameter(what + ": " + bad + ", expected finite values");
}

/// The size (largest possible region), spacing, origin and direction of an ITK image.
Geometry geometry_of(const FloatImage* img) {
    const auto region = img->GetLargestPossibleRegion();
    Geometry g;
    for (unsigned a = 0; a < 3; ++a) {
        g.dims[a] = static_cast<int64_t>(region.GetSize()[a]);
        g.spacing[a] = img->GetSpacing()[a];
        g.origin[a] = img->GetOrigin()[a];
        for (unsigned c = 0; c < 3; ++c) g.direction[3 * a + c] = img->GetDirection()(a, c);
    }
    return g;
}

Volume<float> to_volume(const FloatImage* img, const std::string& what) {
    const auto region = img->GetLargestPossibleRegion();
    const Geometry g = geometry_of(img);
    const float* src = img->GetBufferPointer();
    if (img->GetBufferedRegion() != region || src == nullptr)
        throw IoError(what + ": ITK did not buffer the whole image");
    Volume<float> v;  // one pass over new memory: no zero fill before the copy
    v.geometry() = g;
    v.buffer().assign(src, src + g.voxel_count());
    check_read_volume(v, what);
    return v;
}

constexpr uint64_t kMaxVoxels = uint64_t{1} << 40;

/// Rejects declared sizes of 0 or more than 2^40 voxels (a corrupt or hostile header) before
/// anything is allocated.
void check_declared_size(const Dims& d, const std::string& what) {
    const std::string size =
        std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " + std::to_string(d[2]);
    uint64_t n = 1;
    for (int a = 0; a < 3; ++a) {
        if (d[a] <= 0)
            throw IoError(what + ": header declares a size of " + size +
                          " voxels, expected every dimension > 0");
        if (static_cast<uint64_t>(d[a]) > kMaxVoxels / n)
            throw IoError(what + ": header declares a size of " + size +
                          " voxels, more than the 2^40 voxels this program reads");
        n *= static_cast<uint64_t>(d[a]);
    }
}

/// Whether a NIfTI-1 header `h` (at least 348 bytes) is in the other byte order than the host,
/// decided as nifti_clib (ITK) decides: dim[0] in 1..7, else sizeof_hdr == 348. Unset when neither
/// order gives a valid header (ITK rejects it).
std::optional<bool> nifti_swapped(const unsigned char* h) {
    auto valid_dim0 = [&](bool swap) {
        unsigned char b[2] = {h[40], h[41]};
        if (swap) std::swap(b[0], b[1]);
        int16_t d0;
        std::memcpy(&d0, b, 2);
        return d0 >= 1 && d0 <= 7;
    };
    if (valid_dim0(false)) return false;
    if (valid_dim0(true)) return true;
    const bool little = h[0] == 0x5c && h[1] == 0x01 && h[2] == 0 && h[3] == 0;
    const bool big = h[0] == 0 && h[1] == 0 && h[2] == 0x01 && h[3] == 0x5c;
    if (!little && !big) return std::nullopt;
    return little != host_is_little_endian();
}

/// A single-file NIfTI (.nii, not gzipped) must hold vox_offset + the voxels; ITK's reader does not
/// notice a truncated file (it returns an image padded with zeros), so this is checked here.
void check_nifti_length(const std::string& path, uint64_t image_bytes) {
    std::ifstream in(path, std::ios::binary);
    unsigned char h[348];
    if (!in.read(reinterpret_cast<char*>(h), sizeof h)) return;  // ITK has read it: cannot happen
    const std::optional<bool> swap = nifti_swapped(h);
    if (!swap) return;  // ITK has read it: cannot happen
    unsigned char f[4] = {h[108], h[109], h[110], h[111]};
    if (*swap) std::reverse(f, f + 4);
    float vox_offset = 0;
    std::memcpy(&vox_offset, f, 4);
    std::error_code ec;
    const uint64_t have = fs::file_size(path, ec);
    if (ec) return;  // ITK has read it: cannot happen
    // Compared as floating point first: converting a float beyond 2^64 to an integer is undefined
    // (a fuzzed header with vox_offset 4.7e27 did that).
    if (std::isfinite(vox_offset) && vox_offset > static_cast<double>(have)) {
        std::ostringstream m;
        m << path << ": header declares voxels from byte " << vox_offset
          << " on (vox_offset), beyond the end of the file (" << have
          << " bytes): file truncated or header corrupt";
        throw IoError(m.str());
    }
    const uint64_t offset = std::isfinite(vox_offset) && vox_offset >= 352 ? uint64_t(vox_offset) : 352;
    if (have < offset + image_bytes)
        throw IoError(path + ": holds " + std::to_string(have) + " bytes, expected " +
                      std::to_string(offset + image_bytes) + " (voxels from byte " +
                      std::to_string(offset) + " on, as the header declares): file truncated");
}

/// Rejects a NIfTI-1 header (.nii or .nii.gz) whose geometry fields are not finite or absurdly
/// large, before ITK sees it: ITK 5.2 builds the orientation matrix from them and vnl_svd calls
/// abort() on a non-finite matrix (fuzz_nifti: a NaN in srow_y). Headers that are not NIfTI-1 are
/// left to ITK, which rejects them.
void check_nifti_geometry(const std::string& path) {
    unsigned char h[348];
    gzFile gz = gzopen(path.c_str(), "rb");  // reads uncompressed files as they are
    if (!gz) return;
    const int got = gzread(gz, h, sizeof h);
    gzclose(gz);
    if (got != static_cast<int>(sizeof h)) return;
    const std::optional<bool> swapped = nifti_swapped(h);
    if (!swapped) return;
    const bool swap = *swapped;
    auto field = [&](size_t at, size_t n) {  // n bytes in host order
        std::array<unsigned char, 4> b{};
        std::memcpy(b.data(), h + at, n);
        if (swap) std::reverse(b.begin(), b.begin() + long(n));
        return b;
    };
    auto f32 = [&](size_t at) {
        float v;
        std::memcpy(&v, field(at, 4).data(), 4);
        return v;
    };
    auto i16 = [&](size_t at) {
        int16_t v;
        std::memcpy(&v, field(at, 2).data(), 2);
        return v;
    };
    // Byte offsets of the NIfTI-1 header (nifti1.h).
    struct Field { const char* name; size_t at; int count; bool used; };
    const Field fields[] = {{"pixdim[1..3]", 80, 3, true},
                            {"quatern_b/c/d, qoffset_x/y/z", 256, 6, i16(252) > 0},
                            {"srow_x/y/z", 280, 12, i16(254) > 0}};
    constexpr float kMax = 1e10f;  // mm; far beyond any scanner, far below float overflow
    for (const Field& fd : fields) {
        if (!fd.used) continue;
        for (int i = 0; i < fd.count; ++i) {
            const float v = f32(fd.at + 4 * size_t(i));
            if (std::isfinite(v) && std::abs(v) <= kMax) continue;
            std::ostringstream m;
            m << path << ": NIfTI header field " << fd.name << " holds " << v
              << ", expected finite values of magnitude at most " << kMax;
            throw IoError(m.str());
        }
    }
}

/// MetaIO reads an ElementDataFile holding '%' as a printf pattern of a slice series
/// ("slice%03d.raw 1 40 1") and formats it with one int: any other conversion (%s, %n, two of them)
/// makes ITK 5.2 read past its arguments (fuzz_mhd: "ElementDataFile =%%%s1", a SEGV in snprintf).
/// Allows "%%" and at most one %d/%i with flags and width; rejects the rest.
void check_metaimage_data_file(const std::string& path, const std::string& value) {
    int conversions = 0;
    for (size_t i = 0; i < value.size(); ++i) {
        if (value[i] != '%') continue;
        if (i + 1 < value.size() && value[i + 1] == '%') {
            ++i;
            continue;
        }
        size_t j = i + 1;
        while (j < value.size() && std::strchr("-+ #0123456789", value[j])) ++j;
        if (j >= value.size() || (value[j] != 'd' && value[j] != 'i') || ++conversions > 1)
            throw IoError(path + ": MetaImage ElementDataFile '" + value.substr(0, 60) +
                          "' is not a file name or a slice pattern with one %d");
        i = j;
    }
    if (value.find('%') == std::string::npos) return;
    // Any '%' makes it a slice series for MetaIO ("%%" alone too): "pattern" alone (slices 1..N) or
    // "pattern first last step". MetaIO divides by the step it derives from 2 or 3 words, or reads
    // a non-number as 0 (fuzz_mhd: FPEs in MetaImage::ReadStream), so only those two forms with
    // whole numbers are passed on.
    // MetaIO splits it at single spaces only, into 80-byte words (MET_StringToWordArray: a longer
    // word overflowed the heap, runs of spaces miscount the words; fuzz_mhd), so the words are
    // split here the same way and must be 1 to 79 bytes without other white space.
    std::string t = value;
    t.erase(0, t.find_first_not_of(' '));
    t.erase(t.find_last_not_of(' ') + 1);
    std::vector<std::string> w;
    bool words_ok = !t.empty();
    for (size_t at = 0; words_ok && at <= t.size();) {
        const size_t space = std::min(t.find(' ', at), t.size());
        w.push_back(t.substr(at, space - at));
        const std::string& word = w.back();
        words_ok = !word.empty() && word.size() <= 79 &&
                   word.find_first_of(std::string("\t\v\f\r\0", 5)) == std::string::npos;
        at = space + 1;
    }
    if (!words_ok)
        throw IoError(path + ": MetaImage ElementDataFile '" + value.substr(0, 60) +
                      "' is a slice pattern (it holds '%') but not words of 1 to 79 characters "
                      "separated by single spaces");
    const auto whole = [](const std::string& t, long& out) {
        errno = 0;
        char* end = nullptr;
        out = std::strtol(t.c_str(), &end, 10);
        return end != t.c_str() && *end == '\0' && errno != ERANGE;
    };
    long first = 0, last = 0, step = 0;
    const bool ok = w.size() == 1 ||
                    (w.size() == 4 && whole(w[1], first) && whole(w[2], last) && whole(w[3], step) &&
                     first >= 0 && last >= first && step >= 1 && (last - first) / step < 1000000);
    if (!ok)
        throw IoError(path + ": MetaImage ElementDataFile '" + value.substr(0, 60) +
                      "' is not a slice pattern 'name%03d.raw' or 'name%03d.raw FIRST LAST STEP' "
                      "with whole numbers 0 <= FIRST <= LAST and STEP >= 1");
}

/// Checks a MetaImage header before ITK 5.2's MetaIO parses it, because MetaIO trusts it:
///  - a field name (MetaIO reads it from the end of the previous value up to the next '=' or ':',
///    across lines) of 255 characters or more overflows a strcpy into a 255-byte buffer
///    (MET_InitReadField; fuzz_mhd), so a name that may be that long is rejected;
///  - "NDims = 5555...5" kept it busy for minutes (NDims x NDims transform values; fuzz_mhd), and a
///    second, different NDims left dimensions uninitialised;
///  - ElementDataFile is a printf pattern (check_metaimage_data_file).
/// Only the file's first 64 KiB are read; the header ends with the ElementDataFile value's line.
void check_metaimage_header(const std::string& path) {
    constexpr size_t kMaxHeader = 1u << 16;
    constexpr size_t kMaxField = 254;  // MetaIO's field names hold 255 bytes with the terminator
    std::ifstream in(path, std::ios::binary);
    std::string head(kMaxHeader, '\0');
    in.read(head.data(), std::streamsize(head.size()));
    head.resize(size_t(in.gcount()));
    // MetaIO reads a name from the end of the previous value up to the next '=' or ':', across
    // lines, and compares it as a C string (up to its first NUL, trailing blanks trimmed). Where the
    // previous value ends depends on its field's type, so every separator is taken as the end of a
    // name that may start anywhere after the previous separator.
    std::vector<size_t> seps;
    for (size_t i = 0; i < head.size(); ++i)
        if (head[i] == '=' || head[i] == ':') seps.push_back(i);
    // MetaIO reads a string value (ElementDataFile, Comment) with getline: up to '\n' only, a '\r'
    // inside kept, trailing white space stripped (fuzz_mhd: "name\rword%% 0 1 2" was a pattern to
    // MetaIO, a file name here, and overflowed its word buffer).
    const auto line_end = [&](size_t from) { return std::min(head.find('\n', from), head.size()); };
    // True when the name ending at separator k may be `key` for MetaIO. A name also ends at a line
    // end, and MetaIO then seeks its value past the next separator ("ElementDataFile \nx = v" is
    // ElementDataFile = v to it; fuzz_mhd, 2026-12-06: a slice pattern read so).
    const auto may_be = [&](size_t k, const std::string& key) {
        const size_t lo = k == 0 ? 0 : seps[k - 1] + 1, sep = seps[k];
        for (size_t p = lo; p + key.size() <= sep; ++p) {
            if (head.compare(p, key.size(), key) != 0) continue;
            const size_t rest = p + key.size();
            const size_t next = head.find_first_not_of(" \t", rest);
            if (rest == sep || head[rest] == '\0' || next >= sep || head[next] == '\n' || head[next] == '\r')
                return true;
        }
        return false;
    };
    // The header ends with the ElementDataFile value's line (the last candidate in the window: the
    // data after it hold no such name). For that end the name must be ElementDataFile for MetaIO
    // for certain: at the start of its line (after blanks), as a C string. A candidate preceded by
    // other bytes on its line ("\bElementDataFile =", fuzz_mhd) may not be one to MetaIO, which
    // then reads on as header: the names after it are checked too.
    const auto surely_data_file = [&](size_t k) {
        const std::string key = "ElementDataFile";
        const size_t lo = k == 0 ? 0 : seps[k - 1] + 1, sep = seps[k];
        for (size_t p = lo; p + key.size() <= sep; ++p) {
            if (head.compare(p, key.size(), key) != 0) continue;
            size_t b = p;
            while (b > lo && (head[b - 1] == ' ' || head[b - 1] == '\t')) --b;
            if (!(b == 0 || head[b - 1] == '\n')) continue;
            // Nor other text between the previous value's line (the file's start for the first
            // separator) and it: MetaIO's name starts after that value, so "Word\nElementDataFile"
            // is one unknown name to it, and it reads on (fuzz_mhd in .ci/run, 2026-12-05 after a
            // value, 2026-12-06 before the first separator: a name of 255+ bytes after it, strcpy
            // overflow).
            if (head.find_first_not_of(" \t\r\n", k == 0 ? 0 : line_end(seps[k - 1])) < p) continue;
            const size_t rest = p + key.size();
            if (rest == sep || head[rest] == '\0' || head.find_first_not_of(" \t", rest) >= sep) return true;
        }
        return false;
    };
    std::vector<uint8_t> is_data_file(seps.size());
    size_t data_file = seps.size();
    for (size_t k = 0; k < seps.size(); ++k) {
        is_data_file[k] = may_be(k, "ElementDataFile");
        if (is_data_file[k] && surely_data_file(k)) data_file = k;
    }
    if (data_file == seps.size() && head.size() == kMaxHeader)
        throw IoError(path + ": MetaImage header has no ElementDataFile line in its first " +
                      std::to_string(kMaxHeader / 1024) +
                      " KiB, expected a text header that ends with 'ElementDataFile = ...'");
    // Without one, MetaIO reads the whole (short) file as header: every name is checked.
    const size_t last = data_file == seps.size() ? seps.size() : data_file + 1;
    long ndims_seen = 0;
    for (size_t k = 0; k < last; ++k) {
        // A name: at most the text since the previous separator (since the end of its line after a
        // comment, a string value read to the end of its line).
        size_t from = k == 0 ? 0 : seps[k - 1] + 1;
        if (k > 0 && may_be(k - 1, "Comment")) from = line_end(seps[k - 1]);
        const size_t first = head.find_first_not_of(" \t\r\n\v\f", from);
        const size_t n = first < seps[k] ? seps[k] - first : 0;
        const size_t value_end = line_end(seps[k]);
        if (n > kMaxField || (k == data_file && value_end - seps[k] - 1 > kMaxField)) {
            const long line_no = long(std::count(head.begin(), head.begin() + long(seps[k]), '\n')) + 1;
            std::ostringstream m;
            m << path << ": MetaImage header: the " << (n > kMaxField ? "field name" : "ElementDataFile value")
              << " ending on line " << line_no << " is " << (n > kMaxField ? n : value_end - seps[k] - 1)
              << " characters long (MetaIO reads a name up to the next '=' or ':', across lines), "
                 "expected 'Name = value' lines with names and values of at most "
              << kMaxField << " characters";
            throw IoError(m.str());
        }
        std::string value = head.substr(seps[k] + 1, value_end - seps[k] - 1);
        while (!value.empty() && std::isspace(static_cast<unsigned char>(value.back()))) value.pop_back();
        if (is_data_file[k]) check_metaimage_data_file(path, value);
        // The data file's name as MetaIO uses it (a C string: up to its first NUL) must not be
        // empty: MetaIO opens "" as the data file, fails to measure it and allocates that size, -1,
        // for compressed data (fuzz_mhd in .ci/run, 2026-12-02: ASan allocation-size-too-big).
        if (k == data_file && value.substr(0, value.find('\0')).find_first_not_of(" \t\r") == std::string::npos)
            throw IoError(path + ": MetaImage ElementDataFile is empty, expected LOCAL (the data follow the "
                                 "header) or the name of the data file");
        if (!may_be(k, "NDims")) continue;
        errno = 0;
        char* end = nullptr;
        const long dims = std::strtol(value.c_str(), &end, 10);
        if (end == value.c_str() || errno == ERANGE || dims < 1 || dims > 16)
            throw IoError(path + ": MetaImage header declares NDims =" + value.substr(0, 40) +
                          ", expected a number of dimensions from 1 to 16 (3 for a volume)");
        // A second, different NDims (fuzz_mhd under valgrind: "NDims = 3 ... DimSize = 3 4 4 ...
        // NDims = 4"): MetaIO then takes dimensions it never read, uninitialised.
        if (ndims_seen != 0 && dims != ndims_seen)
            throw IoError(path + ": MetaImage header declares NDims twice (" + std::to_string(ndims_seen) +
                          ", then " + std::to_string(dims) + "), expected it once");
        ndims_seen = dims;
    }
}

/// The stored type of an ITK component as a RawType; nullopt for 64-bit integers.
std::optional<RawType> raw_type_of(itk::IOComponentEnum c, size_t bytes) {
    using C = itk::IOComponentEnum;
    const bool is_signed = c == C::CHAR || c == C::SHORT || c == C::INT || c == C::LONG || c == C::LONGLONG;
    if (c == C::FLOAT && bytes == 4) return RawType::Float32;
    if (c == C::DOUBLE && bytes == 8) return RawType::Float64;
    if (c == C::FLOAT || c == C::DOUBLE) return std::nullopt;
    switch (bytes) {
        case 1: return is_signed ? RawType::Int8 : RawType::UInt8;
        case 2: return is_signed ? RawType::Int16 : RawType::UInt16;
        case 4: return is_signed ? RawType::Int32 : RawType::UInt32;
        default: return std::nullopt;
    }
}

/// Where a NRRD file's data is, from its header: the encoding, the byte order and either the
/// offset of attached data or the one detached data file. `head` is the file's start (at least
/// its header).
struct NrrdData {
    bool gzip = false;
    bool swap = false;
    std::string data_file;                     ///< the detached data file's path; empty: attached
    size_t data_offset = std::string::npos;    ///< attached: where the data starts in the file
};

/// NrrdData for the header at the start of `head`, or nullopt for what we do not read ourselves:
/// other encodings, line or byte skips, lists or patterns of data files, a multi-byte type without
/// "endian", or a header we cannot parse.
std::optional<NrrdData> parse_nrrd_data(std::string_view head, const std::string& path, size_t bytes_per) {
    if (head.compare(0, 7, "NRRD000") != 0) return std::nullopt;
    // Header lines up to the first empty line (attached data follows it) or the end of the file.
    std::string encoding, data_file, endian;
    size_t pos = head.find('\n');
    NrrdData d;
    while (pos != std::string::npos && pos + 1 <= head.size()) {
        const size_t start = pos + 1;
        if (start == head.size()) break;
        const size_t end = head.find('\n', start);
        if (end == std::string::npos) return std::nullopt;  // a last line without newline
        const std::string line(head.substr(start, end - start));
        pos = end;
        if (line.empty()) {
            d.data_offset = end + 1;
            break;
        }
        if (line.find('\r') != std::string::npos || line.find('\0') != std::string::npos) return std::nullopt;
        if (line[0] == '#' || line.find(":=") != std::string::npos) continue;  // comment, key/value
        const size_t colon = line.find(": ");
        if (colon == std::string::npos) return std::nullopt;
        const std::string key = lower(line.substr(0, colon));
        std::string value = line.substr(colon + 2);
        while (!value.empty() && value.back() == ' ') value.pop_back();
        if (key == "encoding") encoding = lower(value);
        else if (key == "data file" || key == "datafile") data_file = value;
        else if (key == "endian") endian = lower(value);
        else if (key == "line skip" || key == "lineskip" || key == "byte skip" || key == "byteskip") {
            if (value != "0") return std::nullopt;
        }
    }
    d.gzip = encoding == "gzip" || encoding == "gz";
    if (!d.gzip && encoding != "raw") return std::nullopt;
    if (bytes_per > 1) {
        if (endian != "little" && endian != "big") return std::nullopt;
        d.swap = (endian == "little") != host_is_little_endian();
    }
    if (!data_file.empty()) {
        if (data_file.find_first_of("% ") != std::string::npos || data_file == "LIST") return std::nullopt;
        fs::path df(data_file);
        if (df.is_relative()) df = fs::path(path).parent_path() / df;
        d.data_file = df.string();
        d.data_offset = std::string::npos;
    } else if (d.data_offset == std::string::npos) {
        return std::nullopt;
    }
    return d;
}

/// The voxels of a NRRD file whose data is raw or gzip in one file (attached, or detached in one
/// "data file"), read here instead of by ITK: the file at once, gzip inflated by libdeflate (about
/// three times zlib's speed: CThead's read 0.14 -> ~0.06 s), converted to float in parallel. ITK
/// has read the header (`io`, `g`); parse_nrrd_data says where the bytes are. Anything else
/// or anything unexpected returns nullopt and ITK reads the file as before (and reports what is
/// wrong): see parse_nrrd_data, and a data size other than the header's or a singular direction
/// matrix.
// The data of a NRRD that read_nrrd_fast reads: the file's bytes (and the detached data file's),
// where the voxels are, and how they are stored.
struct NrrdVoxels {
    RawType type = RawType::UInt8;
    bool gzip = false, swap = false;
    std::optional<FileBytes> file, detached;
    std::string_view data;  // the voxels' bytes (gzip: compressed)
};

std::optional<NrrdVoxels> locate_nrrd_voxels(const std::string& path, const itk::ImageIOBase& io) {
    NrrdVoxels n;
    const std::optional<RawType> type = raw_type_of(io.GetComponentType(), io.GetComponentSize());
    if (!type) return std::nullopt;
    n.type = *type;
    n.file = FileBytes::open(path);
    if (!n.file) return std::nullopt;
    const std::optional<NrrdData> where = parse_nrrd_data(n.file->view(), path, raw_type_size(n.type));
    if (!where) return std::nullopt;
    n.gzip = where->gzip, n.swap = where->swap;
    if (!where->data_file.empty()) {
        n.detached = FileBytes::open(where->data_file);
        if (!n.detached) return std::nullopt;
        n.file.reset();  // the header's bytes are not needed any more
        n.data = n.detached->view();
    } else {
        n.data = n.file->view().substr(where->data_offset);
    }
    return n;
}

// Inflates the gzip data into want bytes at out (a gzip file may hold several members; their
// data is concatenated); false unless it holds exactly want bytes. Members indexed as
// write_nrrd_gzip writes them are inflated on all threads.
bool inflate_nrrd_voxels(std::string_view data, char* out, size_t want) {
    if (inflate_gzip_members(reinterpret_cast<const unsigned char*>(data.data()), data.size(), out, want)) return true;
    struct Free {
        void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
    };
    std::unique_ptr<libdeflate_decompressor, Free> dec(libdeflate_alloc_decompressor());
    if (!dec) return false;
    size_t in_at = 0, out_at = 0;
    while (out_at < want) {
        size_t in_used = 0, out_made = 0;
        const libdeflate_result res = libdeflate_gzip_decompress_ex(dec.get(), data.data() + in_at, data.size() - in_at,
                                                                    out + out_at, want - out_at, &in_used, &out_made);
        if (res != LIBDEFLATE_SUCCESS || out_made == 0) return false;
        in_at += in_used;
        out_at += out_made;
        if (out_at < want && in_at >= data.size()) return false;  // ends early
    }
    return in_at == data.size();  // not more data than the header says
}

std::optional<Volume<float>> read_nrrd_fast(const std::string& path, const itk::ImageIOBase& io,
                                            const Geometry& g) {
    std::optional<NrrdVoxels> n = locate_nrrd_voxels(path, io);
    if (!n) return std::nullopt;
    const size_t voxels = g.voxel_count();
    const size_t want = voxels * raw_type_size(n->type);
    std::string stored;
    if (n->gzip) {
        stored.resize(want);
        if (!inflate_nrrd_voxels(n->data, stored.data(), want)) return std::nullopt;
        n->file.reset(), n->detached.reset();  // the compressed bytes, before the float volume
    } else if (n->data.size() != want) {
        return std::nullopt;
    }
    const unsigned char* src = reinterpret_cast<const unsigned char*>(n->gzip ? stored.data() : n->data.data());
    Volume<float> v;
    v.geometry() = g;
    v.buffer().resize(voxels);
    convert_in_parallel(n->type, src, voxels, n->swap, v.data());
    return v;
}

// read_nrrd_fast's voxels as int16, for data stored as 8- or 16-bit integers whose every value
// fits (uint16 up to 32767): inflated straight into the volume, never held as float (the 512 x
// 512 x 300 phantom: 157 MB instead of 157 + 314 while it is read). nullopt for anything else.
std::optional<Volume<int16_t>> read_nrrd_int16(const std::string& path, const itk::ImageIOBase& io, const Geometry& g) {
    // The type from the header first: any other is read once, by read_nrrd_fast.
    const std::optional<RawType> type = raw_type_of(io.GetComponentType(), io.GetComponentSize());
    if (!type) return std::nullopt;
    const RawType t = *type;
    const bool wide = t == RawType::Int16 || t == RawType::UInt16;
    if (!wide && t != RawType::Int8 && t != RawType::UInt8) return std::nullopt;
    std::optional<NrrdVoxels> n = locate_nrrd_voxels(path, io);
    if (!n) return std::nullopt;
    const size_t voxels = g.voxel_count();
    const size_t want = voxels * raw_type_size(t);
    if (!n->gzip && n->data.size() != want) return std::nullopt;
    Volume<int16_t> v;
    v.geometry() = g;
    v.buffer().resize(voxels);
    int16_t* out = v.data();
    const int64_t count = int64_t(voxels);
    if (wide) {
        char* bytes = reinterpret_cast<char*>(out);
        if (n->gzip) {
            if (!inflate_nrrd_voxels(n->data, bytes, want)) return std::nullopt;
        } else {
            std::memcpy(bytes, n->data.data(), want);
        }
        n->file.reset(), n->detached.reset();
        // The bytes swapped where the file's order is not the host's, then for uint16 the largest
        // value: above 32767 the volume is read as float. Two plain loops (the compiler vectorizes
        // them; a signed and an unsigned view of the same integers may alias): cthead's 7.4 M
        // voxels took 10-12 ms on two threads in one loop that reloaded the swap flag per voxel.
        uint16_t* u = reinterpret_cast<uint16_t*>(out);
        if (n->swap) {
#pragma omp parallel for schedule(static)
            for (int64_t i = 0; i < count; ++i) u[i] = uint16_t((u[i] >> 8) | (u[i] << 8));
        }
        if (t == RawType::UInt16) {
            uint16_t largest = 0;
#pragma omp parallel for schedule(static) reduction(max : largest)
            for (int64_t i = 0; i < count; ++i) largest = std::max(largest, u[i]);
            if (largest > 32767) return std::nullopt;
        }
        return v;
    }
    std::string stored;
    if (n->gzip) {
        stored.resize(want);
        if (!inflate_nrrd_voxels(n->data, stored.data(), want)) return std::nullopt;
    }
    const char* src = n->gzip ? stored.data() : n->data.data();
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < count; ++i)
        out[i] = t == RawType::Int8 ? int16_t(static_cast<signed char>(src[i])) : int16_t(static_cast<unsigned char>(src[i]));
    return v;
}

/// `n` MetaImage ASCII voxels (BinaryData = False) from `text` into `out`, as MetaIO reads them:
/// per voxel a number (white space before it skipped) and one separator character after it, the
/// number cast to the element type (here clamped to its range first) and then to float. Fewer
/// numbers is an IoError (MetaIO left the rest uninitialised).
void parse_metaimage_ascii(std::string_view text, RawType type, size_t n, float* out, const std::string& path,
                           const std::string& data_path, uint64_t start, bool int64 = false) {
    const std::string buf(text);  // NUL-terminated for strtod
    const char* p = buf.c_str();
    const char* const end = p + buf.size();
    const auto cast = [type, int64](double x) -> float {
        if (int64) return float(std::trunc(x));  // 64-bit integers (type Float64 then)
        const auto to = [x](double lo, double hi) { return std::trunc(std::clamp(x, lo, hi)); };
        switch (type) {
            case RawType::UInt8: return float(to(0, 255));
            case RawType::Int8: return float(to(-128, 127));
            case RawType::UInt16: return float(to(0, 65535));
            case RawType::Int16: return float(to(-32768, 32767));
            case RawType::UInt32: return float(uint32_t(to(0, 4294967295.0)));
            case RawType::Int32: return float(int32_t(to(-2147483648.0, 2147483647.0)));
            default: return float(x);
        }
    };
    for (size_t i = 0; i < n; ++i) {
        while (p < end && std::isspace(static_cast<unsigned char>(*p))) ++p;
        // A number as a C++ stream reads one: no "nan", "inf" or hexadecimal.
        const char* digits = p < end && (*p == '-' || *p == '+') ? p + 1 : p;
        const bool numeric = digits < end && (std::isdigit(static_cast<unsigned char>(*digits)) || *digits == '.') &&
                             !(digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X'));
        char* after = nullptr;
        const double x = numeric ? std::strtod(p, &after) : 0;
        if (!numeric || after == p || !std::isfinite(x)) {
            std::ostringstream m;
            m << data_path << ": holds " << i << " ASCII voxel values from byte " << start << " on, expected "
              << n << " as the header " << path << " declares (BinaryData = False): file truncated or corrupt";
            throw IoError(m.str());
        }
        out[i] = cast(x);
        p = after;
        if (p < end) ++p;  // MetaIO reads one character after each number
    }
}

/// The file names of a MetaImage slice pattern ("name%03d.raw", slices 1 to N, or "name%03d.raw
/// FIRST LAST STEP"; check_metaimage_data_file has allowed only these forms), beside the header
/// when relative. IoError unless they are exactly `slices` names.
std::vector<std::string> metaimage_pattern_files(const std::string& path, const std::string& value, int64_t slices) {
    std::istringstream words(value);
    std::vector<std::string> w;
    for (std::string t; words >> t;) w.push_back(t);
    long first = 1, last = long(slices), step = 1;
    if (w.size() == 4) {
        first = std::strtol(w[1].c_str(), nullptr, 10);
        last = std::strtol(w[2].c_str(), nullptr, 10);
        step = std::strtol(w[3].c_str(), nullptr, 10);
    }
    if (w.size() != 1 && w.size() != 4) throw IoError(path + ": MetaImage ElementDataFile '" + value + "' is not a slice pattern");
    if (step < 1 || last < first || (last - first) / step + 1 != slices)
        throw IoError(path + ": MetaImage slice pattern '" + value + "' names " +
                      std::to_string(step < 1 || last < first ? 0 : (last - first) / step + 1) + " slice files, expected " +
                      std::to_string(slices) + " (DimSize along z)");
    for (size_t at = w[0].find('%'); at != std::string::npos; at = w[0].find('%', at + 1)) {
        size_t d = at + 1;
        while (d < w[0].size() && std::strchr("-+ #0", w[0][d])) ++d;
        size_t digits = 0;
        while (d + digits < w[0].size() && std::isdigit(static_cast<unsigned char>(w[0][d + digits]))) ++digits;
        if (digits > 2)
            throw IoError(path + ": MetaImage slice pattern '" + value + "': a field width of at most 2 digits expected");
        if (d < w[0].size() && w[0][d] == '%') at = d;  // "%%"
    }
    std::vector<std::string> files;
    for (long i = first; i <= last; i += step) {
        char name[512];
        // The pattern holds at most one %d or %i with flags and a width of at most 2 digits
        // (check_metaimage_data_file), so it is a safe format for one int.
        std::snprintf(name, sizeof name, w[0].c_str(), int(i));  // NOLINT(cert-err33-c)
        fs::path f(name);
        if (f.is_relative()) f = fs::path(path).parent_path() / f;
        files.push_back(f.string());
    }
    return files;
}

/// InvalidParameter unless an image of these sizes (one per dimension) and components per voxel is
/// a 3-D scalar volume: three dimensions, or more whose sizes beyond the third are 1.
void check_scalar_volume(const std::string& path, const std::vector<int64_t>& dims, long components) {
    bool three_d = dims.size() >= 3;
    for (size_t d = 3; d < dims.size(); ++d)
        if (dims[d] != 1) three_d = false;
    if (!three_d) {
        std::string size;
        for (size_t d = 0; d < dims.size(); ++d) size += (d ? " x " : "") + std::to_string(dims[d]);
        throw InvalidParameter(path + ": image has " + std::to_string(dims.size()) + " dimensions (" + size +
                               "), expected a 3-D volume");
    }
    if (components != 1)
        throw InvalidParameter(path + ": image has " + std::to_string(components) +
                               " components per voxel, expected a scalar image (1 component)");
}

/// Where a MetaImage's voxels are: the files, each with an equal part of them, in order. LOCAL: the
/// header's own file; "LIST [D]": the names on the lines after the header; a slice pattern; else
/// one data file beside the header (NAME, else NAME.gz or NAME.Z, compressed, as MetaIO looks for
/// them). IoError for a LOCAL or LIST header that ends with the file, a short LIST, a missing file.
struct MetaImageFiles {
    std::vector<std::string> files;
    bool local = false;               ///< LOCAL: the data follow the header in its own file
    bool compressed_by_name = false;  ///< found as NAME.gz or NAME.Z
};
MetaImageFiles metaimage_files(const std::string& path, const MetaImageHeader& mh) {
    const Geometry& g = mh.geometry;
    const std::string& name = mh.data_file;
    // No data file (fuzz_mhd: "ElementDataFile" without '=' at the end of the file): MetaIO opens
    // the header's directory as one and reads nothing into the voxels.
    if (name.empty())
        throw IoError(path + ": MetaImage header has no ElementDataFile value, expected LOCAL (the data "
                             "follow the header) or the name of the data file");
    MetaImageFiles mf;
    mf.local = name == "LOCAL" || name == "Local" || name == "local";
    const bool list = name.rfind("LIST", 0) == 0;
    if ((mf.local || list) && mh.header_end < 0)
        throw IoError(path + ": MetaImage header does not end before the end of the file, expected " +
                      (mf.local ? "the voxel data after 'ElementDataFile = LOCAL'" : "the file names after 'ElementDataFile = LIST'"));
    const auto beside = [&](const std::string& f) {
        fs::path p(f);
        return p.is_relative() ? (fs::path(path).parent_path() / p).string() : p.string();
    };
    std::vector<std::string>& files = mf.files;
    if (mf.local) {
        files = {path};
    } else if (list) {
        // "LIST [D]": D-dimensional parts (default and otherwise 2: slices), one name per line.
        std::istringstream words(name);
        std::string w0, w1;
        words >> w0 >> w1;
        const long d = w1.empty() ? 2 : std::strtol(w1.c_str(), nullptr, 10);
        const int part_dims = d >= 1 && d <= 3 ? int(d) : 2;
        int64_t parts = 1;
        for (int a = part_dims; a < 3; ++a) parts *= g.dims[size_t(a)];
        std::ifstream names(path, std::ios::binary);
        names.seekg(mh.header_end);
        std::string line;
        for (int64_t k = 0; k < parts; ++k) {
            if (!std::getline(names, line) || line.size() > 1023)
                throw IoError(path + ": MetaImage ElementDataFile = LIST names " + std::to_string(k) +
                              " files (one per line after it), expected " + std::to_string(parts));
            while (!line.empty() && (std::isspace(static_cast<unsigned char>(line.back())) ||
                                     !std::isprint(static_cast<unsigned char>(line.back()))))
                line.pop_back();
            files.push_back(beside(line));
        }
    } else if (name.find('%') != std::string::npos) {
        files = metaimage_pattern_files(path, name, g.dims[2]);
    } else {
        const std::string p = beside(name);
        for (const char* ext : {"", ".gz", ".Z"}) {
            std::error_code ec;
            if (!fs::exists(p + ext, ec)) continue;
            files = {p + ext};
            mf.compressed_by_name = *ext != '\0';
            break;
        }
        if (files.empty())
            throw IoError(path + ": MetaImage data file " + p + " (ElementDataFile = " + name +
                          ") does not exist, nor with .gz or .Z");
    }
    return mf;
}

/// The byte of a MetaImage data file (of `file_bytes` bytes, holding a part of `part_bytes` stored
/// bytes) where its part starts, as MetaIO finds it: after the header for LOCAL data, else at 0;
/// HeaderSize bytes in when it is > 0; with HeaderSize = -1 the part is the file's last bytes (the
/// caller checks first that the file holds that many).
uint64_t metaimage_data_start(const MetaImageHeader& mh, bool local, uint64_t file_bytes, uint64_t part_bytes) {
    if (mh.header_size == -1) return file_bytes - part_bytes;
    if (mh.header_size > 0) return uint64_t(mh.header_size);
    return local ? uint64_t(mh.header_end) : 0;
}

/// The voxels of a MetaImage whose header read_metaimage_header has read, here instead of by ITK.
/// ITK 5.2's MetaIO notices a short read, prints "data not read completely", "Uncompress failed" or
/// "cannot construct file" and returns success, leaving the voxels it did not read uninitialised: a
/// truncated .mha, a compressed stream that ends early or inflates to more, a CompressedDataSize
/// smaller than the stream, a missing slice file were read as garbage (fuzz_mhd under valgrind).
/// Here they are an IoError. The data are LOCAL, one data file (NAME, else NAME.gz or NAME.Z as
/// compressed, as MetaIO looks for them), a slice pattern or a LIST of files, each holding an equal
/// part of the voxels; binary (raw, zlib or gzip) or ASCII; HeaderSize bytes skipped in each file
/// (-1: the part is the file's last bytes).
Volume<float> read_metaimage_direct(const std::string& path, const MetaImageHeader& mh) {
    const Geometry& g = mh.geometry;
    // 64-bit integers (mh.type unset) are read as 8-byte units and converted by `convert` below.
    const bool wide = !mh.type;
    const RawType type = wide ? RawType::Float64 : *mh.type;
    const auto convert = [&](const unsigned char* src, size_t n, bool swap, float* dst) {
        if (!wide) return convert_in_parallel(type, src, n, swap, dst);
        // The stored byte order is mh.msb's, whatever the host's.
        const bool is_signed = mh.voxel_type == "int64";
        for (size_t i = 0; i < n; ++i) {
            uint64_t u = 0;
            for (int b = 0; b < 8; ++b) u |= uint64_t(src[8 * i + size_t(mh.msb ? 7 - b : b)]) << (8 * b);
            dst[i] = is_signed ? float(int64_t(u)) : float(u);
        }
    };
    const MetaImageFiles mf = metaimage_files(path, mh);
    const std::vector<std::string>& files = mf.files;
    const bool local = mf.local;
    const int64_t header_size = mh.header_size;
    const bool binary = mh.binary || mf.compressed_by_name;
    const bool compressed = mh.compressed || mf.compressed_by_name;
    if (header_size == -1 && (compressed || !binary))
        throw IoError(path + ": MetaImage HeaderSize = -1 (the voxels are the data file's last bytes) with " +
                      std::string(binary ? "CompressedData = True" : "BinaryData = False") +
                      ", expected it only with uncompressed binary data");
    const size_t bytes_per = raw_type_size(type);
    const size_t voxels = g.voxel_count();
    const size_t part_voxels = voxels / files.size();
    const size_t part_bytes = part_voxels * bytes_per;
    Volume<float> v;
    v.geometry() = g;
    v.buffer().resize(voxels);
    const bool swap = mh.msb == host_is_little_endian();
    // Binary parts are gathered here and converted at the end; one uncompressed file is converted
    // straight from its bytes (no second copy of the stored voxels).
    const bool direct_from_file = binary && !compressed && files.size() == 1;
    std::string stored(binary && !direct_from_file ? voxels * bytes_per : 0, '\0');
    struct Free {
        void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
    };
    std::unique_ptr<libdeflate_decompressor, Free> dec;
    for (size_t k = 0; k < files.size(); ++k) {
        const std::string& data_path = files[k];
        std::error_code ec;
        if (!fs::is_regular_file(data_path, ec))
            throw IoError(path + ": MetaImage data file " + data_path + (fs::exists(data_path, ec) ? " is not a regular file" : " does not exist") +
                          ", expected the file of " + (files.size() > 1 ? "slice " + std::to_string(k + 1) + " of the voxels" : std::string("the voxels")));
        std::optional<std::string> file = slurp(data_path);
        if (!file) throw IoError(path + ": cannot read the MetaImage data file " + data_path);
        const auto truncated = [&](uint64_t have, uint64_t from, const std::string& what) {
            std::ostringstream m;
            m << data_path << ": holds " << have << " bytes of " << what << " from byte " << from << " on, expected "
              << (compressed ? "the " + std::to_string(mh.compressed_size) + " bytes of CompressedDataSize"
                             : std::to_string(part_bytes) + " (" + std::to_string(part_voxels) + " voxels of " +
                                   std::to_string(bytes_per) + " bytes)")
              << " as the header " << path << " declares: file truncated or header corrupt";
            throw IoError(m.str());
        };
        if (header_size == -1 && file->size() < part_bytes) truncated(file->size(), 0, "voxel data");
        const uint64_t start = metaimage_data_start(mh, local, file->size(), part_bytes);
        if (start > file->size()) truncated(0, start, compressed ? "compressed data" : "voxel data");
        std::string_view data = std::string_view(*file).substr(size_t(start));
        if (!binary) {
            parse_metaimage_ascii(data, type, part_voxels, v.data() + k * part_voxels, path, data_path, start, wide);
            continue;
        }
        if (!compressed) {
            if (data.size() < part_bytes) truncated(data.size(), start, "voxel data");
            if (direct_from_file)
                convert(reinterpret_cast<const unsigned char*>(data.data()), voxels, swap, v.data());
            else
                std::memcpy(stored.data() + k * part_bytes, data.data(), part_bytes);
            continue;
        }
        unsigned char* out = reinterpret_cast<unsigned char*>(stored.data()) + k * part_bytes;
        // MetaIO reads CompressedDataSize bytes (all that follow when it is 0) and inflates them
        // (zlib or gzip, one stream) into exactly the voxels' bytes.
        const int64_t declared = mh.compressed_size;
        if (declared < 0)
            throw IoError(path + ": MetaImage CompressedDataSize = " + std::to_string(declared) +
                          ", expected the number of bytes of the compressed data");
        if (declared > 0) {
            if (uint64_t(declared) > data.size()) truncated(data.size(), start, "compressed data");
            data = data.substr(0, size_t(declared));
        }
        if (!dec) dec.reset(libdeflate_alloc_decompressor());
        if (!dec) throw OutOfMemory(path + ": out of memory while reading");
        const bool gzip = data.size() >= 2 && uint8_t(data[0]) == 0x1f && uint8_t(data[1]) == 0x8b;
        size_t in_used = 0, out_made = 0;
        const libdeflate_result res =
            gzip ? libdeflate_gzip_decompress_ex(dec.get(), data.data(), data.size(), out, part_bytes, &in_used, &out_made)
                 : libdeflate_zlib_decompress_ex(dec.get(), data.data(), data.size(), out, part_bytes, &in_used, &out_made);
        if (res != LIBDEFLATE_SUCCESS || out_made != part_bytes) {
            std::ostringstream m;
            m << data_path << ": the compressed voxel data from byte " << start << " (" << data.size() << " bytes) "
              << (res == LIBDEFLATE_SUCCESS ? "inflate to " + std::to_string(out_made) + " bytes"
                  : res == LIBDEFLATE_INSUFFICIENT_SPACE ? std::string("inflate to more bytes")
                                                         : std::string("do not inflate (corrupt or cut short)"))
              << ", expected " << part_bytes << " (" << part_voxels << " voxels of " << bytes_per
              << " bytes) as the header " << path << " declares: file truncated or header corrupt";
            throw IoError(m.str());
        }
    }
    if (binary && !direct_from_file) {
        convert(reinterpret_cast<const unsigned char*>(stored.data()), voxels, swap, v.data());
    }
    return v;
}

/// An image file's header as ITK reads it, checked: a 3-D scalar volume of a known type and a
/// sane size (IoError / InvalidParameter otherwise).
struct ImageHeader {
    FileFormat fmt = FileFormat::Unknown;
    itk::ImageIOBase::Pointer io;
    VolumeHeader header;
};

ImageHeader read_image_header(const std::string& path) {
    const FileFormat fmt = format_of(path);
    if (fmt == FileFormat::Unknown)
        throw IoError(path + ": unknown file type, expected " + kKnownExtensions +
                      ", a DICOM directory, or raw options");
    if (fmt == FileFormat::Nifti) check_nifti_geometry(path);
    if (fmt == FileFormat::MetaImage) check_metaimage_header(path);
    itk::ImageIOBase::Pointer io = make_image_io(fmt);
    try {
        io->SetFileName(path);
        io->ReadImageInformation();
    } catch (const itk::ExceptionObject& e) {
        throw IoError(path + ": cannot read header: " + describe(e));
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(path + ": out of memory while reading the header");
    } catch (const std::exception& e) {  // ITK lets some std exceptions through
        throw IoError(path + ": cannot read header: " + e.what());
    }
    std::vector<int64_t> dims;
    for (unsigned d = 0; d < io->GetNumberOfDimensions(); ++d) dims.push_back(int64_t(io->GetDimensions(d)));
    check_scalar_volume(path, dims, long(io->GetNumberOfComponents()));

    if (component_name(io->GetComponentType()) == "unknown")
        throw IoError(path + ": voxel type " +
                      itk::ImageIOBase::GetComponentTypeAsString(io->GetComponentType()) +
                      " is not supported, expected an integer or floating-point scalar type");
    VolumeHeader header;
    header.stored_voxel_bytes = io->GetComponentSize();
    for (unsigned a = 0; a < 3; ++a) {
        header.geometry.dims[a] = static_cast<int64_t>(io->GetDimensions(a));
        header.geometry.spacing[a] = io->GetSpacing(a);
        header.geometry.origin[a] = io->GetOrigin(a);
        for (unsigned c = 0; c < 3; ++c)
            header.geometry.direction[3 * c + a] = io->GetDirection(a)[c];
    }
    check_declared_size(header.geometry.dims, path);
    if (fmt == FileFormat::Nifti && ends_with(lower(path), ".nii"))
        check_nifti_length(path, io->GetImageSizeInBytes());
    return {fmt, io, header};
}

/// A MetaImage read here, header (read_metaimage_header, after check_metaimage_header's checks)
/// and voxels (read_metaimage_direct): ITK's MetaIO never parses it.
ReadResult read_metaimage(const std::string& path, const HeaderCheck& check_header) {
    check_metaimage_header(path);
    const MetaImageHeader mh = read_metaimage_header(path);
    check_scalar_volume(path, mh.dims, mh.channels);
    VolumeHeader header;
    header.stored_voxel_bytes = mh.voxel_bytes;
    header.geometry = mh.geometry;
    check_declared_size(header.geometry.dims, path);
    if (!(std::abs(header.geometry.direction_determinant()) > 1e-6))
        throw IoError(path + ": MetaImage TransformMatrix " + meshpost::text::point({header.geometry.direction[0],
                      header.geometry.direction[4], header.geometry.direction[8]}) + "... is singular (determinant " +
                      std::to_string(header.geometry.direction_determinant()) +
                      "), expected the directions of three independent axes");
    if (check_header) check_header(header);
    ReadResult r;
    r.info.paths = {path};
    r.info.format = format_name(FileFormat::MetaImage);
    r.info.voxel_type = mh.voxel_type;
    r.info.files_read = 1;
    try {
        r.volume = read_metaimage_direct(path, mh);
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(path + ": out of memory while reading");
    }
    check_read_volume(r.volume, path, r.info.voxel_type.rfind("float", 0) != 0);
    r.info.read_directly = true;
    return r;
}

ReadResult read_image_file(const std::string& path, const HeaderCheck& check_header, bool fast_nrrd,
                           bool fast_metaimage, bool int16) {
    if (fast_metaimage && format_of(path) == FileFormat::MetaImage)
        return read_metaimage(path, check_header);
    const ImageHeader ih = read_image_header(path);
    const FileFormat fmt = ih.fmt;
    const itk::ImageIOBase::Pointer& io = ih.io;
    const VolumeHeader& header = ih.header;
    if (check_header) check_header(header);

    ReadResult r;
    r.info.paths = {path};
    r.info.format = format_name(fmt);
    r.info.voxel_type = component_name(io->GetComponentType());
    r.info.files_read = 1;
    // Our own readers of the voxels (same voxels and geometry as ITK's); nullopt: ITK reads them.
    const auto read_directly = [&](auto&& read) {
        std::optional<Volume<float>> v;
        try {
            v = read();
        } catch (const std::bad_alloc&) {
            throw OutOfMemory(path + ": out of memory while reading");
        }
        if (!v) return false;
        check_read_volume(*v, path, r.info.voxel_type.rfind("float", 0) != 0);
        r.volume = std::move(*v);
        r.info.read_directly = true;
        return true;
    };
    const bool regular = std::abs(header.geometry.direction_determinant()) > 1e-6;
    if (fmt == FileFormat::Nrrd && fast_nrrd && regular && int16) {
        try {
            if (std::optional<Volume<int16_t>> v = read_nrrd_int16(path, *io, header.geometry)) {
                r.volume16 = std::move(*v);
                r.volume.geometry() = header.geometry;  // the geometry readable, the samples in volume16
                r.info.read_directly = true;
                return r;
            }
        } catch (const std::bad_alloc&) {
            throw OutOfMemory(path + ": out of memory while reading");
        }
    }
    if (fmt == FileFormat::Nrrd && fast_nrrd && regular &&
        read_directly([&] { return read_nrrd_fast(path, *io, header.geometry); }))
        return r;
    try {
        auto reader = itk::ImageFileReader<FloatImage>::New();
        reader->SetImageIO(io);
        reader->SetFileName(path);
        reader->Update();
        r.volume = to_volume(reader->GetOutput(), path);
    } catch (const Error&) {
        throw;  // from to_volume
    } catch (const itk::ExceptionObject& e) {
        throw IoError(path + ": " + describe(e));
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(path + ": out of memory while reading");
    } catch (const std::exception& e) {
        // ITK 5.2's MetaImage reader lets std::length_error out of a corrupt header
        // (fuzz_mhd: "ElementDataFile =%%% LOCAL").
        throw IoError(path + ": reading failed inside ITK: " + e.what());
    }
    return r;
}

/// The slices as the scanner placed them (slice_stack.h): throws IoError for a duplicated slice or
/// a real gap; a tilted or unevenly spaced stack (or any, when slice_spacing_mm > 0) is resampled
/// onto a regular grid in patient space, with what was done in r.info and a warning.
void regularize_slices(ReadResult& r, const std::vector<Vec3>& ipp, const std::vector<std::string>& files,
                       const std::string& dir, double slice_spacing_mm, bool resample, const HeaderCheck& check_header) {
    const bool dicom = !files.empty();
    if (ipp.size() < 2 || (dicom && ipp.size() != files.size()) || int64_t(ipp.size()) != r.volume.nz()) return;
    const Geometry& g = r.volume.geometry();
    const auto& d = g.direction;
    const Vec3 row{d[0], d[3], d[6]}, col{d[1], d[4], d[7]};
    const SliceStack st = analyze_slice_stack(ipp, row, col, std::min(g.spacing[0], g.spacing[1]), dir, files);
    if (!resample || (!st.needs_resampling() && !(slice_spacing_mm > 0))) return;
    if (!r.volume16.empty()) {  // resampled as float
        r.volume = to_float(r.volume16);
        r.volume16 = Volume<int16_t>();
    }
    SliceResampling rp;
    rp.slice_spacing_mm = slice_spacing_mm;
    float lowest = std::numeric_limits<float>::infinity();
    const float* v = r.volume.data();
#pragma omp parallel for schedule(static) reduction(min : lowest)
    for (int64_t i = 0; i < int64_t(r.volume.size()); ++i) lowest = std::min(lowest, v[i]);
    rp.outside = lowest;
    Geometry grid;
    try {
        grid = resampled_geometry(g, ipp, st, rp);
    } catch (const IoError& e) {
        throw IoError(dir + ": " + e.what());
    }
    check_declared_size(grid.dims, dir);
    if (check_header) {
        VolumeHeader h;
        h.geometry = grid;
        h.stored_voxel_bytes = 4;
        check_header(h);
    }
    std::ostringstream why;
    if (st.tilted) why << (dicom ? "gantry tilt " : "sheared grid (a gantry tilt kept as a shear): ")
                       << std::round(st.tilt_deg * 100) / 100 << " deg (slices sheared by up to "
                       << std::round(st.shear_mm * 10) / 10 << " mm)";
    if (!st.regular) why << (st.tilted ? "; " : "") << "uneven slice spacing (" << st.runs.size() << " runs of even spacing)";
    if (st.regular && !st.tilted) why << "--slice-spacing " << slice_spacing_mm << " mm";
    r.volume = resample_slice_stack(r.volume, ipp, st, rp);
    r.info.gantry_tilt_deg = st.tilt_deg;
    r.info.resampled = true;
    r.info.resample_reason = why.str();
    r.info.slice_runs = st.changes;
    const Geometry& o = r.volume.geometry();
    std::ostringstream w;
    w << dir << ": " << why.str() << ": resampled onto a regular grid in patient coordinates, " << o.dims[0] << " x "
      << o.dims[1] << " x " << o.dims[2] << " voxels of " << o.spacing[0] << " x " << o.spacing[1] << " x "
      << o.spacing[2] << " mm (slice axis along the slices' normal; --mask and --qc are in this grid)";
    for (size_t i = 0; i < st.changes.size(); ++i) w << (i ? "; " : ": ") << st.changes[i];
    r.info.warnings.push_back(w.str());
}

/// Cosines of the angles between the grid's x and y, x and z, y and z axes (0 when perpendicular).
std::array<double, 3> axis_cosines(const Geometry& g) {
    const auto& d = g.direction;
    const Vec3 a{d[0], d[3], d[6]}, b{d[1], d[4], d[7]}, c{d[2], d[5], d[8]};
    return {dot(a, b), dot(a, c), dot(b, c)};
}

/// A volume file whose grid is sheared (its slice axis not perpendicular to its slices, e.g. a
/// tilted CT converted with the tilt kept in the direction matrix): resampled like a tilted DICOM
/// series (the same grid), since the method's distances need an orthonormal grid. A shear within
/// the slices (x and y axes not perpendicular) is refused.
void regularize_grid(ReadResult& r, const std::string& path, double slice_spacing_mm, bool resample,
                     const HeaderCheck& check_header) {
    const Geometry& g = r.volume.geometry();
    const auto [ab, ac, bc] = axis_cosines(g);
    if (std::fabs(ab) <= 1e-6 && std::fabs(ac) <= 1e-6 && std::fabs(bc) <= 1e-6) return;
    if (std::fabs(ab) > 1e-6) {
        std::ostringstream m;
        m << path << ": the grid's x and y axes are " << std::acos(std::clamp(ab, -1.0, 1.0)) * 180 / M_PI
          << " deg apart, expected perpendicular axes (a shear within the slices is not supported)";
        throw InvalidParameter(m.str());
    }
    if (!resample) return;
    if (!r.volume16.empty()) {  // resampled as float
        r.volume = to_float(r.volume16);
        r.volume16 = Volume<int16_t>();
    }
    std::vector<Vec3> pos;
    for (int64_t k = 0; k < g.dims[2]; ++k) pos.push_back(g.index_to_world(0, 0, double(k)));
    regularize_slices(r, pos, {}, path, slice_spacing_mm, true, check_header);
}

/// Throws IoError naming the first slice whose size differs from the first slice's (read only on
/// the error path: one header per file).
void check_slice_sizes(const std::vector<std::string>& files, const std::string& dir) {
    std::string first_size;
    for (const auto& f : files) {
        std::string size;
        try {
            auto io = gdcm_api().new_image_io();
            io->SetFileName(f);
            io->ReadImageInformation();
            size = std::to_string(io->GetDimensions(0)) + " x " + std::to_string(io->GetDimensions(1));
        } catch (const itk::ExceptionObject& e) {
            throw IoError(f + ": cannot read DICOM header: " + describe(e));
        }
        if (first_size.empty()) first_size = size;
        if (size != first_size)
            throw IoError(dir + ": DICOM slice " + fs::path(f).filename().string() + " is " + size +
                          " pixels, expected " + first_size + " like " +
                          fs::path(files.front()).filename().string() +
                          ": a series must hold slices of one size");
    }
}

ReadResult read_dicom_dir(const std::string& dir, const DicomSeriesChoice& choice,
                          const HeaderCheck& check_header, bool direct, double slice_spacing_mm,
                          bool resample, bool int16) {
    // Every series under the folder (recursively), then the one asked for or the default
    // (dicom_series.h); its files in slice order, as ITK's GDCMSeriesFileNames sorted them.
    DicomStudy study = list_dicom_series(dir);
    const DicomSeriesPick pick = choose_dicom_series(study, choice);
    const std::string uid = study.series[pick.index].series_uid;
    const std::vector<std::string> files = study.series[pick.index].files;
    if (files.empty()) throw IoError(dir + ": DICOM series " + uid + " has no files");

    if (check_header) {
        VolumeHeader header;
        try {
            auto first = gdcm_api().new_image_io();
            first->SetFileName(files.front());
            first->ReadImageInformation();
            header.stored_voxel_bytes = first->GetComponentSize();
            header.geometry.dims = {static_cast<int64_t>(first->GetDimensions(0)),
                                    static_cast<int64_t>(first->GetDimensions(1)),
                                    static_cast<int64_t>(files.size())};
            for (unsigned a = 0; a < 3; ++a) header.geometry.spacing[a] = first->GetSpacing(a);
        } catch (const itk::ExceptionObject& e) {
            throw IoError(files.front() + ": cannot read DICOM header: " + describe(e));
        }
        check_declared_size(header.geometry.dims, dir);
        check_header(header);
    }

    ReadResult r;
    r.info.paths = {dir};
    r.info.format = "dicom";
    r.info.series_uid = uid;
    r.info.files_read = files.size();
    r.info.series_found = std::move(study.series);
    if (!pick.warning.empty()) r.info.warnings.push_back(pick.warning);
    std::vector<Vec3> dicom_positions;
    const std::string series = dir + " (DICOM series " + uid + ")";
    try {
        auto dicom = gdcm_api().new_image_io();
        auto reader = itk::ImageSeriesReader<FloatImage>::New();
        reader->SetImageIO(dicom);
        reader->SetFileNames(files);
        // ITK's own multi-line warning about non-uniform sampling is silenced; regularize_slices
        // handles it.
        reader->SetSpacingWarningRelThreshold(1e30);
        if (direct) {
            // The geometry from ITK (the first and last slices' headers), the pixels read here
            // in parallel when the slices are the common case (read_dicom_pixels).
            reader->UpdateOutputInformation();
            const FloatImage* info = reader->GetOutput();
            Volume<float> v;
            v.geometry() = geometry_of(info);
            const Dims& d = v.geometry().dims;
            if (d[2] == int64_t(files.size()) && d[0] > 0 && d[1] > 0) {
                check_declared_size(d, dir);
                // ReadOptions::int16: straight into int16 when every value fits (no float copy);
                // a value beyond int16 reads the series again as float; not the direct reader's
                // case: ITK reads it.
                bool as_float = true;
                if (int16) {
                    check_read_volume(v, series, true);  // the geometry (no samples yet)
                    Volume<int16_t> v16(v.geometry());
                    bool fits = false;
                    auto positions = read_dicom_pixels(files, d[0], d[1], v16.data(), fits);
                    as_float = positions && !fits;
                    if (positions && fits) {
                        dicom_positions = std::move(*positions);
                        r.info.read_directly = true;
                        r.volume16 = std::move(v16);
                        r.volume = std::move(v);  // the geometry readable, the samples in volume16
                    }
                }
                if (as_float) {
                    v.buffer().resize(v.geometry().voxel_count());
                    if (auto positions = read_dicom_pixels(files, d[0], d[1], v.data())) {
                        dicom_positions = std::move(*positions);
                        r.info.read_directly = true;
                        check_read_volume(v, series, true);
                        r.volume = std::move(v);
                    }
                }
            }
        }
        if (!r.info.read_directly) {
            // Per-slice dictionaries: their ImagePositionPatient finds missing slices below.
            reader->SetMetaDataDictionaryArrayUpdate(true);
            reader->Update();
            for (const auto* d : *reader->GetMetaDataDictionaryArray()) {
                std::string v;
                if (!d || !itk::ExposeMetaData<std::string>(*d, "0020|0032", v)) break;
                const std::optional<Vec3> p = parse_image_position(v);
                if (!p) break;
                dicom_positions.push_back(*p);
            }
            // GDCMImageIO applies RescaleSlope/RescaleIntercept when reading: values are HU.
            r.volume = to_volume(reader->GetOutput(), series);
        }
        // The stored type, from the headers ITK read (either way).
        r.info.voxel_type = component_name(gdcm_api().internal_component_type(*dicom));
    } catch (const Error&) {
        throw;  // from check_read_volume / to_volume
    } catch (const itk::ExceptionObject& e) {
        check_slice_sizes(files, dir);  // names the odd slice when that is the cause
        throw IoError(dir + ": reading DICOM series " + uid + ": " + describe(e));
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(dir + ": out of memory while reading DICOM series " + uid);
    }
    regularize_slices(r, dicom_positions, files, dir, slice_spacing_mm, resample, check_header);
    return r;
}

/// Writes through a hidden temporary directory beside `path`, then renames into place.
template <class T>
void write_itk(const Volume<T>& v, const std::string& path) {
    const FileFormat fmt = format_of(path);
    if (fmt == FileFormat::Unknown)
        throw IoError(path + ": unknown file type for writing, expected " +
                      std::string(kKnownExtensions));
    if (v.empty()) throw IoError(path + ": volume is empty, nothing to write");

    const fs::path target(path);
    const fs::path filename = target.filename();
    fs::path parent = target.parent_path();
    if (parent.empty()) parent = ".";
    std::error_code ec;
    if (!fs::is_directory(parent, ec))
        throw IoError(path + ": directory " + parent.string() + " does not exist");

    static std::atomic<unsigned> counter{0};
    const fs::path tmpdir =
        parent / ("." + filename.string() + ".tmp" + std::to_string(::getpid()) + "_" +
                  std::to_string(counter++));
    if (!fs::create_directory(tmpdir, ec) || ec)
        throw IoError(path + ": cannot create temporary directory " + tmpdir.string() + ": " +
                      ec.message());
    auto cleanup = [&]() {
        std::error_code ignored;
        fs::remove_all(tmpdir, ignored);
    };

    try {
        using Image = itk::Image<T, 3>;
        const Geometry& g = v.geometry();
        auto img = Image::New();
        typename Image::RegionType region;
        typename Image::SizeType size;
        typename Image::SpacingType spacing;
        typename Image::PointType origin;
        typename Image::DirectionType direction;
        for (unsigned a = 0; a < 3; ++a) {
            size[a] = static_cast<itk::SizeValueType>(g.dims[a]);
            spacing[a] = g.spacing[a];
            origin[a] = g.origin[a];
            for (unsigned c = 0; c < 3; ++c) direction(a, c) = g.direction[3 * a + c];
        }
        region.SetSize(size);
        img->SetRegions(region);
        img->SetSpacing(spacing);
        img->SetOrigin(origin);
        img->SetDirection(direction);
        // The writer only reads the buffer: borrow the volume's memory instead of copying it.
        img->GetPixelContainer()->SetImportPointer(const_cast<T*>(v.data()), v.size(), false);

        const std::string lname = lower(filename.string());
        auto writer = itk::ImageFileWriter<Image>::New();
        writer->SetImageIO(make_image_io(fmt));
        writer->SetFileName((tmpdir / filename).string());
        writer->SetInput(img);
        writer->SetUseCompression(ends_with(lname, ".nrrd") || ends_with(lname, ".nhdr") ||
                                  ends_with(lname, ".nii.gz") || ends_with(lname, ".mha"));
        writer->Update();
    } catch (const itk::ExceptionObject& e) {
        cleanup();
        throw IoError(path + ": cannot write: " + describe(e));
    } catch (const std::exception& e) {
        cleanup();
        throw IoError(path + ": cannot write: " + e.what());
    }

    // Data files (detached formats) first, the named file last.
    std::vector<fs::path> written;
    for (const auto& entry : fs::directory_iterator(tmpdir, ec))
        if (entry.path().filename() != filename) written.push_back(entry.path());
    std::sort(written.begin(), written.end());
    written.push_back(tmpdir / filename);
    for (const auto& f : written) {
        fs::rename(f, parent / f.filename(), ec);
        if (ec) {
            const std::string msg = ec.message();
            cleanup();
            throw IoError(path + ": cannot rename " + f.string() + " to " +
                          (parent / f.filename()).string() + ": " + msg);
        }
    }
    cleanup();
}

}  // namespace

ReadResult read_volume(const std::vector<std::string>& inputs, const ReadOptions& opt) {
    return read_volume(inputs, opt, DirectReaders{});
}

ReadResult read_volume(const std::vector<std::string>& inputs, const ReadOptions& opt, const DirectReaders& direct) {
    if (opt.raw) return read_raw(inputs, *opt.raw, opt.check_header);
    if (inputs.empty()) throw InvalidParameter("no input given, expected a file or a directory");
    if (is_tiff_input(inputs)) return read_tiff(inputs, {opt.spacing, opt.origin}, opt.check_header);
    if (opt.spacing || opt.origin)
        throw InvalidParameter(inputs[0] + ": a spacing or origin was given, but this input carries its own "
                               "geometry (they apply to TIFF and raw input only)");
    if (inputs.size() > 1)
        throw InvalidParameter(std::to_string(inputs.size()) + " inputs given (" + inputs[0] +
                               ", ...), expected one file or DICOM directory; several files "
                               "are read only as raw or TIFF slices");
    const std::string& path = inputs[0];
    // ITK prints warnings (e.g. "No Series were found") as several lines on stderr; every problem
    // is reported by our exceptions instead, on one line.
    itk::Object::GlobalWarningDisplayOff();
    std::error_code ec;
    const auto st = fs::status(path, ec);
    if (!fs::exists(st)) throw IoError(path + ": no such file or directory");
    if (fs::is_directory(st) || is_dicomdir_path(path))
        return read_dicom_dir(path, {opt.series_uid, opt.series_description}, opt.check_header, direct.dicom,
                              opt.slice_spacing_mm, opt.resample_slices, opt.int16);
    ReadResult r = read_image_file(path, opt.check_header, direct.nrrd, direct.metaimage, opt.int16);
    regularize_grid(r, path, opt.slice_spacing_mm, opt.resample_slices, opt.check_header);
    return r;
}

std::unique_ptr<SliceSource> open_metaimage_slices(const std::string& path) {
    if (format_of(path) != FileFormat::MetaImage) return nullptr;
    check_metaimage_header(path);
    const MetaImageHeader mh = read_metaimage_header(path);
    check_scalar_volume(path, mh.dims, mh.channels);
    // Uncompressed binary 8- to 32-bit or float voxels on a grid with perpendicular axes and a sane
    // geometry, in one file (LOCAL or a data file) or one file per slice (a pattern); anything else
    // is read whole (read_volume then says what is wrong with it).
    const Geometry& g = mh.geometry;
    bool plain = mh.type && mh.binary && !mh.compressed && mh.data_file.rfind("LIST", 0) != 0;
    for (int a = 0; a < 3; ++a)
        plain = plain && g.dims[a] > 0 && std::isfinite(g.spacing[a]) && g.spacing[a] > 0 && std::isfinite(g.origin[a]);
    for (double d : g.direction) plain = plain && std::isfinite(d);
    if (!plain || !(std::abs(g.direction_determinant()) > 1e-6)) return nullptr;
    const auto [ab, ac, bc] = axis_cosines(g);
    if (std::fabs(ab) > 1e-6 || std::fabs(ac) > 1e-6 || std::fabs(bc) > 1e-6) return nullptr;
    check_declared_size(g.dims, path);
    const MetaImageFiles mf = metaimage_files(path, mh);
    if (mf.compressed_by_name) return nullptr;
    const uint64_t part_slices = uint64_t(g.dims[2]) / mf.files.size();
    const uint64_t part_bytes = uint64_t(g.dims[0]) * uint64_t(g.dims[1]) * part_slices * mh.voxel_bytes;
    std::vector<RawPart> parts;
    for (const std::string& f : mf.files) {
        std::error_code ec;
        const uint64_t size = fs::is_regular_file(f, ec) ? fs::file_size(f, ec) : 0;
        if (ec || size < part_bytes) return nullptr;  // missing or short: read_volume says which
        const uint64_t offset = metaimage_data_start(mh, mf.local, size, part_bytes);
        if (size < offset + part_bytes) return nullptr;
        parts.push_back({f, offset, int64_t(part_slices)});
    }
    InputInfo info;
    info.paths = {path};
    info.format = format_name(FileFormat::MetaImage);
    info.voxel_type = mh.voxel_type;
    info.files_read = mf.files.size();
    info.read_directly = true;
    return open_raw_parts(std::move(parts), *mh.type, mh.msb == host_is_little_endian(), {g, mh.voxel_bytes}, info);
}

std::unique_ptr<SliceSource> open_nrrd_slices(const std::string& path) {
    if (format_of(path) != FileFormat::Nrrd) return nullptr;
    itk::Object::GlobalWarningDisplayOff();
    const ImageHeader ih = read_image_header(path);
    const Geometry& g = ih.header.geometry;
    if (!(std::abs(g.direction_determinant()) > 1e-6)) return nullptr;
    const auto [ab, ac, bc] = axis_cosines(g);  // perpendicular axes, as regularize_grid leaves them
    if (std::fabs(ab) > 1e-6 || std::fabs(ac) > 1e-6 || std::fabs(bc) > 1e-6) return nullptr;
    const std::optional<RawType> type = raw_type_of(ih.io->GetComponentType(), ih.io->GetComponentSize());
    if (!type) return nullptr;
    std::string head(size_t(1) << 20, '\0');
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) return nullptr;
        in.read(head.data(), std::streamsize(head.size()));
        head.resize(size_t(in.gcount()));
    }
    const std::optional<NrrdData> where = parse_nrrd_data(head, path, raw_type_size(*type));
    if (!where) return nullptr;
    RawPart part{where->data_file.empty() ? path : where->data_file,
                 where->data_file.empty() ? uint64_t(where->data_offset) : 0, g.dims[2]};
    std::error_code ec;
    const uint64_t size = fs::file_size(part.path, ec);
    if (ec) return nullptr;  // ITK says why
    InputInfo info;
    info.paths = {path};
    info.format = format_name(FileFormat::Nrrd);
    info.voxel_type = component_name(ih.io->GetComponentType());
    info.files_read = 1;
    info.read_directly = true;
    if (where->gzip) return open_gzip_part(part.path, part.offset, *type, where->swap, ih.header, info);
    if (size != part.offset + g.voxel_count() * raw_type_size(*type)) return nullptr;  // ITK says why
    return open_raw_parts({part}, *type, where->swap, ih.header, info);
}

// An attached NRRD is written here (gzip in indexed members, compressed on all threads, inflated
// on all threads by read_volume; ITK and any gzip reader read it too), TIFF by tiff_io.cpp, the
// rest by ITK.
template <class T>
void write_any(const Volume<T>& v, const std::string& path) {
    if (is_tiff_path(path)) write_tiff(v, path);
    else if (lower(fs::path(path).extension().string()) == ".nrrd") write_nrrd_gzip(v, path);
    else write_itk(v, path);
}

void write_volume(const Volume<uint8_t>& v, const std::string& path) { write_any(v, path); }
void write_volume(const Volume<int16_t>& v, const std::string& path) { write_any(v, path); }
void write_volume(const Volume<float>& v, const std::string& path) { write_any(v, path); }

}  // namespace endocast
