// Volumes written a slab of slices at a time (io.h, open_slab_writer): NRRD with raw data here,
// TIFF in tiff_io.cpp. No ITK: the header is a few lines and the data are appended as they come.
// Also the whole-volume NRRD writer (write_nrrd_gzip): gzip data as indexed members, compressed on
// all threads (io_internal.h).
#include <libdeflate.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <type_traits>
#include <vector>

#include "endocast/io.h"
#include "endocast/tiff.h"
#include "meshpost/text.h"
#include "io_internal.h"

namespace endocast {
namespace {

namespace fs = std::filesystem;

std::string exact(double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
}

/// An attached NRRD0004 header (LPS space, as ITK writes it) for samples of NRRD type `type` on `g`,
/// in the host's byte order.
std::string nrrd_header(const Geometry& g, const char* type, const char* encoding) {
    std::string h = "NRRD0004\n# Complete NRRD file format specification at:\n"
                    "# http://teem.sourceforge.net/nrrd/format.html\n";
    h += std::string("type: ") + type + "\ndimension: 3\nspace: left-posterior-superior\n";
    h += "sizes: " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " + std::to_string(g.dims[2]) + "\n";
    h += "space directions:";
    for (int c = 0; c < 3; ++c) {
        h += " (";
        for (int r = 0; r < 3; ++r) h += (r ? "," : "") + exact(g.direction[size_t(3 * r + c)] * g.spacing[size_t(c)]);
        h += ")";
    }
    h += "\nkinds: domain domain domain\n";
    h += std::string("endian: ") + (host_is_little_endian() ? "little" : "big") + "\nencoding: " + encoding + "\n";
    h += "space origin: (" + exact(g.origin[0]) + "," + exact(g.origin[1]) + "," + exact(g.origin[2]) + ")\n\n";
    return h;
}

/// A file written under a temporary name beside `path`, renamed onto it by finish(); removed when
/// destroyed before.
class TempFile {
public:
    explicit TempFile(const std::string& path)
        : path_(path), temp_((fs::path(path).parent_path() / ("." + fs::path(path).filename().string() + ".part")).string()) {
        f_ = std::fopen(temp_.c_str(), "wb");
        if (!f_) throw IoError(path + ": cannot write: " + std::strerror(errno));
    }
    TempFile(const TempFile&) = delete;
    TempFile& operator=(const TempFile&) = delete;
    ~TempFile() {
        if (f_) std::fclose(f_);
        if (!finished_) {
            std::error_code ec;
            fs::remove(temp_, ec);
        }
    }
    void put(const void* p, size_t n) {
        if (n > 0 && std::fwrite(p, 1, n, f_) != n)
            throw IoError(path_ + ": cannot write " + std::to_string(n) + " bytes: " + std::strerror(errno));
    }
    void finish() {
        const int rc = std::fclose(f_);
        f_ = nullptr;
        if (rc != 0) throw IoError(path_ + ": cannot write: " + std::strerror(errno));
        std::error_code ec;
        fs::rename(temp_, path_, ec);
        if (ec) throw IoError(path_ + ": cannot rename " + temp_ + " to it: " + ec.message());
        finished_ = true;
    }

private:
    std::string path_, temp_;
    std::FILE* f_ = nullptr;
    bool finished_ = false;
};

void put_le(std::string& out, uint64_t v, int bytes) {
    for (int k = 0; k < bytes; ++k) out.push_back(char((v >> (8 * k)) & 0xff));
}

/// One gzip member (RFC 1952) holding `n` bytes at `in`, with the extra subfield "EC" (kGzipIndexId)
/// giving the member's whole size in bytes (by which inflate_gzip_members hops from member to member).
std::string gzip_member(const unsigned char* in, size_t n, libdeflate_compressor* c) {
    const size_t bound = libdeflate_deflate_compress_bound(c, n);
    std::string m;
    m.reserve(kGzipMemberHeader + bound + 8);
    m += "\x1f\x8b\x08\x04";  // magic, deflate, FEXTRA
    put_le(m, 0, 4);            // no time stamp
    m.push_back(0), m.push_back(char(255));  // no compression flags, unknown OS
    put_le(m, 8, 2);                          // XLEN: one 8-byte subfield
    m.push_back(kGzipIndexId[0]), m.push_back(kGzipIndexId[1]);
    put_le(m, 4, 2);
    put_le(m, 0, 4);  // the member's size, set below
    m.resize(kGzipMemberHeader + bound);
    const size_t packed = libdeflate_deflate_compress(c, in, n, m.data() + kGzipMemberHeader, bound);
    if (packed == 0) throw IoError("gzip: cannot compress " + std::to_string(n) + " bytes");
    m.resize(kGzipMemberHeader + packed);
    put_le(m, libdeflate_crc32(0, in, n), 4);
    put_le(m, uint32_t(n), 4);
    std::string size;
    put_le(size, m.size(), 4);
    std::copy(size.begin(), size.end(), m.begin() + 16);
    return m;
}

/// NRRD0004 with an attached header and raw int16 data in the host's byte order, under a temporary
/// name beside `path` until finish().
class NrrdSlabWriter : public SlabWriter {
public:
    NrrdSlabWriter(const std::string& path, const Geometry& whole) : path_(path), whole_(whole), file_(path) {
        const std::string h = nrrd_header(whole, "short", "raw");
        file_.put(h.data(), h.size());
    }

    void write(const Volume<int16_t>& slab) override {
        const Dims d = slab.dims();
        check_slab(path_, whole_, next_z_, d);
        file_.put(slab.data(), slab.size() * sizeof(int16_t));
        next_z_ += d[2];
    }

    void finish() override {
        if (next_z_ != whole_.dims[2])
            throw InvalidParameter(path_ + ": " + std::to_string(next_z_) + " slices written, expected " +
                                   std::to_string(whole_.dims[2]));
        file_.finish();
    }

private:
    std::string path_;
    Geometry whole_;
    TempFile file_;
    int64_t next_z_ = 0;
};

template <class T>
constexpr const char* nrrd_type_name() {
    if constexpr (std::is_same_v<T, uint8_t>) return "unsigned char";
    else if constexpr (std::is_same_v<T, int16_t>) return "short";
    else return "float";
}

}  // namespace

template <class T>
void write_nrrd_gzip(const Volume<T>& v, const std::string& path) {
    TempFile file(path);
    const std::string h = nrrd_header(v.geometry(), nrrd_type_name<T>(), "gzip");
    file.put(h.data(), h.size());
    const unsigned char* bytes = reinterpret_cast<const unsigned char*>(v.data());
    const size_t total = v.size() * sizeof(T);
    const size_t members = std::max<size_t>(1, (total + kGzipMemberBytes - 1) / kGzipMemberBytes);
    // In batches (the compressed batch is held until written), each member on one thread.
    constexpr size_t kBatch = 64;
    std::vector<std::string> packed(std::min(members, kBatch));
    struct Free {
        void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
    };
    for (size_t first = 0; first < members; first += kBatch) {
        const int64_t count = int64_t(std::min(kBatch, members - first));
        bool failed = false;
#pragma omp parallel reduction(|| : failed)
        {
            std::unique_ptr<libdeflate_compressor, Free> c(libdeflate_alloc_compressor(kGzipLevel));
#pragma omp for schedule(dynamic, 1)
            for (int64_t k = 0; k < count; ++k) {
                const size_t at = (first + size_t(k)) * kGzipMemberBytes;
                try {
                    if (!c) throw IoError("gzip: no compressor");
                    packed[size_t(k)] = gzip_member(bytes + at, std::min(kGzipMemberBytes, total - at), c.get());
                } catch (...) {
                    failed = true;
                }
            }
        }
        if (failed) throw IoError(path + ": cannot compress the voxels (out of memory?)");
        for (int64_t k = 0; k < count; ++k) {
            file.put(packed[size_t(k)].data(), packed[size_t(k)].size());
            std::string().swap(packed[size_t(k)]);
        }
    }
    file.finish();
}

template void write_nrrd_gzip(const Volume<uint8_t>&, const std::string&);
template void write_nrrd_gzip(const Volume<int16_t>&, const std::string&);
template void write_nrrd_gzip(const Volume<float>&, const std::string&);

std::unique_ptr<SlabWriter> open_slab_writer(const std::string& path, const Geometry& whole) {
    if (is_tiff_path(path)) return open_tiff_slab_writer(path, whole);
    if (meshpost::text::lower_extension(path) == ".nrrd") return std::make_unique<NrrdSlabWriter>(path, whole);
    throw IoError(path + ": cannot write a volume slab by slab in this format, expected .nrrd or .tif/.tiff");
}

}  // namespace endocast
