// Mesh file reading and writing: STL, PLY, OBJ, OFF.
#include "meshpost/io.h"

#include "meshpost/measure.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <new>
#include <random>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace meshpost {
namespace {

namespace fs = std::filesystem;

enum class Format { Stl, Ply, Obj, Off };

[[noreturn]] void fail(const std::string& path, const std::string& what) {
    throw MeshIoError(path + ": " + what);
}

std::string errno_text(int err) { return std::strerror(err); }

/// Lower-case extension of the file name, including the dot ("" when there is none).
std::string lower_extension(const std::string& path) {
    const size_t slash = path.find_last_of('/');
    const size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot);
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

Format format_of(const std::string& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".stl") return Format::Stl;
    if (ext == ".ply") return Format::Ply;
    if (ext == ".obj") return Format::Obj;
    if (ext == ".off") return Format::Off;
    fail(path, "unknown mesh file extension '" + ext + "' (expected .stl, .ply, .obj or .off)");
}

std::string quoted(std::string_view s) {
    constexpr size_t kMax = 40;
    std::string out = "'";
    for (size_t i = 0; i < s.size() && i < kMax; ++i) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        out += (c >= 32 && c < 127) ? static_cast<char>(c) : '?';
    }
    if (s.size() > kMax) out += "...";
    return out + "'";
}

// ------------------------------------------------------------------------------------------------
// Number parsing (locale-independent)

bool parse_double(std::string_view tok, double& out) {
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    if (tok.empty()) return false;
    const auto res = std::from_chars(tok.data(), tok.data() + tok.size(), out);
    return res.ec == std::errc() && res.ptr == tok.data() + tok.size();
}

bool parse_int64(std::string_view tok, int64_t& out) {
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    if (tok.empty()) return false;
    const auto res = std::from_chars(tok.data(), tok.data() + tok.size(), out);
    return res.ec == std::errc() && res.ptr == tok.data() + tok.size();
}

bool parse_uint64(std::string_view tok, uint64_t& out) {
    if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
    if (tok.empty() || tok.front() == '-') return false;
    const auto res = std::from_chars(tok.data(), tok.data() + tok.size(), out);
    return res.ec == std::errc() && res.ptr == tok.data() + tok.size();
}

bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}

/// Splits one line into whitespace-separated tokens.
void split_tokens(std::string_view line, std::vector<std::string_view>& tokens) {
    tokens.clear();
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && is_space(line[i])) ++i;
        const size_t start = i;
        while (i < line.size() && !is_space(line[i])) ++i;
        if (i > start) tokens.push_back(line.substr(start, i - start));
    }
}

/// Walks a text buffer line by line.
class LineReader {
public:
    explicit LineReader(std::string_view text) : text_(text) {}
    bool next(std::string_view& line) {
        if (pos_ >= text_.size()) return false;
        size_t end = text_.find('\n', pos_);
        if (end == std::string_view::npos) end = text_.size();
        line = text_.substr(pos_, end - pos_);
        pos_ = end + 1;
        ++line_no_;
        return true;
    }
    size_t line_no() const { return line_no_; }
    size_t position() const { return pos_; }

private:
    std::string_view text_;
    size_t pos_ = 0;
    size_t line_no_ = 0;
};

/// Walks a text buffer token by token, tracking the line number.
class TokenReader {
public:
    explicit TokenReader(std::string_view text) : text_(text) {}
    bool next(std::string_view& tok) {
        while (pos_ < text_.size() && is_space(text_[pos_])) {
            if (text_[pos_] == '\n') ++line_;
            ++pos_;
        }
        if (pos_ >= text_.size()) return false;
        const size_t start = pos_;
        while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
        tok = text_.substr(start, pos_ - start);
        return true;
    }
    void skip_line() {
        while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    }
    size_t line() const { return line_; }

private:
    std::string_view text_;
    size_t pos_ = 0;
    size_t line_ = 1;
};

// ------------------------------------------------------------------------------------------------
// Common reading helpers

std::string read_whole_file(const std::string& path) {
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    if (st.type() == fs::file_type::not_found) fail(path, "cannot read mesh: the file does not exist");
    if (ec || !fs::exists(st)) fail(path, "cannot read mesh: " + (ec ? ec.message() : std::string("cannot access it")));
    if (fs::is_directory(st)) fail(path, "cannot read mesh: the path is a directory, expected a file");
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot open mesh file for reading: " + errno_text(errno));
    std::string data;
    if (fs::is_regular_file(st)) {
        const uintmax_t size = fs::file_size(path, ec);
        if (!ec && size < static_cast<uintmax_t>(std::numeric_limits<std::streamsize>::max())) {
            try {
                data.resize(static_cast<size_t>(size));
            } catch (const std::bad_alloc&) {
                fail(path, "cannot read mesh file: not enough memory for its " + std::to_string(size) + " bytes");
            }
            in.read(data.data(), static_cast<std::streamsize>(size));
            if (static_cast<uintmax_t>(in.gcount()) != size)
                fail(path, "cannot read mesh file: expected " + std::to_string(size) + " bytes, read " +
                               std::to_string(in.gcount()));
            return data;
        }
    }
    char buf[1 << 16];
    while (in.read(buf, sizeof buf) || in.gcount() > 0) data.append(buf, static_cast<size_t>(in.gcount()));
    if (in.bad()) fail(path, "cannot read mesh file: I/O error");
    return data;
}

void check_finite(const std::string& path, const Point& p, const std::string& where) {
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        fail(path, where + " has a non-finite coordinate, expected finite numbers");
}

/// Appends the fan triangulation of polygon `idx` (at least 3 vertices, indices validated).
void add_polygon(TriangleMesh& mesh, const std::vector<uint32_t>& idx) {
    for (size_t k = 1; k + 1 < idx.size(); ++k) mesh.faces.push_back({idx[0], idx[k], idx[k + 1]});
}

constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max();

/// Welds vertices by exact position (bit pattern, with -0 treated as +0).
class Welder {
public:
    explicit Welder(TriangleMesh& mesh) : mesh_(mesh) {}
    /// Returns false when the vertex count would overflow 32-bit indices.
    bool add(const Point& p, uint32_t& index) {
        Key key;
        for (int i = 0; i < 3; ++i) {
            const double v = p[i] + 0.0;  // -0.0 + 0.0 == +0.0
            std::memcpy(&key[i], &v, sizeof v);
        }
        const auto it = map_.find(key);
        if (it != map_.end()) {
            index = it->second;
            return true;
        }
        if (mesh_.vertices.size() >= kMaxVertices) return false;
        index = static_cast<uint32_t>(mesh_.vertices.size());
        mesh_.vertices.push_back({p[0] + 0.0, p[1] + 0.0, p[2] + 0.0});
        map_.emplace(key, index);
        return true;
    }
    void reserve(size_t n) { map_.reserve(n); }

private:
    using Key = std::array<uint64_t, 3>;
    struct KeyHash {
        size_t operator()(const Key& k) const {
            uint64_t h = 0x9E3779B97F4A7C15ull;
            for (uint64_t v : k) {
                h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
                h *= 0xBF58476D1CE4E5B9ull;
                h ^= h >> 31;
            }
            return static_cast<size_t>(h);
        }
    };
    TriangleMesh& mesh_;
    std::unordered_map<Key, uint32_t, KeyHash> map_;
};

// Little/big-endian decoding independent of the host byte order.
uint64_t load_uint(const unsigned char* p, int size, bool big_endian) {
    uint64_t v = 0;
    for (int i = 0; i < size; ++i) {
        const int shift = big_endian ? 8 * (size - 1 - i) : 8 * i;
        v |= static_cast<uint64_t>(p[i]) << shift;
    }
    return v;
}

float load_f32(const unsigned char* p, bool big_endian) {
    const uint32_t bits = static_cast<uint32_t>(load_uint(p, 4, big_endian));
    float f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
}

double load_f64(const unsigned char* p, bool big_endian) {
    const uint64_t bits = load_uint(p, 8, big_endian);
    double d;
    std::memcpy(&d, &bits, sizeof d);
    return d;
}

// ------------------------------------------------------------------------------------------------
// STL

bool looks_like_ascii_stl(std::string_view data) {
    size_t i = 0;
    while (i < data.size() && is_space(data[i])) ++i;
    if (data.substr(i, 5) != "solid") return false;
    // Binary files may start with "solid" too: their triangle data holds control bytes.
    const size_t n = std::min<size_t>(data.size(), 4096);
    for (size_t k = 0; k < n; ++k) {
        const unsigned char c = static_cast<unsigned char>(data[k]);
        if (c < 32 && !is_space(static_cast<char>(c))) return false;
    }
    return true;
}

TriangleMesh read_binary_stl(const std::string& path, std::string_view data, uint32_t count) {
    TriangleMesh mesh;
    Welder welder(mesh);
    mesh.faces.reserve(count);
    welder.reserve(static_cast<size_t>(count) / 2 + 4);
    mesh.vertices.reserve(static_cast<size_t>(count) / 2 + 4);
    const auto* p = reinterpret_cast<const unsigned char*>(data.data()) + 84;
    for (uint32_t t = 0; t < count; ++t, p += 50) {
        Face f;
        for (int k = 0; k < 3; ++k) {
            const unsigned char* q = p + 12 + 12 * k;
            const Point pt{load_f32(q, false), load_f32(q + 4, false), load_f32(q + 8, false)};
            check_finite(path, pt, "triangle " + std::to_string(t));
            if (!welder.add(pt, f[k])) fail(path, "too many distinct vertices for 32-bit indices");
        }
        mesh.faces.push_back(f);
    }
    return mesh;
}

TriangleMesh read_ascii_stl(const std::string& path, std::string_view data) {
    TriangleMesh mesh;
    Welder welder(mesh);
    TokenReader tr(data);
    std::string_view tok;
    auto where = [&]() { return "ASCII STL line " + std::to_string(tr.line()) + ": "; };
    auto expect = [&](std::string_view word) {
        if (!tr.next(tok)) fail(path, where() + "file ends early, expected '" + std::string(word) + "'");
        if (tok != word)
            fail(path, where() + "found " + quoted(tok) + ", expected '" + std::string(word) + "'");
    };
    auto number = [&](const char* what) {
        if (!tr.next(tok)) fail(path, where() + "file ends early, expected " + what);
        double v;
        if (!parse_double(tok, v)) fail(path, where() + "bad number " + quoted(tok) + ", expected " + what);
        return v;
    };

    expect("solid");
    tr.skip_line();
    std::vector<uint32_t> idx;
    size_t facet = 0;
    while (true) {
        if (!tr.next(tok)) fail(path, where() + "file ends early, expected 'facet' or 'endsolid'");
        if (tok == "endsolid") {
            tr.skip_line();
            if (!tr.next(tok)) break;
            if (tok != "solid")
                fail(path, where() + "found " + quoted(tok) + " after 'endsolid', expected end of file or 'solid'");
            tr.skip_line();
            continue;
        }
        if (tok != "facet") fail(path, where() + "found " + quoted(tok) + ", expected 'facet' or 'endsolid'");
        expect("normal");
        for (int i = 0; i < 3; ++i) number("a normal component");
        expect("outer");
        expect("loop");
        idx.clear();
        while (true) {
            if (!tr.next(tok)) fail(path, where() + "file ends early, expected 'vertex' or 'endloop'");
            if (tok == "endloop") break;
            if (tok != "vertex") fail(path, where() + "found " + quoted(tok) + ", expected 'vertex' or 'endloop'");
            Point p;
            for (int i = 0; i < 3; ++i) p[i] = number("a vertex coordinate");
            check_finite(path, p, where() + "vertex");
            uint32_t v;
            if (!welder.add(p, v)) fail(path, "too many distinct vertices for 32-bit indices");
            idx.push_back(v);
        }
        if (idx.size() < 3)
            fail(path, where() + "facet " + std::to_string(facet) + " has " + std::to_string(idx.size()) +
                           " vertices, expected at least 3");
        expect("endfacet");
        add_polygon(mesh, idx);
        ++facet;
    }
    return mesh;
}

TriangleMesh read_stl(const std::string& path, std::string_view data) {
    const bool ascii = looks_like_ascii_stl(data);
    if (data.size() >= 84) {
        const auto* p = reinterpret_cast<const unsigned char*>(data.data());
        const uint32_t count = static_cast<uint32_t>(load_uint(p + 80, 4, false));
        const uint64_t expected = 84 + 50 * static_cast<uint64_t>(count);
        if (expected == data.size()) return read_binary_stl(path, data, count);
        if (!ascii)
            fail(path, "binary STL declares " + std::to_string(count) + " triangles (" + std::to_string(expected) +
                           " bytes) but the file holds " + std::to_string(data.size()) + " bytes");
    } else if (!ascii) {
        fail(path, "file holds " + std::to_string(data.size()) +
                       " bytes: too short for a binary STL (at least 84 bytes) and not an ASCII STL "
                       "(no leading 'solid')");
    }
    return read_ascii_stl(path, data);
}

// ------------------------------------------------------------------------------------------------
// PLY

enum class PlyType { I8, U8, I16, U16, I32, U32, F32, F64 };

bool ply_type_from_name(std::string_view name, PlyType& t) {
    static const std::pair<std::string_view, PlyType> names[] = {
        {"char", PlyType::I8},     {"int8", PlyType::I8},    {"uchar", PlyType::U8},   {"uint8", PlyType::U8},
        {"short", PlyType::I16},   {"int16", PlyType::I16},  {"ushort", PlyType::U16}, {"uint16", PlyType::U16},
        {"int", PlyType::I32},     {"int32", PlyType::I32},  {"uint", PlyType::U32},   {"uint32", PlyType::U32},
        {"float", PlyType::F32},   {"float32", PlyType::F32}, {"double", PlyType::F64}, {"float64", PlyType::F64},
    };
    for (const auto& [n, type] : names) {
        if (n == name) {
            t = type;
            return true;
        }
    }
    return false;
}

int ply_size(PlyType t) {
    switch (t) {
        case PlyType::I8:
        case PlyType::U8: return 1;
        case PlyType::I16:
        case PlyType::U16: return 2;
        case PlyType::I32:
        case PlyType::U32:
        case PlyType::F32: return 4;
        case PlyType::F64: return 8;
    }
    return 1;
}

bool ply_is_integer(PlyType t) { return t != PlyType::F32 && t != PlyType::F64; }

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::F32;        ///< value type (element type for lists)
    bool is_list = false;
    PlyType count_type = PlyType::U8;   ///< for lists
};

struct PlyElement {
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> props;
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

/// Binary record reader with bounds checks.
class BinaryCursor {
public:
    BinaryCursor(const std::string& path, std::string_view data, size_t pos, bool big_endian)
        : path_(path), p_(reinterpret_cast<const unsigned char*>(data.data())), size_(data.size()), pos_(pos),
          big_(big_endian) {}

    void need(uint64_t n, const std::string& what) {
        if (n > size_ - pos_)
            fail(path_, "binary PLY is truncated: " + what + " ends past the end of the file (" +
                            std::to_string(size_) + " bytes)");
    }
    double number(PlyType t, const std::string& what) {
        need(static_cast<uint64_t>(ply_size(t)), what);
        const unsigned char* q = p_ + pos_;
        pos_ += static_cast<size_t>(ply_size(t));
        switch (t) {
            case PlyType::F32: return load_f32(q, big_);
            case PlyType::F64: return load_f64(q, big_);
            default: return static_cast<double>(integer_at(q, t));
        }
    }
    int64_t integer(PlyType t, const std::string& what) {
        need(static_cast<uint64_t>(ply_size(t)), what);
        const unsigned char* q = p_ + pos_;
        pos_ += static_cast<size_t>(ply_size(t));
        return integer_at(q, t);
    }
    void skip(uint64_t n, const std::string& what) {
        need(n, what);
        pos_ += static_cast<size_t>(n);
    }

private:
    int64_t integer_at(const unsigned char* q, PlyType t) const {
        const uint64_t u = load_uint(q, ply_size(t), big_);
        switch (t) {
            case PlyType::I8: return static_cast<int8_t>(static_cast<uint8_t>(u));
            case PlyType::I16: return static_cast<int16_t>(static_cast<uint16_t>(u));
            case PlyType::I32: return static_cast<int32_t>(static_cast<uint32_t>(u));
            default: return static_cast<int64_t>(u);
        }
    }
    const std::string& path_;
    const unsigned char* p_;
    size_t size_;
    size_t pos_;
    bool big_;
};

/// ASCII record reader.
class AsciiCursor {
public:
    AsciiCursor(const std::string& path, std::string_view body) : path_(path), tr_(body) {}
    std::string_view token(const std::string& what) {
        std::string_view tok;
        if (!tr_.next(tok)) fail(path_, "ASCII PLY data ends early, expected " + what);
        return tok;
    }
    double number(const std::string& what) {
        const std::string_view tok = token(what);
        double v;
        if (!parse_double(tok, v))
            fail(path_, "ASCII PLY data line " + std::to_string(tr_.line()) + ": bad number " + quoted(tok) +
                            ", expected " + what);
        return v;
    }
    int64_t integer(const std::string& what) {
        const std::string_view tok = token(what);
        int64_t v;
        if (!parse_int64(tok, v))
            fail(path_, "ASCII PLY data line " + std::to_string(tr_.line()) + ": bad integer " + quoted(tok) +
                            ", expected " + what);
        return v;
    }

private:
    const std::string& path_;
    TokenReader tr_;
};

struct PlyHeader {
    PlyFormat format = PlyFormat::Ascii;
    std::vector<PlyElement> elements;
    size_t data_start = 0;
};

PlyHeader parse_ply_header(const std::string& path, std::string_view data) {
    PlyHeader h;
    LineReader lr(data);
    std::string_view line;
    std::vector<std::string_view> tok;
    if (!lr.next(line)) fail(path, "file is empty");
    split_tokens(line, tok);
    if (tok.size() != 1 || tok[0] != "ply") fail(path, "not a PLY file: first line must be 'ply'");
    bool have_format = false;
    bool ended = false;
    while (lr.next(line)) {
        split_tokens(line, tok);
        const std::string at = "PLY header line " + std::to_string(lr.line_no()) + ": ";
        if (tok.empty()) continue;
        if (tok[0] == "comment" || tok[0] == "obj_info") continue;
        if (tok[0] == "end_header") {
            ended = true;
            break;
        }
        if (tok[0] == "format") {
            if (tok.size() < 2) fail(path, at + "'format' needs a format name");
            if (tok[1] == "ascii") h.format = PlyFormat::Ascii;
            else if (tok[1] == "binary_little_endian") h.format = PlyFormat::BinaryLE;
            else if (tok[1] == "binary_big_endian") h.format = PlyFormat::BinaryBE;
            else
                fail(path, at + "unsupported PLY format " + quoted(tok[1]) +
                               ", expected ascii, binary_little_endian or binary_big_endian");
            have_format = true;
        } else if (tok[0] == "element") {
            if (tok.size() != 3) fail(path, at + "expected 'element <name> <count>'");
            PlyElement e;
            e.name = std::string(tok[1]);
            if (!parse_uint64(tok[2], e.count))
                fail(path, at + "element count " + quoted(tok[2]) + " is not a valid non-negative 64-bit count");
            h.elements.push_back(std::move(e));
        } else if (tok[0] == "property") {
            if (h.elements.empty()) fail(path, at + "'property' before any 'element'");
            PlyProperty prop;
            if (tok.size() >= 2 && tok[1] == "list") {
                if (tok.size() != 5) fail(path, at + "expected 'property list <count type> <index type> <name>'");
                if (!ply_type_from_name(tok[2], prop.count_type))
                    fail(path, at + "unsupported property type " + quoted(tok[2]));
                if (!ply_type_from_name(tok[3], prop.type))
                    fail(path, at + "unsupported property type " + quoted(tok[3]));
                if (!ply_is_integer(prop.count_type))
                    fail(path, at + "list count type " + quoted(tok[2]) + " is unsupported, expected an integer type");
                prop.is_list = true;
                prop.name = std::string(tok[4]);
            } else {
                if (tok.size() != 3) fail(path, at + "expected 'property <type> <name>'");
                if (!ply_type_from_name(tok[1], prop.type))
                    fail(path, at + "unsupported property type " + quoted(tok[1]) +
                                   ", expected char, uchar, short, ushort, int, uint, float or double");
                prop.name = std::string(tok[2]);
            }
            h.elements.back().props.push_back(std::move(prop));
        } else {
            fail(path, at + "unknown keyword " + quoted(tok[0]));
        }
    }
    if (!ended) fail(path, "PLY header has no 'end_header' line");
    if (!have_format) fail(path, "PLY header has no 'format' line");
    h.data_start = std::min(lr.position(), data.size());
    return h;
}

/// Multiplies/adds with overflow detection.
bool mul_overflows(uint64_t a, uint64_t b, uint64_t& out) { return __builtin_mul_overflow(a, b, &out); }
bool add_overflows(uint64_t a, uint64_t b, uint64_t& out) { return __builtin_add_overflow(a, b, &out); }

TriangleMesh read_ply(const std::string& path, std::string_view data) {
    const PlyHeader h = parse_ply_header(path, data);
    const bool binary = h.format != PlyFormat::Ascii;
    const uint64_t body_size = data.size() - std::min(data.size(), h.data_start);

    // Locate the vertex and face elements and their properties; check declared sizes against the file.
    int vertex_el = -1, face_el = -1;
    int xyz[3] = {-1, -1, -1};
    int index_prop = -1;
    uint64_t min_total = 0;
    for (size_t e = 0; e < h.elements.size(); ++e) {
        const PlyElement& el = h.elements[e];
        if (el.name == "vertex" && vertex_el < 0) {
            vertex_el = static_cast<int>(e);
            for (size_t p = 0; p < el.props.size(); ++p) {
                for (int a = 0; a < 3; ++a) {
                    if (el.props[p].name == std::string(1, static_cast<char>('x' + a))) {
                        if (el.props[p].is_list) fail(path, "PLY vertex property '" + el.props[p].name + "' is a list, expected a number");
                        xyz[a] = static_cast<int>(p);
                    }
                }
            }
            if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
                fail(path, "PLY vertex element lacks one of the properties x, y, z");
            if (el.count > kMaxVertices)
                fail(path, "PLY declares " + std::to_string(el.count) +
                               " vertices, more than 32-bit indices can address");
        } else if (el.name == "face" && face_el < 0) {
            face_el = static_cast<int>(e);
            for (size_t p = 0; p < el.props.size(); ++p) {
                if (el.props[p].name == "vertex_indices" || el.props[p].name == "vertex_index") {
                    if (!el.props[p].is_list) fail(path, "PLY face property '" + el.props[p].name + "' is not a list");
                    if (!ply_is_integer(el.props[p].type))
                        fail(path, "PLY face index type is unsupported, expected an integer type");
                    index_prop = static_cast<int>(p);
                }
            }
            if (index_prop < 0) fail(path, "PLY face element has no 'vertex_indices' list property");
        }
        // Smallest possible record size: guards against hostile counts before anything is allocated.
        uint64_t record = 0;
        for (size_t p = 0; p < el.props.size(); ++p) {
            const PlyProperty& prop = el.props[p];
            const bool index_list =
                prop.is_list && face_el == static_cast<int>(e) && index_prop == static_cast<int>(p);
            uint64_t s;
            if (!binary) s = index_list ? 8 : 2;  // each value one character and a separator: "3 0 1 2 "
            else if (!prop.is_list) s = static_cast<uint64_t>(ply_size(prop.type));
            else s = static_cast<uint64_t>(ply_size(prop.count_type)) +
                     (index_list ? 3 * static_cast<uint64_t>(ply_size(prop.type)) : 0);
            record += s;
        }
        uint64_t bytes;
        if (mul_overflows(el.count, record, bytes) || add_overflows(min_total, bytes, min_total))
            fail(path, "PLY header declares " + std::to_string(el.count) + " '" + el.name +
                           "' elements: their size overflows 64 bits");
        if (min_total > body_size + (binary ? 0 : 1))  // ASCII: the last value needs no separator
            fail(path, "PLY header declares " + std::to_string(el.count) + " '" + el.name +
                           "' elements; the data up to and including them needs at least " +
                           std::to_string(min_total) + " bytes but only " + std::to_string(body_size) +
                           " bytes follow the header");
    }
    if (vertex_el < 0) fail(path, "PLY file has no 'vertex' element");

    TriangleMesh mesh;
    const uint64_t nv = h.elements[static_cast<size_t>(vertex_el)].count;
    std::vector<uint32_t> idx;
    auto use_index = [&](int64_t v, uint64_t face) {
        if (v < 0 || static_cast<uint64_t>(v) >= nv)
            fail(path, "PLY face " + std::to_string(face) + " references vertex " + std::to_string(v) +
                           ", expected an index in [0, " + std::to_string(nv) + ")");
        idx.push_back(static_cast<uint32_t>(v));
    };
    auto check_count = [&](int64_t n, uint64_t face) {
        if (n < 3)
            fail(path, "PLY face " + std::to_string(face) + " has " + std::to_string(n) +
                           " vertices, expected at least 3");
    };

    if (binary) {
        BinaryCursor cur(path, data, h.data_start, h.format == PlyFormat::BinaryBE);
        for (size_t e = 0; e < h.elements.size(); ++e) {
            const PlyElement& el = h.elements[e];
            const bool is_vertex = static_cast<int>(e) == vertex_el, is_face = static_cast<int>(e) == face_el;
            if (el.props.empty()) continue;  // records without properties occupy no data
            if (is_vertex) mesh.vertices.reserve(static_cast<size_t>(el.count));
            if (is_face) mesh.faces.reserve(static_cast<size_t>(el.count));
            for (uint64_t r = 0; r < el.count; ++r) {
                const std::string what = "'" + el.name + "' element " + std::to_string(r);
                Point pt{0, 0, 0};
                for (size_t p = 0; p < el.props.size(); ++p) {
                    const PlyProperty& prop = el.props[p];
                    if (is_vertex && !prop.is_list) {
                        const int axis = (static_cast<int>(p) == xyz[0]) ? 0 : (static_cast<int>(p) == xyz[1]) ? 1
                                       : (static_cast<int>(p) == xyz[2]) ? 2 : -1;
                        if (axis >= 0) pt[static_cast<size_t>(axis)] = cur.number(prop.type, what);
                        else cur.skip(static_cast<uint64_t>(ply_size(prop.type)), what);
                    } else if (is_face && static_cast<int>(p) == index_prop) {
                        const int64_t n = cur.integer(prop.count_type, what);
                        check_count(n, r);
                        cur.need(static_cast<uint64_t>(n) * static_cast<uint64_t>(ply_size(prop.type)), what);
                        idx.clear();
                        for (int64_t k = 0; k < n; ++k) use_index(cur.integer(prop.type, what), r);
                        add_polygon(mesh, idx);
                    } else if (prop.is_list) {
                        const int64_t n = cur.integer(prop.count_type, what);
                        if (n < 0) fail(path, "PLY " + what + " has a negative list length");
                        cur.skip(static_cast<uint64_t>(n) * static_cast<uint64_t>(ply_size(prop.type)), what);
                    } else {
                        cur.skip(static_cast<uint64_t>(ply_size(prop.type)), what);
                    }
                }
                if (is_vertex) {
                    check_finite(path, pt, "PLY vertex " + std::to_string(r));
                    mesh.vertices.push_back(pt);
                }
            }
        }
    } else {
        AsciiCursor cur(path, data.substr(std::min(data.size(), h.data_start)));
        for (size_t e = 0; e < h.elements.size(); ++e) {
            const PlyElement& el = h.elements[e];
            const bool is_vertex = static_cast<int>(e) == vertex_el, is_face = static_cast<int>(e) == face_el;
            if (el.props.empty()) continue;  // records without properties occupy no data
            if (is_vertex) mesh.vertices.reserve(static_cast<size_t>(el.count));
            if (is_face) mesh.faces.reserve(static_cast<size_t>(el.count));
            for (uint64_t r = 0; r < el.count; ++r) {
                const std::string what = "a value of '" + el.name + "' element " + std::to_string(r);
                Point pt{0, 0, 0};
                for (size_t p = 0; p < el.props.size(); ++p) {
                    const PlyProperty& prop = el.props[p];
                    if (is_vertex && !prop.is_list) {
                        const double v = cur.number(what);
                        for (int a = 0; a < 3; ++a)
                            if (static_cast<int>(p) == xyz[a]) pt[static_cast<size_t>(a)] = v;
                    } else if (prop.is_list) {
                        const int64_t n = cur.integer("a list length of '" + el.name + "' element " + std::to_string(r));
                        const bool indices = is_face && static_cast<int>(p) == index_prop;
                        if (indices) check_count(n, r);
                        if (n < 0) fail(path, "PLY " + what + " has a negative list length");
                        idx.clear();
                        for (int64_t k = 0; k < n; ++k) {
                            if (indices) use_index(cur.integer("a vertex index of face " + std::to_string(r)), r);
                            else cur.token(what);
                        }
                        if (indices) add_polygon(mesh, idx);
                    } else {
                        cur.token(what);
                    }
                }
                if (is_vertex) {
                    check_finite(path, pt, "PLY vertex " + std::to_string(r));
                    mesh.vertices.push_back(pt);
                }
            }
        }
    }
    return mesh;
}

// ------------------------------------------------------------------------------------------------
// OBJ

TriangleMesh read_obj(const std::string& path, std::string_view data) {
    TriangleMesh mesh;
    LineReader lr(data);
    std::string_view line;
    std::vector<std::string_view> tok;
    std::vector<uint32_t> idx;
    while (lr.next(line)) {
        const size_t hash = line.find('#');
        if (hash != std::string_view::npos) line = line.substr(0, hash);
        split_tokens(line, tok);
        if (tok.empty()) continue;
        const std::string at = "OBJ line " + std::to_string(lr.line_no()) + ": ";
        if (tok[0] == "v") {
            if (tok.size() < 4) fail(path, at + "vertex has " + std::to_string(tok.size() - 1) +
                                               " values, expected at least 3 coordinates");
            Point p;
            for (int i = 0; i < 3; ++i)
                if (!parse_double(tok[static_cast<size_t>(i) + 1], p[static_cast<size_t>(i)]))
                    fail(path, at + "bad number " + quoted(tok[static_cast<size_t>(i) + 1]) + ", expected a coordinate");
            check_finite(path, p, at + "vertex");
            if (mesh.vertices.size() >= kMaxVertices) fail(path, at + "too many vertices for 32-bit indices");
            mesh.vertices.push_back(p);
        } else if (tok[0] == "f") {
            if (tok.size() < 4)
                fail(path, at + "face has " + std::to_string(tok.size() - 1) + " vertices, expected at least 3");
            idx.clear();
            for (size_t k = 1; k < tok.size(); ++k) {
                const std::string_view ref = tok[k].substr(0, tok[k].find('/'));
                int64_t i;
                if (!parse_int64(ref, i)) fail(path, at + "bad vertex index " + quoted(tok[k]));
                if (i == 0)
                    fail(path, at + "vertex index 0 is invalid, expected 1-based (or negative relative) indices");
                const int64_t n = static_cast<int64_t>(mesh.vertices.size());
                const int64_t resolved = i > 0 ? i - 1 : n + i;
                if (resolved < 0 || resolved >= n)
                    fail(path, at + "vertex index " + std::to_string(i) + " is out of range, " +
                                   std::to_string(n) + " vertices are defined so far");
                idx.push_back(static_cast<uint32_t>(resolved));
            }
            add_polygon(mesh, idx);
        }
        // Other statements (vn, vt, g, o, s, usemtl, mtllib, l, p, ...) carry nothing we need.
    }
    return mesh;
}

// ------------------------------------------------------------------------------------------------
// OFF

TriangleMesh read_off(const std::string& path, std::string_view data) {
    TriangleMesh mesh;
    LineReader lr(data);
    std::string_view line;
    std::vector<std::string_view> tok;
    // Next non-empty line (comments stripped) as tokens; false at end of file.
    auto next_tokens = [&]() {
        while (lr.next(line)) {
            const size_t hash = line.find('#');
            if (hash != std::string_view::npos) line = line.substr(0, hash);
            split_tokens(line, tok);
            if (!tok.empty()) return true;
        }
        return false;
    };
    if (!next_tokens()) fail(path, "OFF file has no header, expected 'OFF'");
    if (tok[0] != "OFF" && tok[0] != "COFF" && tok[0] != "NOFF" && tok[0] != "CNOFF")
        fail(path, "OFF header is " + quoted(tok[0]) + ", expected 'OFF'");
    std::vector<std::string_view> counts(tok.begin() + 1, tok.end());
    if (counts.empty()) {
        if (!next_tokens()) fail(path, "OFF file ends before the vertex/face counts");
        counts = tok;
    }
    if (counts.size() < 2) fail(path, "OFF counts line needs '<vertices> <faces> [<edges>]'");
    uint64_t nv = 0, nf = 0;
    if (!parse_uint64(counts[0], nv)) fail(path, "OFF vertex count " + quoted(counts[0]) + " is not a valid count");
    if (!parse_uint64(counts[1], nf)) fail(path, "OFF face count " + quoted(counts[1]) + " is not a valid count");
    if (nv > kMaxVertices) fail(path, "OFF declares " + std::to_string(nv) + " vertices, more than 32-bit indices can address");
    // Each vertex line needs at least 6 bytes ("0 0 0\n"), each face line 8 ("3 0 1 2\n").
    uint64_t need_v, need_f, need;
    if (mul_overflows(nv, 6, need_v) || mul_overflows(nf, 8, need_f) || add_overflows(need_v, need_f, need) ||
        need > data.size())
        fail(path, "OFF declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                       " faces, more than the " + std::to_string(data.size()) + "-byte file can hold");
    mesh.vertices.reserve(static_cast<size_t>(nv));
    mesh.faces.reserve(static_cast<size_t>(nf));
    for (uint64_t i = 0; i < nv; ++i) {
        if (!next_tokens())
            fail(path, "OFF file ends after " + std::to_string(i) + " of " + std::to_string(nv) + " vertices");
        const std::string at = "OFF line " + std::to_string(lr.line_no()) + ": ";
        if (tok.size() < 3) fail(path, at + "vertex needs 3 coordinates");
        Point p;
        for (size_t k = 0; k < 3; ++k)
            if (!parse_double(tok[k], p[k])) fail(path, at + "bad number " + quoted(tok[k]) + ", expected a coordinate");
        check_finite(path, p, at + "vertex");
        mesh.vertices.push_back(p);
    }
    std::vector<uint32_t> idx;
    for (uint64_t f = 0; f < nf; ++f) {
        if (!next_tokens())
            fail(path, "OFF file ends after " + std::to_string(f) + " of " + std::to_string(nf) + " faces");
        const std::string at = "OFF line " + std::to_string(lr.line_no()) + ": ";
        uint64_t n;
        if (!parse_uint64(tok[0], n)) fail(path, at + "bad face vertex count " + quoted(tok[0]));
        if (n < 3) fail(path, at + "face has " + std::to_string(n) + " vertices, expected at least 3");
        if (n > tok.size() - 1)
            fail(path, at + "face declares " + std::to_string(n) + " vertices but lists " +
                           std::to_string(tok.size() - 1));
        idx.clear();
        for (size_t k = 1; k <= n; ++k) {
            uint64_t v;
            if (!parse_uint64(tok[k], v) || v >= nv)
                fail(path, at + "vertex index " + quoted(tok[k]) + " is invalid, expected an index in [0, " +
                               std::to_string(nv) + ")");
            idx.push_back(static_cast<uint32_t>(v));
        }
        add_polygon(mesh, idx);
    }
    return mesh;
}

// ------------------------------------------------------------------------------------------------
// Writing

/// A uniquely named temporary file beside the target; removed unless committed.
class TempFile {
public:
    explicit TempFile(const std::string& target) : target_(target) {
        static std::atomic<uint64_t> counter{0};
        uint64_t seed = static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count()) ^
                        (static_cast<uint64_t>(::getpid()) << 32) ^ (counter.fetch_add(1) * 0x9E3779B97F4A7C15ull);
        try {
            std::random_device rd;
            seed ^= (static_cast<uint64_t>(rd()) << 32) ^ rd();
        } catch (...) {
            // The clock, pid and counter are unique enough.
        }
        std::mt19937_64 rng(seed);
        static const char alphabet[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
        for (int attempt = 0; attempt < 100; ++attempt) {
            std::string name = target + ".tmp-";
            for (int i = 0; i < 6; ++i) name += alphabet[rng() % (sizeof alphabet - 1)];
            const int fd = ::open(name.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
            if (fd >= 0) {
                fd_ = fd;
                name_ = std::move(name);
                return;
            }
            if (errno != EEXIST) fail(target, "cannot create temporary file " + name + ": " + errno_text(errno));
        }
        fail(target, "cannot create a unique temporary file beside it");
    }
    ~TempFile() {
        if (fd_ >= 0) ::close(fd_);
        if (!committed_ && !name_.empty()) ::unlink(name_.c_str());
    }
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;

    void write(const char* p, size_t n) {
        while (n > 0) {
            const ssize_t w = ::write(fd_, p, n);
            if (w < 0) {
                if (errno == EINTR) continue;
                fail(target_, "cannot write temporary file " + name_ + ": " + errno_text(errno));
            }
            p += w;
            n -= static_cast<size_t>(w);
        }
    }
    /// Syncs, closes and renames onto the target.
    void commit() {
        if (::fsync(fd_) != 0 && errno != EINVAL && errno != EROFS)
            fail(target_, "cannot sync temporary file " + name_ + ": " + errno_text(errno));
        const int fd = fd_;
        fd_ = -1;
        if (::close(fd) != 0) fail(target_, "cannot close temporary file " + name_ + ": " + errno_text(errno));
        if (std::rename(name_.c_str(), target_.c_str()) != 0)
            fail(target_, "cannot rename temporary file " + name_ + " onto it: " + errno_text(errno));
        committed_ = true;
    }

private:
    std::string target_;
    std::string name_;
    int fd_ = -1;
    bool committed_ = false;
};

/// Buffered output to a TempFile.
class Writer {
public:
    explicit Writer(TempFile& file) : file_(file) { buf_.reserve(kChunk + 256); }
    void text(std::string_view s) {
        buf_.append(s.data(), s.size());
        maybe_flush();
    }
    void number(double v) {
        char tmp[32];
        const auto res = std::to_chars(tmp, tmp + sizeof tmp, v);
        buf_.append(tmp, static_cast<size_t>(res.ptr - tmp));
    }
    void integer(uint64_t v) {
        char tmp[24];
        const auto res = std::to_chars(tmp, tmp + sizeof tmp, v);
        buf_.append(tmp, static_cast<size_t>(res.ptr - tmp));
    }
    void u8(uint8_t v) { buf_.push_back(static_cast<char>(v)); }
    void u16le(uint16_t v) {
        for (int i = 0; i < 2; ++i) buf_.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
    }
    void u32le(uint32_t v) {
        for (int i = 0; i < 4; ++i) buf_.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
    }
    void f32le(float f) {
        uint32_t bits;
        std::memcpy(&bits, &f, sizeof bits);
        u32le(bits);
    }
    void maybe_flush() {
        if (buf_.size() >= kChunk) flush();
    }
    void flush() {
        file_.write(buf_.data(), buf_.size());
        buf_.clear();
    }

private:
    static constexpr size_t kChunk = 1 << 20;
    TempFile& file_;
    std::string buf_;
};

void validate_for_write(const TriangleMesh& mesh, const std::string& path, bool float32) {
    const size_t nv = mesh.vertices.size();
    for (size_t i = 0; i < mesh.faces.size(); ++i)
        for (uint32_t v : mesh.faces[i])
            if (v >= nv)
                fail(path, "cannot write: face " + std::to_string(i) + " references vertex " + std::to_string(v) +
                               " but the mesh has " + std::to_string(nv) + " vertices");
    constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
    for (size_t i = 0; i < nv; ++i) {
        const Point& p = mesh.vertices[i];
        for (double c : p) {
            if (!std::isfinite(c))
                fail(path, "cannot write: vertex " + std::to_string(i) + " has a non-finite coordinate");
            if (float32 && std::fabs(c) > kFloatMax)
                fail(path, "cannot write: vertex " + std::to_string(i) + " does not fit the float32 range of the format");
        }
    }
}

void write_stl(const TriangleMesh& mesh, const std::string& path, Writer& w) {
    if (mesh.faces.size() > std::numeric_limits<uint32_t>::max())
        fail(path, "cannot write: binary STL holds at most 2^32-1 triangles");
    char header[80] = {};
    // Must not start with "solid". SPACE=LPS tells 3D Slicer (and other readers that look for it)
    // that the coordinates are LPS, as every coordinate in endocast is (docs/slicer.md).
    const char title[] = "binary STL written by endocast meshpost SPACE=LPS";
    std::memcpy(header, title, sizeof title - 1);
    w.text(std::string_view(header, sizeof header));
    w.u32le(static_cast<uint32_t>(mesh.faces.size()));
    for (const Face& f : mesh.faces) {
        Point n = face_cross(mesh, f);
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (double& x : n) x = (len > 0 && std::isfinite(len)) ? x / len : 0.0;
        for (double x : n) w.f32le(static_cast<float>(x));
        for (uint32_t vi : f)
            for (double x : mesh.vertices[vi]) w.f32le(static_cast<float>(x));
        w.u16le(0);
        w.maybe_flush();
    }
}

void write_ply(const TriangleMesh& mesh, const std::string& path, Writer& w) {
    if (mesh.vertices.size() > static_cast<size_t>(std::numeric_limits<int32_t>::max()))
        fail(path, "cannot write: PLY 'int' indices address at most 2^31-1 vertices");
    w.text("ply\nformat binary_little_endian 1.0\ncomment written by endocast meshpost\ncomment SPACE=LPS\nelement vertex ");
    w.integer(mesh.vertices.size());
    w.text("\nproperty float x\nproperty float y\nproperty float z\nelement face ");
    w.integer(mesh.faces.size());
    w.text("\nproperty list uchar int vertex_indices\nend_header\n");
    for (const Point& p : mesh.vertices) {
        for (double x : p) w.f32le(static_cast<float>(x));
        w.maybe_flush();
    }
    for (const Face& f : mesh.faces) {
        w.u8(3);
        for (uint32_t v : f) w.u32le(v);
        w.maybe_flush();
    }
}

void write_obj(const TriangleMesh& mesh, Writer& w) {
    w.text("# written by endocast meshpost\n# SPACE=LPS\n");
    for (const Point& p : mesh.vertices) {
        w.text("v ");
        w.number(p[0]);
        w.text(" ");
        w.number(p[1]);
        w.text(" ");
        w.number(p[2]);
        w.text("\n");
    }
    for (const Face& f : mesh.faces) {
        w.text("f ");
        w.integer(static_cast<uint64_t>(f[0]) + 1);
        w.text(" ");
        w.integer(static_cast<uint64_t>(f[1]) + 1);
        w.text(" ");
        w.integer(static_cast<uint64_t>(f[2]) + 1);
        w.text("\n");
    }
}

void write_off(const TriangleMesh& mesh, Writer& w) {
    w.text("OFF\n");
    w.integer(mesh.vertices.size());
    w.text(" ");
    w.integer(mesh.faces.size());
    w.text(" 0\n");
    for (const Point& p : mesh.vertices) {
        w.number(p[0]);
        w.text(" ");
        w.number(p[1]);
        w.text(" ");
        w.number(p[2]);
        w.text("\n");
    }
    for (const Face& f : mesh.faces) {
        w.text("3 ");
        w.integer(f[0]);
        w.text(" ");
        w.integer(f[1]);
        w.text(" ");
        w.integer(f[2]);
        w.text("\n");
    }
}

}  // namespace

void write_mesh(const TriangleMesh& mesh, const std::string& path) {
    const Format format = format_of(path);
    validate_for_write(mesh, path, format == Format::Stl || format == Format::Ply);
    TempFile file(path);
    Writer w(file);
    switch (format) {
        case Format::Stl: write_stl(mesh, path, w); break;
        case Format::Ply: write_ply(mesh, path, w); break;
        case Format::Obj: write_obj(mesh, w); break;
        case Format::Off: write_off(mesh, w); break;
    }
    w.flush();
    file.commit();
}

namespace {

/// Parses `data` as `format`; `path` only names the input in error messages.
TriangleMesh parse_mesh(const std::string& path, Format format, const std::string& data) {
    if (data.empty()) fail(path, "file is empty, expected a mesh");
    switch (format) {
        case Format::Stl: return read_stl(path, data);
        case Format::Ply: return read_ply(path, data);
        case Format::Obj: return read_obj(path, data);
        case Format::Off: return read_off(path, data);
    }
    fail(path, "unknown mesh format");
}

}  // namespace

TriangleMesh read_mesh(const std::string& path) {
    const Format format = format_of(path);
    const std::string data = read_whole_file(path);
    return parse_mesh(path, format, data);
}

TriangleMesh read_mesh_from_memory(const std::string& bytes, const std::string& extension) {
    const std::string name = "<memory>" + (extension.empty() || extension[0] == '.' ? extension : "." + extension);
    return parse_mesh(name, format_of(name), bytes);
}

}  // namespace meshpost
