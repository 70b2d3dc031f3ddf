// Direct reading of the pixels of a DICOM CT series (see io_internal.h): the common case of
// uncompressed, little-endian, single-frame, 16-bit MONOCHROME2 CT slices, parsed here and
// converted in parallel. GDCM (through ITK) reads one slice at a time and is not safe for
// concurrent readers, so it is kept for everything else and for the geometry.
//
// Pixel values follow GDCM's reading: the bits above BitsStored are cleared (unsigned) or
// filled with the sign bit (signed), then value = stored * RescaleSlope + RescaleIntercept.
// Only integer slopes and intercepts are taken here, so every value is an integer that float
// holds exactly, as GDCM's integer output converted to float by ITK.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "io_internal.h"

namespace endocast {
namespace {

constexpr uint32_t kUndefinedLength = 0xFFFFFFFFu;
constexpr int kMaxSequenceDepth = 16;

uint16_t rd16(const unsigned char* p) { return uint16_t(p[0] | (p[1] << 8)); }
uint32_t rd32(const unsigned char* p) {
    return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
constexpr uint32_t tag_of(uint16_t group, uint16_t element) { return (uint32_t(group) << 16) | element; }

/// The value of a string element without its trailing spaces and NULs.
std::string text(const unsigned char* v, uint32_t len) {
    std::string s(reinterpret_cast<const char*>(v), len);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
    return s;
}

/// One element header: tag, value offset and length (kUndefinedLength for undefined).
struct Element {
    uint32_t tag = 0;
    size_t value = 0;
    uint32_t length = 0;
    bool explicit_un = false;  ///< explicit VR "UN" (an undefined length then holds implicit VR)
};

class Parser {
public:
    Parser(const unsigned char* b, size_t n, bool explicit_vr) : b_(b), n_(n), explicit_(explicit_vr) {}

    /// Reads the element header at `pos`; false when it does not fit in the file.
    bool header(size_t pos, Element& e) const {
        if (pos > n_ || n_ - pos < 8) return false;
        e.tag = tag_of(rd16(b_ + pos), rd16(b_ + pos + 2));
        e.explicit_un = false;
        const uint16_t group = uint16_t(e.tag >> 16);
        if (!explicit_ || group == 0xFFFE) {  // items and delimiters have no VR in any syntax
            e.length = rd32(b_ + pos + 4);
            e.value = pos + 8;
        } else {
            const char v0 = char(b_[pos + 4]), v1 = char(b_[pos + 5]);
            static const char* const kLong[] = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ",
                                                "SV", "UC", "UN", "UR", "UT", "UV"};
            bool long_form = false;
            for (const char* l : kLong) long_form = long_form || (v0 == l[0] && v1 == l[1]);
            if (long_form) {
                if (n_ - pos < 12) return false;
                e.length = rd32(b_ + pos + 8);
                e.value = pos + 12;
                e.explicit_un = v0 == 'U' && v1 == 'N';
            } else {
                e.length = rd16(b_ + pos + 6);
                e.value = pos + 8;
            }
        }
        if (e.length != kUndefinedLength && (e.value > n_ || n_ - e.value < e.length)) return false;
        return true;
    }

    /// Skips the items of a sequence of undefined length whose first item starts at `pos`; the
    /// position after its delimiter, or 0 when malformed.
    size_t skip_sequence(size_t pos, int depth) const {
        if (depth > kMaxSequenceDepth) return 0;
        for (;;) {
            Element e;
            if (!header(pos, e)) return 0;
            if (e.tag == tag_of(0xFFFE, 0xE0DD)) return e.value;  // sequence delimiter
            if (e.tag != tag_of(0xFFFE, 0xE000)) return 0;        // not an item
            if (e.length != kUndefinedLength) {
                pos = e.value + e.length;
                continue;
            }
            pos = skip_item(e.value, depth + 1);
            if (pos == 0) return 0;
        }
    }

private:
    /// Skips the elements of an item of undefined length; the position after its delimiter.
    size_t skip_item(size_t pos, int depth) const {
        if (depth > kMaxSequenceDepth) return 0;
        for (;;) {
            Element e;
            if (!header(pos, e)) return 0;
            if (e.tag == tag_of(0xFFFE, 0xE00D)) return e.value;  // item delimiter
            if (e.length == kUndefinedLength) {
                if (e.explicit_un) return 0;
                pos = skip_sequence(e.value, depth + 1);
                if (pos == 0) return 0;
            } else {
                pos = e.value + e.length;
            }
        }
    }

    const unsigned char* b_;
    size_t n_;
    bool explicit_;
};

/// What the direct reader needs of one slice file.
struct Slice {
    int rows = -1, columns = -1, bits_allocated = -1, bits_stored = -1, high_bit = -1;
    int pixel_representation = -1, samples = 1;
    std::string photometric, frames, sop_class, slope = "1", intercept = "0";
    std::string position;  ///< ImagePositionPatient's text; empty when absent
    bool modality_lut = false;
    size_t pixels = 0;
    uint32_t pixel_bytes = 0;
};

/// An integer DS value (e.g. "-1024 ", "1"); false when it is not one or too large.
bool integer_ds(const std::string& s, double& v) {
    if (s.empty()) return false;
    char* end = nullptr;
    v = std::strtod(s.c_str(), &end);
    while (end && *end == ' ') ++end;
    return end && *end == '\0' && std::isfinite(v) && v == std::floor(v) && std::fabs(v) <= 65536.0;
}

/// Parses one slice file held in `b`; false when it is not the direct reader's case.
bool parse_slice(const unsigned char* b, size_t n, Slice& s) {
    if (n < 132 || std::memcmp(b + 128, "DICM", 4) != 0) return false;
    // File meta information: group 0002, always explicit VR little endian.
    Parser meta(b, n, true);
    size_t pos = 132;
    std::string syntax;
    for (;;) {
        // The group first: the dataset after the meta group may be implicit VR, whose first
        // element must not be parsed as explicit.
        if (pos > n || n - pos < 2) return false;
        if (rd16(b + pos) != 0x0002) break;
        Element e;
        if (!meta.header(pos, e)) return false;
        if (e.length == kUndefinedLength) return false;
        if (e.tag == tag_of(0x0002, 0x0010)) syntax = text(b + e.value, e.length);
        pos = e.value + e.length;
    }
    bool explicit_vr;
    if (syntax == "1.2.840.10008.1.2") explicit_vr = false;
    else if (syntax == "1.2.840.10008.1.2.1") explicit_vr = true;
    else return false;  // compressed, big endian, deflated: GDCM reads those

    Parser p(b, n, explicit_vr);
    for (;;) {
        Element e;
        if (!p.header(pos, e)) return false;  // no pixel data
        if ((e.tag >> 16) == 0xFFFE) return false;
        if (e.tag == tag_of(0x7FE0, 0x0010)) {
            if (e.length == kUndefinedLength) return false;  // encapsulated
            s.pixels = e.value;
            s.pixel_bytes = e.length;
            return true;
        }
        if (e.length == kUndefinedLength) {
            if (e.explicit_un) return false;
            pos = p.skip_sequence(e.value, 0);
            if (pos == 0) return false;
            continue;
        }
        const unsigned char* v = b + e.value;
        auto us = [&](int& out) {
            if (e.length != 2) return false;
            out = rd16(v);
            return true;
        };
        bool ok = true;
        switch (e.tag) {
            case tag_of(0x0008, 0x0016): s.sop_class = text(v, e.length); break;
            case tag_of(0x0020, 0x0032): s.position = text(v, e.length); break;
            case tag_of(0x0028, 0x0002): ok = us(s.samples); break;
            case tag_of(0x0028, 0x0004): s.photometric = text(v, e.length); break;
            case tag_of(0x0028, 0x0008): s.frames = text(v, e.length); break;
            case tag_of(0x0028, 0x0010): ok = us(s.rows); break;
            case tag_of(0x0028, 0x0011): ok = us(s.columns); break;
            case tag_of(0x0028, 0x0100): ok = us(s.bits_allocated); break;
            case tag_of(0x0028, 0x0101): ok = us(s.bits_stored); break;
            case tag_of(0x0028, 0x0102): ok = us(s.high_bit); break;
            case tag_of(0x0028, 0x0103): ok = us(s.pixel_representation); break;
            case tag_of(0x0028, 0x1052): s.intercept = text(v, e.length); break;
            case tag_of(0x0028, 0x1053): s.slope = text(v, e.length); break;
            case tag_of(0x0028, 0x3000): s.modality_lut = true; break;
            default: break;
        }
        if (!ok) return false;
        pos = e.value + e.length;
    }
}

/// Converts one parsed slice into nx * ny floats (or int16, the same values: `fits` false when one
/// is outside int16's range); false when it is not the direct reader's case.
template <class T>
bool convert_slice(const unsigned char* b, const Slice& s, int64_t nx, int64_t ny, T* out, bool& fits) {
    if (s.sop_class != "1.2.840.10008.5.1.4.1.1.2") return false;  // CT Image Storage only
    if (s.samples != 1 || s.photometric != "MONOCHROME2" || s.modality_lut) return false;
    if (!s.frames.empty() && s.frames != "1") return false;
    if (s.rows != ny || s.columns != nx || s.bits_allocated != 16) return false;
    if (s.bits_stored < 1 || s.bits_stored > 16 || s.high_bit != s.bits_stored - 1) return false;
    if (s.pixel_representation != 0 && s.pixel_representation != 1) return false;
    const size_t count = size_t(nx) * size_t(ny);
    if (s.pixel_bytes < 2 * count) return false;
    double slope, intercept;
    if (!integer_ds(s.slope, slope) || !integer_ds(s.intercept, intercept) || slope == 0) return false;

    const unsigned char* src = b + s.pixels;
    const int unused = 16 - s.bits_stored;
    const uint16_t keep = uint16_t(0xFFFFu >> unused);
    const bool is_signed = s.pixel_representation == 1;
    const uint16_t sign = uint16_t(1u << (s.bits_stored - 1));
    for (size_t i = 0; i < count; ++i) {
        uint16_t u = rd16(src + 2 * i) & keep;
        double stored;
        if (is_signed) {
            if (u & sign) u = uint16_t(u | ~keep);  // extend the sign bit
            stored = double(int16_t(u));
        } else {
            stored = double(u);
        }
        const double value = stored * slope + intercept;
        if constexpr (std::is_same_v<T, float>) {
            out[i] = float(value);
        } else {
            const bool in_range = value >= -32768.0 && value <= 32767.0;
            fits = fits && in_range;
            out[i] = in_range ? int16_t(value) : int16_t(0);
        }
    }
    return true;
}

}  // namespace

std::optional<Vec3> parse_image_position(std::string v) {
    std::replace(v.begin(), v.end(), '\\', ' ');
    std::istringstream is(v);
    Vec3 p{};
    if (!(is >> p[0] >> p[1] >> p[2])) return std::nullopt;
    return p;
}

namespace {

template <class T>
std::optional<std::vector<Vec3>> read_pixels(const std::vector<std::string>& files, int64_t nx, int64_t ny, T* out,
                                             bool& all_fit) {
    const int64_t nz = int64_t(files.size());
    std::atomic<bool> ok{true}, fit{true};
    std::vector<std::optional<Vec3>> positions(files.size());
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t k = 0; k < nz; ++k) {
        if (!ok.load(std::memory_order_relaxed)) continue;
        Slice s;
        bool done = false;
        try {
            const std::optional<std::string> file = slurp(files[size_t(k)]);
            const auto* b = file ? reinterpret_cast<const unsigned char*>(file->data()) : nullptr;
            bool slice_fits = true;
            done = b && parse_slice(b, file->size(), s) &&
                   convert_slice(b, s, nx, ny, out + size_t(k) * size_t(nx) * size_t(ny), slice_fits);
            if (!slice_fits) fit = false;
        } catch (...) {  // out of memory for a file's bytes: ITK's reader reports it
        }
        if (!done) {
            ok = false;
            continue;
        }
        positions[size_t(k)] = parse_image_position(s.position);  // nullopt when absent
    }
    if (!ok) return std::nullopt;
    all_fit = fit;
    // As the ITK path: the positions up to the first slice without one.
    std::vector<Vec3> found;
    for (const auto& p : positions) {
        if (!p) break;
        found.push_back(*p);
    }
    return found;
}

}  // namespace

std::optional<std::vector<Vec3>> read_dicom_pixels(const std::vector<std::string>& files, int64_t nx,
                                                   int64_t ny, float* out) {
    bool fits = true;
    return read_pixels(files, nx, ny, out, fits);
}

std::optional<std::vector<Vec3>> read_dicom_pixels(const std::vector<std::string>& files, int64_t nx,
                                                   int64_t ny, int16_t* out, bool& fits) {
    fits = true;
    return read_pixels(files, nx, ny, out, fits);
}

}  // namespace endocast
