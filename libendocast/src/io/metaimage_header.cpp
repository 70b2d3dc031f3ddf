// A MetaImage (.mha/.mhd) header read here, line by line, instead of by ITK 5.2's MetaIO, whose
// parser trusts its input (names read across lines into a 255-byte buffer, slice patterns passed to
// sprintf, "NDims = 5555...5" taking minutes, voxels of a short read left uninitialised: fuzz_mhd
// found a new way in each of several sessions, docs/reliability.md fixes 9-20). The format is
// "Name = value" lines up to the ElementDataFile line; everything outside the forms below is an
// IoError naming the file, the line and what was expected.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string_view>

#include "endocast/errors.h"
#include "io_internal.h"

namespace endocast {

namespace {

std::string_view trim(std::string_view s) {
    const size_t b = s.find_first_not_of(" \t");
    if (b == std::string_view::npos) return {};
    return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

std::vector<std::string_view> words_of(std::string_view s) {
    std::vector<std::string_view> w;
    for (size_t at = 0; at < s.size();) {
        at = s.find_first_not_of(" \t", at);
        if (at == std::string_view::npos) break;
        const size_t end = std::min(s.find_first_of(" \t", at), s.size());
        w.push_back(s.substr(at, end - at));
        at = end;
    }
    return w;
}

/// The element types MetaIO knows, with the bytes of each (MET_ValueTypeSize: MET_LONG is 4).
struct MetType {
    const char* name;
    std::optional<RawType> type;  ///< nullopt: 64-bit integers
    size_t bytes;
    const char* stored;           ///< as InputInfo::voxel_type names it
};
constexpr MetType kMetTypes[] = {
    {"MET_UCHAR", RawType::UInt8, 1, "uint8"},        {"MET_CHAR", RawType::Int8, 1, "int8"},
    {"MET_USHORT", RawType::UInt16, 2, "uint16"},     {"MET_SHORT", RawType::Int16, 2, "int16"},
    {"MET_UINT", RawType::UInt32, 4, "uint32"},       {"MET_INT", RawType::Int32, 4, "int32"},
    {"MET_ULONG", RawType::UInt32, 4, "uint32"},      {"MET_LONG", RawType::Int32, 4, "int32"},
    {"MET_ULONG_LONG", std::nullopt, 8, "uint64"},    {"MET_LONG_LONG", std::nullopt, 8, "int64"},
    {"MET_FLOAT", RawType::Float32, 4, "float32"},    {"MET_DOUBLE", RawType::Float64, 8, "float64"},
};

}  // namespace

MetaImageHeader read_metaimage_header(const std::string& path) {
    constexpr size_t kMaxHeader = 1u << 16;
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path + ": cannot open the MetaImage file");
    std::string head(kMaxHeader, '\0');
    in.read(head.data(), std::streamsize(head.size()));
    head.resize(size_t(in.gcount()));

    MetaImageHeader h;
    // Each field's value as first given, and on which line; a field given twice with another value
    // is refused (MetaIO took dimensions it never read after a second NDims; fuzz_mhd).
    struct Field {
        std::string value;
        long line = 0;
    };
    std::vector<std::pair<std::string, Field>> fields;
    const auto field = [&](std::string_view name) -> const Field* {
        for (const auto& [n, f] : fields)
            if (n == name) return &f;
        return nullptr;
    };
    const auto where = [&](long line) { return path + ": MetaImage header line " + std::to_string(line); };
    bool data_file_seen = false;
    long line_no = 0;
    for (size_t at = 0; at < head.size() && !data_file_seen;) {
        const size_t nl = head.find('\n', at);
        if (nl == std::string::npos && head.size() == kMaxHeader)
            throw IoError(path + ": MetaImage header has no ElementDataFile line in its first " +
                          std::to_string(kMaxHeader / 1024) +
                          " KiB, expected a text header that ends with 'ElementDataFile = ...'");
        const size_t end = nl == std::string::npos ? head.size() : nl;
        std::string_view line(head.data() + at, end - at);
        at = nl == std::string::npos ? head.size() : nl + 1;
        ++line_no;
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        for (const char c : line)
            if (static_cast<unsigned char>(c) < 0x20 && c != '\t') {
                char hex[8];
                std::snprintf(hex, sizeof hex, "0x%02x", unsigned(static_cast<unsigned char>(c)));
                throw IoError(where(line_no) + " holds the control character " + hex +
                              ", expected a text header of 'Name = value' lines");
            }
        if (trim(line).empty()) continue;
        const size_t sep = line.find_first_of("=:");
        const std::string_view name = trim(line.substr(0, std::min(sep, line.size())));
        if (sep == std::string_view::npos || name.empty() || name.size() > 254 ||
            name.find_first_of(" \t") != std::string_view::npos)
            throw IoError(where(line_no) + " '" + std::string(line.substr(0, 60)) +
                          "' is not a field, expected 'Name = value' (a name of 1 to 254 characters "
                          "without blanks, then '=' or ':')");
        const std::string value(trim(line.substr(sep + 1)));
        if (const Field* f = field(name)) {
            if (f->value != value)
                throw IoError(where(line_no) + " gives " + std::string(name) + " = " + value.substr(0, 60) +
                              " after line " + std::to_string(f->line) + " gave " + f->value.substr(0, 60) +
                              ", expected each field once");
        } else {
            fields.push_back({std::string(name), {value, line_no}});
        }
        if (name == "ElementDataFile") {
            data_file_seen = true;
            h.data_file = value;
            h.header_end = nl == std::string::npos ? -1 : int64_t(nl + 1);
        }
    }
    if (!data_file_seen)
        throw IoError(path + ": MetaImage header has no ElementDataFile line, expected a text header of "
                             "'Name = value' lines that ends with 'ElementDataFile = LOCAL' or the data file's name");
    if (h.data_file.empty())
        throw IoError(path + ": MetaImage ElementDataFile is empty, expected LOCAL (the data follow the "
                             "header) or the name of the data file");

    const auto number = [&](const char* name, std::string_view word, long line, bool whole) {
        const std::string w(word);
        errno = 0;
        char* end = nullptr;
        // Whole numbers within +-2^53, so that they are exact as doubles and convert back to int64.
        const double x = whole ? double(std::strtoll(w.c_str(), &end, 10)) : std::strtod(w.c_str(), &end);
        if (w.empty() || end != w.c_str() + w.size() || errno == ERANGE || !std::isfinite(x) ||
            (whole && std::fabs(x) > 9007199254740992.0))
            throw IoError(where(line) + ": " + name + " holds '" + w.substr(0, 40) + "', expected " +
                          (whole ? "a whole number (of at most 2^53)" : "a finite number"));
        return x;
    };
    // A field of `count` numbers (count 0: one), or nullopt when it is not given.
    const auto numbers = [&](const char* name, size_t count, bool whole) -> std::optional<std::vector<double>> {
        const Field* f = field(name);
        if (!f) return std::nullopt;
        const auto w = words_of(f->value);
        const size_t want = count == 0 ? 1 : count;
        if (w.size() != want)
            throw IoError(where(f->line) + ": " + name + " = " + f->value.substr(0, 60) + " holds " +
                          std::to_string(w.size()) + " values, expected " + std::to_string(want) +
                          (count > 1 ? " (from NDims)" : ""));
        std::vector<double> v;
        for (const auto& word : w) v.push_back(number(name, word, f->line, whole));
        return v;
    };
    // MetaIO's rule for a boolean: true when the value starts with T, t or 1.
    const auto flag = [&](const char* name, bool fallback) {
        const Field* f = field(name);
        if (!f || f->value.empty()) return fallback;
        return f->value[0] == 'T' || f->value[0] == 't' || f->value[0] == '1';
    };

    const std::optional<std::vector<double>> nd = numbers("NDims", 0, true);
    if (!nd || (*nd)[0] < 1 || (*nd)[0] > 16)
        throw IoError(path + ": MetaImage header declares NDims = " + (nd ? std::to_string(long((*nd)[0])) : "nothing") +
                      ", expected a number of dimensions from 1 to 16 (3 for a volume)");
    h.ndims = int((*nd)[0]);
    const size_t n = size_t(h.ndims);
    const auto dims = numbers("DimSize", n, true);
    if (!dims) throw IoError(path + ": MetaImage header has no DimSize, expected the number of voxels along each axis");
    for (double d : *dims)
        if (d < 0 || d > 1e12)
            throw IoError(path + ": MetaImage DimSize = " + field("DimSize")->value.substr(0, 60) +
                          ", expected numbers of voxels >= 1");
    for (double d : *dims) h.dims.push_back(int64_t(d));
    std::optional<std::vector<double>> spacing = numbers("ElementSpacing", n, false);
    if (!spacing) spacing = numbers("ElementSize", n, false);  // MetaIO: the spacing when it is not given
    std::optional<std::vector<double>> origin;
    for (const char* name : {"Offset", "Position", "Origin"})
        if (!origin) origin = numbers(name, n, false);
    std::optional<std::vector<double>> matrix;
    for (const char* name : {"TransformMatrix", "Rotation", "Orientation"})
        if (!matrix) matrix = numbers(name, n * n, false);
    if (const auto channels = numbers("ElementNumberOfChannels", 0, true)) h.channels = long((*channels)[0]);

    const Field* type = field("ElementType");
    if (!type) throw IoError(path + ": MetaImage header has no ElementType, expected e.g. ElementType = MET_SHORT");
    const MetType* met = nullptr;
    for (const MetType& t : kMetTypes)
        if (type->value == t.name) met = &t;
    if (!met)
        throw IoError(path + ": MetaImage ElementType = " + type->value.substr(0, 40) +
                      " is not supported, expected an integer or floating-point scalar type (MET_UCHAR, MET_CHAR, "
                      "MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_ULONG, MET_LONG, MET_ULONG_LONG, "
                      "MET_LONG_LONG, MET_FLOAT or MET_DOUBLE)");
    h.type = met->type;
    h.voxel_bytes = met->bytes;
    h.voxel_type = met->stored;
    h.binary = flag("BinaryData", true);
    h.compressed = h.binary && flag("CompressedData", false);  // MetaIO inflates only binary data
    h.msb = flag("BinaryDataByteOrderMSB", flag("ElementByteOrderMSB", false));
    if (const auto size = numbers("CompressedDataSize", 0, true)) {
        if ((*size)[0] < 0)
            throw IoError(path + ": MetaImage CompressedDataSize = " + std::to_string(int64_t((*size)[0])) +
                          ", expected the number of bytes of the compressed data");
        h.compressed_size = int64_t((*size)[0]);
    }
    if (const auto skip = numbers("HeaderSize", 0, true)) {
        if ((*skip)[0] < -1)
            throw IoError(path + ": MetaImage HeaderSize = " + std::to_string(int64_t((*skip)[0])) +
                          ", expected the bytes to skip before the data (>= 0), or -1 (the data are the file's last bytes)");
        h.header_size = int64_t((*skip)[0]);
    }

    // The first three axes, as ITK (MetaImageIO, then ImageFileReader into a 3-D image) gives
    // them: axis a's direction is row a of the transform matrix (Geometry::direction holds the axes
    // as columns); with more than three dimensions ITK drops the matrix (identity); a negative
    // spacing is made positive and its axis reversed.
    for (size_t a = 0; a < 3 && a < n; ++a) {
        h.geometry.dims[a] = h.dims[a];
        if (origin) h.geometry.origin[a] = (*origin)[a];
        if (matrix && n == 3)
            for (size_t c = 0; c < 3; ++c) h.geometry.direction[3 * c + a] = (*matrix)[a * n + c];
        if (spacing) h.geometry.spacing[a] = (*spacing)[a];
        if (h.geometry.spacing[a] < 0) {
            h.geometry.spacing[a] = -h.geometry.spacing[a];
            for (size_t c = 0; c < 3; ++c) h.geometry.direction[3 * c + a] = -h.geometry.direction[3 * c + a];
        }
    }
    return h;
}

}  // namespace endocast
