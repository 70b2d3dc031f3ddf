// Headerless raw volumes: one file or a stack of slice/slab files. No ITK here.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <system_error>

#include <fcntl.h>
#include <glob.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "endocast/io.h"
#include "io_internal.h"
#include "meshpost/text.h"

namespace endocast {
namespace {

namespace fs = std::filesystem;

struct TypeInfo {
    RawType type;
    const char* name;
    size_t size;
};

constexpr TypeInfo kTypes[] = {
    {RawType::Int8, "int8", 1},       {RawType::UInt8, "uint8", 1},
    {RawType::Int16, "int16", 2},     {RawType::UInt16, "uint16", 2},
    {RawType::Int32, "int32", 4},     {RawType::UInt32, "uint32", 4},
    {RawType::Float32, "float32", 4}, {RawType::Float64, "float64", 8},
};

const TypeInfo& info_of(RawType t) {
    for (const auto& ti : kTypes)
        if (ti.type == t) return ti;
    throw InvalidParameter("raw type " + std::to_string(static_cast<int>(t)) +
                           " is not a known RawType");
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

}  // namespace

bool natural_less(const std::string& a, const std::string& b) {
    size_t i = 0, j = 0;
    while (i < a.size() && j < b.size()) {
        if (is_digit(a[i]) && is_digit(b[j])) {
            size_t ie = i, je = j;
            while (ie < a.size() && is_digit(a[ie])) ++ie;
            while (je < b.size() && is_digit(b[je])) ++je;
            size_t is = i, js = j;  // skip leading zeros
            while (is + 1 < ie && a[is] == '0') ++is;
            while (js + 1 < je && b[js] == '0') ++js;
            const size_t la = ie - is, lb = je - js;
            if (la != lb) return la < lb;
            const int c = a.compare(is, la, b, js, lb);
            if (c != 0) return c < 0;
            i = ie;
            j = je;
        } else {
            if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
            ++i;
            ++j;
        }
    }
    if ((a.size() - i) != (b.size() - j)) return (a.size() - i) < (b.size() - j);
    return a < b;  // equal up to leading zeros: plain order keeps the sort deterministic
}

std::string PrintfPattern::format(long n) const {
    char buf[64];
    std::snprintf(buf, sizeof buf, spec.c_str(), n);
    return prefix + buf + suffix;
}

std::optional<PrintfPattern> parse_printf(const std::string& s) {
    PrintfPattern p;
    std::string* out = &p.prefix;
    bool found = false;
    for (size_t i = 0; i < s.size(); ++i) {
        if (s[i] != '%') {
            *out += s[i];
            continue;
        }
        if (i + 1 < s.size() && s[i + 1] == '%') {
            *out += '%';
            ++i;
            continue;
        }
        if (found) return std::nullopt;  // a second conversion
        size_t k = i + 1;
        std::string flags, width;
        while (k < s.size() && s[k] != '\0' && std::strchr("0-+ ", s[k]) && flags.size() < 4) flags += s[k++];
        while (k < s.size() && is_digit(s[k]) && width.size() < 3) width += s[k++];
        if (k >= s.size() || s[k] == '\0' || !std::strchr("diu", s[k])) return std::nullopt;
        p.spec = "%" + flags + width + "l" + (s[k] == 'u' ? "u" : "d");
        found = true;
        out = &p.suffix;
        i = k;
    }
    if (!found) return std::nullopt;
    return p;
}

namespace {

bool has_glob_chars(const std::string& s) { return s.find_first_of("*?[") != std::string::npos; }

bool is_regular_file(const std::string& p) {
    std::error_code ec;
    return fs::is_regular_file(p, ec);
}

}  // namespace

std::vector<std::string> expand_files(const std::string& in, const std::string& kind) {
    std::error_code ec;
    if (fs::exists(in, ec)) {
        if (fs::is_directory(in, ec))
            throw IoError(in + ": is a directory, expected a " + kind + " file or pattern");
        return {in};
    }
    if (auto pp = parse_printf(in)) {
        std::vector<std::string> files;
        long n = is_regular_file(pp->format(0)) ? 0 : 1;
        for (; is_regular_file(pp->format(n)); ++n) files.push_back(pp->format(n));
        if (files.empty())
            throw IoError(in + ": no file matches the pattern (tried " + pp->format(0) + " and " +
                          pp->format(1) + ")");
        return files;
    }
    if (has_glob_chars(in)) {
        glob_t g{};
        const int rc = ::glob(in.c_str(), 0, nullptr, &g);
        std::vector<std::string> files;
        if (rc == 0)
            for (size_t i = 0; i < g.gl_pathc; ++i)
                if (is_regular_file(g.gl_pathv[i])) files.emplace_back(g.gl_pathv[i]);
        ::globfree(&g);
        if (rc != 0 && rc != GLOB_NOMATCH)
            throw IoError(in + ": cannot expand the pattern (glob error " + std::to_string(rc) + ")");
        if (files.empty()) throw IoError(in + ": no file matches the pattern");
        return files;
    }
    throw IoError(in + ": no such file");
}

namespace {

std::string dims_string(const Dims& d) {
    return std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " + std::to_string(d[2]);
}

constexpr uint64_t kMaxVoxels = uint64_t{1} << 40;

void validate(const RawOptions& o) {
    for (int a = 0; a < 3; ++a)
        if (o.size[a] <= 0)
            throw InvalidParameter("raw size " + dims_string(o.size) +
                                   ": every dimension must be > 0");
    uint64_t n = 1;
    for (int a = 0; a < 3; ++a) {
        const uint64_t d = static_cast<uint64_t>(o.size[a]);
        if (d > kMaxVoxels / n)
            throw InvalidParameter("raw size " + dims_string(o.size) +
                                   ": too many voxels, expected at most 2^40");
        n *= d;
    }
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(o.spacing[a]) || o.spacing[a] <= 0)
            throw InvalidParameter("raw spacing " + meshpost::text::point(o.spacing) +
                                   ": expected finite values > 0");
        if (!std::isfinite(o.origin[a]))
            throw InvalidParameter("raw origin " + meshpost::text::point(o.origin) +
                                   ": expected finite values");
    }
    info_of(o.type);
}

/// Refuses a raw volume that cannot fit in physical memory as float (read whole).
void check_fits_memory(const RawOptions& o) {
    const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
    if (pages <= 0 || page <= 0) return;
    const long double mem = static_cast<long double>(pages) * static_cast<long double>(page);
    long double n = 1;
    for (int a = 0; a < 3; ++a) n *= static_cast<long double>(o.size[a]);
    const long double need = n * sizeof(float);
    if (need > mem)
        throw InvalidParameter("raw size " + dims_string(o.size) + " needs " +
                               std::to_string(static_cast<uint64_t>(need / (1 << 20))) +
                               " MiB as float, more than the " +
                               std::to_string(static_cast<uint64_t>(mem / (1 << 20))) +
                               " MiB of memory");
}

/// Converts n stored values of type S at src (bytes reversed if `swap`) to float.
template <class S>
void convert(const unsigned char* src, size_t n, bool swap, float* dst) {
    unsigned char tmp[sizeof(S)];
    for (size_t i = 0; i < n; ++i, src += sizeof(S)) {
        if (swap) {
            for (size_t b = 0; b < sizeof(S); ++b) tmp[b] = src[sizeof(S) - 1 - b];
        } else {
            std::memcpy(tmp, src, sizeof(S));
        }
        S s;
        std::memcpy(&s, tmp, sizeof(S));
        dst[i] = static_cast<float>(s);
    }
}

}  // namespace

std::optional<std::string> slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return std::nullopt;
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size < 0) return std::nullopt;
    in.seekg(0);
    std::string bytes(static_cast<size_t>(size), '\0');
    if (!in.read(bytes.data(), size)) return std::nullopt;
    return bytes;
}

std::optional<FileBytes> FileBytes::open(const std::string& path) {
    FileBytes f;
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return std::nullopt;
    struct stat st{};
    if (fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
        // MAP_POPULATE: the pages mapped now, not faulted in one by one as they are read.
        void* m = mmap(nullptr, size_t(st.st_size), PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
        if (m != MAP_FAILED) {
            f.map_ = m;
            f.size_ = size_t(st.st_size);
        }
    }
    ::close(fd);
    if (f.map_) return f;
    std::optional<std::string> bytes = slurp(path);
    if (!bytes) return std::nullopt;
    f.copy_ = std::move(*bytes);
    return f;
}

FileBytes::FileBytes(FileBytes&& o) noexcept : map_(o.map_), size_(o.size_), copy_(std::move(o.copy_)) {
    o.map_ = nullptr;
    o.size_ = 0;
}

FileBytes& FileBytes::operator=(FileBytes&& o) noexcept {
    if (this != &o) {
        if (map_) munmap(map_, size_);
        map_ = o.map_;
        size_ = o.size_;
        copy_ = std::move(o.copy_);
        o.map_ = nullptr;
        o.size_ = 0;
    }
    return *this;
}

FileBytes::~FileBytes() {
    if (map_) munmap(map_, size_);
}

bool host_is_little_endian() {
    const uint16_t one = 1;
    unsigned char b;
    std::memcpy(&b, &one, 1);
    return b == 1;
}

void convert_samples(RawType t, const unsigned char* src, size_t n, bool swap, float* dst) {
    switch (t) {
        case RawType::Int8: return convert<int8_t>(src, n, false, dst);
        case RawType::UInt8: return convert<uint8_t>(src, n, false, dst);
        case RawType::Int16: return convert<int16_t>(src, n, swap, dst);
        case RawType::UInt16: return convert<uint16_t>(src, n, swap, dst);
        case RawType::Int32: return convert<int32_t>(src, n, swap, dst);
        case RawType::UInt32: return convert<uint32_t>(src, n, swap, dst);
        case RawType::Float32: return convert<float>(src, n, swap, dst);
        case RawType::Float64: return convert<double>(src, n, swap, dst);
    }
}

void convert_in_parallel(RawType t, const unsigned char* src, size_t n, bool swap, float* dst) {
    constexpr size_t kChunk = size_t(1) << 16;
    const size_t bytes = raw_type_size(t);
    const int64_t chunks = int64_t((n + kChunk - 1) / kChunk);
#pragma omp parallel for schedule(static)
    for (int64_t c = 0; c < chunks; ++c) {
        const size_t a = size_t(c) * kChunk, m = std::min(kChunk, n - a);
        convert_samples(t, src + a * bytes, m, swap, dst + a);
    }
}

namespace {

struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};

/// Reads `count` voxels after `header` bytes of `path` into dst.
void read_file(const std::string& path, const RawOptions& o, size_t count, float* dst) {
    std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
    if (!f) throw IoError(path + ": cannot open: " + std::strerror(errno));
    if (o.header_bytes > 0 &&
        ::fseeko(f.get(), static_cast<off_t>(o.header_bytes), SEEK_SET) != 0)
        throw IoError(path + ": cannot skip the " + std::to_string(o.header_bytes) +
                      " header bytes: " + std::strerror(errno));
    const size_t tsize = raw_type_size(o.type);
    const bool swap = (o.endian == Endian::Little) != host_is_little_endian();
    const size_t chunk = (size_t{1} << 22) / tsize;  // 4 MiB of stored data at a time
    std::vector<unsigned char> buf(std::min(chunk, count) * tsize);
    size_t done = 0;
    while (done < count) {
        const size_t n = std::min(chunk, count - done);
        if (std::fread(buf.data(), tsize, n, f.get()) != n)
            throw IoError(path + ": short read after " + std::to_string(done) + " of " +
                          std::to_string(count) + " voxels" +
                          (std::ferror(f.get()) ? std::string(": ") + std::strerror(errno) : ""));
        convert_samples(o.type, buf.data(), n, swap, dst + done);
        done += n;
    }
}

}  // namespace

std::string to_string(RawType t) { return info_of(t).name; }

size_t raw_type_size(RawType t) { return info_of(t).size; }

RawLayout scan_raw(const std::vector<std::string>& inputs, const RawOptions& o) {
    if (inputs.empty()) throw InvalidParameter("no raw input given, expected a file or a pattern");
    validate(o);

    RawLayout l;
    for (const auto& in : inputs) {
        auto f = expand_files(in, "raw data");
        l.files.insert(l.files.end(), f.begin(), f.end());
    }
    std::stable_sort(l.files.begin(), l.files.end(), natural_less);
    const std::vector<std::string>& files = l.files;

    const int64_t nfiles = static_cast<int64_t>(files.size());
    if (o.size[2] % nfiles != 0)
        throw InvalidParameter("raw size " + dims_string(o.size) + ": " +
                               std::to_string(o.size[2]) + " slices cannot be split evenly over " +
                               std::to_string(nfiles) + " files (" + files.front() + " ... " +
                               files.back() + ")");
    l.slices_per_file = o.size[2] / nfiles;
    const int64_t zper = l.slices_per_file;
    const size_t tsize = raw_type_size(o.type);
    const uint64_t per_file = static_cast<uint64_t>(o.size[0]) * static_cast<uint64_t>(o.size[1]) *
                              static_cast<uint64_t>(zper);
    const uint64_t expected = o.header_bytes + per_file * tsize;
    for (const auto& f : files) {
        std::error_code ec;
        const uint64_t have = fs::file_size(f, ec);
        if (ec) throw IoError(f + ": cannot get its size: " + ec.message());
        if (have != expected)
            throw IoError(f + ": holds " + std::to_string(have) + " bytes, expected " +
                          std::to_string(expected) + " (" + std::to_string(o.size[0]) + " x " +
                          std::to_string(o.size[1]) + " x " + std::to_string(zper) + " " +
                          to_string(o.type) + " + header " + std::to_string(o.header_bytes) + ")");
    }
    l.geometry.dims = o.size;
    l.geometry.spacing = o.spacing;
    l.geometry.origin = o.origin;
    return l;
}

ReadResult read_raw(const std::vector<std::string>& inputs, const RawOptions& o,
                    const std::function<void(const VolumeHeader&)>& check_header) {
    const RawLayout l = scan_raw(inputs, o);
    const std::vector<std::string>& files = l.files;
    const size_t tsize = raw_type_size(o.type);
    const uint64_t per_file = static_cast<uint64_t>(o.size[0]) * static_cast<uint64_t>(o.size[1]) *
                              static_cast<uint64_t>(l.slices_per_file);
    const Geometry& g = l.geometry;
    if (check_header) check_header({g, tsize});
    check_fits_memory(o);
    ReadResult r;
    try {
        r.volume = Volume<float>(g);
    } catch (const std::bad_alloc&) {
        throw OutOfMemory("raw size " + dims_string(o.size) + ": out of memory allocating " +
                          std::to_string(g.voxel_count() * sizeof(float) >> 20) + " MiB");
    }
    for (size_t i = 0; i < files.size(); ++i)
        read_file(files[i], o, per_file, r.volume.data() + i * per_file);

    if (o.type == RawType::Float32 || o.type == RawType::Float64) {
        const std::string bad = describe_non_finite(r.volume);
        if (!bad.empty())
            throw InvalidParameter(files.front() + (files.size() > 1 ? " ..." : "") + ": " + bad +
                                   " (" + to_string(o.type) +
                                   " NaN/Inf or out of float range), expected finite values");
    }
    r.info.paths = inputs;
    r.info.format = "raw";
    r.info.voxel_type = to_string(o.type);
    r.info.files_read = files.size();
    return r;
}

}  // namespace endocast
