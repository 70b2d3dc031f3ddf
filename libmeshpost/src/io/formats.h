#pragma once
// Internal to libmeshpost's mesh io (not installed): the per-format readers and writers that
// io.cpp dispatches to, and the helpers they share (errors, number parsing, text walking, writing).
#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost::io {

class Writer;

// ------------------------------------------------------------------------------------------------
// The formats (stl.cpp, ply.cpp, obj.cpp, off.cpp). `path` only names the input or output in
// error messages; readers get the whole file's bytes (never empty), writers a validated mesh.

TriangleMesh read_stl(const std::string& path, std::string_view data);
TriangleMesh read_ply(const std::string& path, std::string_view data);
TriangleMesh read_obj(const std::string& path, std::string_view data);
TriangleMesh read_off(const std::string& path, std::string_view data);

void write_stl(const TriangleMesh& mesh, const std::string& path, Writer& w);
void write_ply(const TriangleMesh& mesh, const std::string& path, Writer& w);
void write_obj(const TriangleMesh& mesh, Writer& w);
void write_off(const TriangleMesh& mesh, Writer& w);

// ------------------------------------------------------------------------------------------------
// Errors and text (io.cpp)

/// Throws MeshIoError("<path>: <what>").
[[noreturn]] void fail(const std::string& path, const std::string& what);

/// `s` in single quotes for an error message: at most 40 characters, non-printable ones as '?'.
std::string quoted(std::string_view s);

// Number parsing (locale-independent): the whole token must be the number; a leading '+' is allowed.
bool parse_double(std::string_view tok, double& out);
bool parse_int64(std::string_view tok, int64_t& out);
bool parse_uint64(std::string_view tok, uint64_t& out);

inline bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}

/// Splits one line into whitespace-separated tokens.
void split_tokens(std::string_view line, std::vector<std::string_view>& tokens);

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
// Mesh building and binary decoding

constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max();

/// Throws (via fail) when `p` has a NaN or infinite coordinate; `where` names the vertex.
void check_finite(const std::string& path, const Point& p, const std::string& where);

/// Appends the fan triangulation of polygon `idx` (at least 3 vertices, indices validated).
inline void add_polygon(TriangleMesh& mesh, const std::vector<uint32_t>& idx) {
    for (size_t k = 1; k + 1 < idx.size(); ++k) mesh.faces.push_back({idx[0], idx[k], idx[k + 1]});
}

/// Multiplies/adds with overflow detection.
inline bool mul_overflows(uint64_t a, uint64_t b, uint64_t& out) { return __builtin_mul_overflow(a, b, &out); }
inline bool add_overflows(uint64_t a, uint64_t b, uint64_t& out) { return __builtin_add_overflow(a, b, &out); }

// Little/big-endian decoding independent of the host byte order.
inline uint64_t load_uint(const unsigned char* p, int size, bool big_endian) {
    uint64_t v = 0;
    for (int i = 0; i < size; ++i) {
        const int shift = big_endian ? 8 * (size - 1 - i) : 8 * i;
        v |= static_cast<uint64_t>(p[i]) << shift;
    }
    return v;
}

inline float load_f32(const unsigned char* p, bool big_endian) {
    const uint32_t bits = static_cast<uint32_t>(load_uint(p, 4, big_endian));
    float f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
}

inline double load_f64(const unsigned char* p, bool big_endian) {
    const uint64_t bits = load_uint(p, 8, big_endian);
    double d;
    std::memcpy(&d, &bits, sizeof d);
    return d;
}

// ------------------------------------------------------------------------------------------------
// Writing (io.cpp): the atomic temporary file and the buffered writer the formats write through

/// A uniquely named temporary file beside the target; removed unless committed.
class TempFile {
public:
    explicit TempFile(const std::string& target);
    ~TempFile();
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;

    void write(const char* p, size_t n);
    /// Syncs, closes and renames onto the target.
    void commit();

private:
    std::string target_;
    std::string name_;
    int fd_ = -1;
    bool committed_ = false;
};

/// Buffered output to a TempFile: values are stored straight into a fixed buffer (a byte
/// pattern the compiler turns into one store), flushed by the writers between records.
class Writer {
public:
    explicit Writer(TempFile& file) : file_(file), buf_(new char[kCapacity]) {}
    void text(std::string_view s) {
        if (n_ + s.size() > kCapacity) flush();
        if (s.size() > kCapacity) {
            file_.write(s.data(), s.size());
            return;
        }
        std::memcpy(buf_.get() + n_, s.data(), s.size());
        n_ += s.size();
        maybe_flush();
    }
    void number(double v) {
        room(32);
        const auto res = std::to_chars(buf_.get() + n_, buf_.get() + n_ + 32, v);
        n_ = static_cast<size_t>(res.ptr - buf_.get());
    }
    void integer(uint64_t v) {
        room(24);
        const auto res = std::to_chars(buf_.get() + n_, buf_.get() + n_ + 24, v);
        n_ = static_cast<size_t>(res.ptr - buf_.get());
    }
    void u8(uint8_t v) {
        room(1);
        buf_[n_++] = static_cast<char>(v);
    }
    void u16le(uint16_t v) {
        room(2);
        unsigned char* p = reinterpret_cast<unsigned char*>(buf_.get() + n_);
        p[0] = static_cast<unsigned char>(v & 0xFF);
        p[1] = static_cast<unsigned char>(v >> 8);
        n_ += 2;
    }
    void u32le(uint32_t v) {
        room(4);
        unsigned char* p = reinterpret_cast<unsigned char*>(buf_.get() + n_);
        p[0] = static_cast<unsigned char>(v & 0xFF);
        p[1] = static_cast<unsigned char>((v >> 8) & 0xFF);
        p[2] = static_cast<unsigned char>((v >> 16) & 0xFF);
        p[3] = static_cast<unsigned char>(v >> 24);
        n_ += 4;
    }
    void f32le(float f) {
        uint32_t bits;
        std::memcpy(&bits, &f, sizeof bits);
        u32le(bits);
    }
    void maybe_flush() {
        if (n_ >= kChunk) flush();
    }
    void flush() {
        file_.write(buf_.get(), n_);
        n_ = 0;
    }

private:
    void room(size_t k) {
        if (n_ + k > kCapacity) flush();
    }
    static constexpr size_t kChunk = 1 << 20;           ///< flushed from this many bytes on
    static constexpr size_t kCapacity = kChunk + 4096;  ///< room for a record past kChunk
    TempFile& file_;
    std::unique_ptr<char[]> buf_;
    size_t n_ = 0;
};

/// The text formats' body (OBJ, OFF): a line `vertex_prefix` "x y z" per vertex (shortest
/// round-trip decimals), then a line `face_prefix` "a b c" per face (indices + `first_index`).
void write_text_lines(const TriangleMesh& mesh, Writer& w, std::string_view vertex_prefix,
                      std::string_view face_prefix, uint64_t first_index);

}  // namespace meshpost::io
