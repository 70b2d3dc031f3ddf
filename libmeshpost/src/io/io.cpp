// Mesh io by file extension (write_mesh, read_mesh, read_mesh_from_memory) and the helpers the
// format files share (errors, number parsing, atomic writing, the OBJ/OFF vertex and face lines).
#include "meshpost/io.h"
#include "meshpost/text.h"

#include "formats.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <new>
#include <random>

namespace meshpost::io {
namespace {

using meshpost::text::lower_extension;

std::string errno_text(int err) { return std::strerror(err); }

}  // namespace

[[noreturn]] void fail(const std::string& path, const std::string& what) {
    throw MeshIoError(path + ": " + what);
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

void check_finite(const std::string& path, const Point& p, const std::string& where) {
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
        fail(path, where + " has a non-finite coordinate, expected finite numbers");
}

// ------------------------------------------------------------------------------------------------
// Atomic writing

TempFile::TempFile(const std::string& target) : target_(target) {
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

TempFile::~TempFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_ && !name_.empty()) ::unlink(name_.c_str());
}

void TempFile::write(const char* p, size_t n) {
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

void TempFile::commit() {
    if (::fsync(fd_) != 0 && errno != EINVAL && errno != EROFS)
        fail(target_, "cannot sync temporary file " + name_ + ": " + errno_text(errno));
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail(target_, "cannot close temporary file " + name_ + ": " + errno_text(errno));
    if (std::rename(name_.c_str(), target_.c_str()) != 0)
        fail(target_, "cannot rename temporary file " + name_ + " onto it: " + errno_text(errno));
    committed_ = true;
}

void write_text_lines(const TriangleMesh& mesh, Writer& w, std::string_view vertex_prefix,
                      std::string_view face_prefix, uint64_t first_index) {
    for (const Point& p : mesh.vertices) {
        w.text(vertex_prefix);
        w.number(p[0]);
        w.text(" ");
        w.number(p[1]);
        w.text(" ");
        w.number(p[2]);
        w.text("\n");
    }
    for (const Face& f : mesh.faces) {
        w.text(face_prefix);
        w.integer(static_cast<uint64_t>(f[0]) + first_index);
        w.text(" ");
        w.integer(static_cast<uint64_t>(f[1]) + first_index);
        w.text(" ");
        w.integer(static_cast<uint64_t>(f[2]) + first_index);
        w.text("\n");
    }
}

// ------------------------------------------------------------------------------------------------
// Dispatch by extension

namespace {

namespace fs = std::filesystem;

enum class Format { Stl, Ply, Obj, Off };

Format format_of(const std::string& path) {
    const std::string ext = lower_extension(path);
    if (ext == ".stl") return Format::Stl;
    if (ext == ".ply") return Format::Ply;
    if (ext == ".obj") return Format::Obj;
    if (ext == ".off") return Format::Off;
    fail(path, "unknown mesh file extension '" + ext + "' (expected .stl, .ply, .obj or .off)");
}

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
}  // namespace meshpost::io

namespace meshpost {

void write_mesh(const TriangleMesh& mesh, const std::string& path) {
    using namespace io;
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

TriangleMesh read_mesh(const std::string& path) {
    using namespace io;
    const Format format = format_of(path);
    const std::string data = read_whole_file(path);
    return parse_mesh(path, format, data);
}

TriangleMesh read_mesh_from_memory(const std::string& bytes, const std::string& extension) {
    using namespace io;
    const std::string name = "<memory>" + (extension.empty() || extension[0] == '.' ? extension : "." + extension);
    return parse_mesh(name, format_of(name), bytes);
}

void write_file_atomic(const std::string& path, std::string_view bytes) {
    io::TempFile file(path);
    file.write(bytes.data(), bytes.size());
    file.commit();
}

}  // namespace meshpost
