// Volumes written a slab of slices at a time (io.h, open_slab_writer): NRRD with raw data here,
// TIFF in tiff_io.cpp. No ITK: the header is a few lines and the data are appended as they come.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

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

/// NRRD0004 with an attached header and raw int16 data in the host's byte order, under a temporary
/// name beside `path` until finish().
class NrrdSlabWriter : public SlabWriter {
public:
    NrrdSlabWriter(const std::string& path, const Geometry& whole)
        : path_(path), temp_((fs::path(path).parent_path() / ("." + fs::path(path).filename().string() + ".part")).string()),
          whole_(whole) {
        f_ = std::fopen(temp_.c_str(), "wb");
        if (!f_) throw IoError(path + ": cannot write: " + std::strerror(errno));
        const Geometry& g = whole;
        std::string h = "NRRD0004\n# Complete NRRD file format specification at:\n"
                        "# http://teem.sourceforge.net/nrrd/format.html\n"
                        "type: short\ndimension: 3\nspace: left-posterior-superior\n";
        h += "sizes: " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " + std::to_string(g.dims[2]) + "\n";
        h += "space directions:";
        for (int c = 0; c < 3; ++c) {
            h += " (";
            for (int r = 0; r < 3; ++r)
                h += (r ? "," : "") + exact(g.direction[size_t(3 * r + c)] * g.spacing[size_t(c)]);
            h += ")";
        }
        h += "\nkinds: domain domain domain\n";
        h += std::string("endian: ") + (host_is_little_endian() ? "little" : "big") + "\nencoding: raw\n";
        h += "space origin: (" + exact(g.origin[0]) + "," + exact(g.origin[1]) + "," + exact(g.origin[2]) + ")\n\n";
        put(h.data(), h.size());
    }
    NrrdSlabWriter(const NrrdSlabWriter&) = delete;
    NrrdSlabWriter& operator=(const NrrdSlabWriter&) = delete;
    ~NrrdSlabWriter() override {
        if (f_) std::fclose(f_);
        if (!finished_) {
            std::error_code ec;
            fs::remove(temp_, ec);
        }
    }

    void write(const Volume<int16_t>& slab) override {
        const Dims d = slab.dims();
        check_slab(path_, whole_, next_z_, d);
        put(slab.data(), slab.size() * sizeof(int16_t));
        next_z_ += d[2];
    }

    void finish() override {
        if (next_z_ != whole_.dims[2])
            throw InvalidParameter(path_ + ": " + std::to_string(next_z_) + " slices written, expected " +
                                   std::to_string(whole_.dims[2]));
        const int rc = std::fclose(f_);
        f_ = nullptr;
        if (rc != 0) throw IoError(path_ + ": cannot write: " + std::strerror(errno));
        std::error_code ec;
        fs::rename(temp_, path_, ec);
        if (ec) throw IoError(path_ + ": cannot rename " + temp_ + " to it: " + ec.message());
        finished_ = true;
    }

private:
    void put(const void* p, size_t n) {
        if (std::fwrite(p, 1, n, f_) != n)
            throw IoError(path_ + ": cannot write " + std::to_string(n) + " bytes: " + std::strerror(errno));
    }

    std::string path_, temp_;
    Geometry whole_;
    std::FILE* f_ = nullptr;
    int64_t next_z_ = 0;
    bool finished_ = false;
};

}  // namespace

std::unique_ptr<SlabWriter> open_slab_writer(const std::string& path, const Geometry& whole) {
    if (is_tiff_path(path)) return open_tiff_slab_writer(path, whole);
    if (meshpost::text::lower_extension(path) == ".nrrd") return std::make_unique<NrrdSlabWriter>(path, whole);
    throw IoError(path + ": cannot write a volume slab by slab in this format, expected .nrrd or .tif/.tiff");
}

}  // namespace endocast
