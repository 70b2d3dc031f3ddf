// Reading volumes a slab of slices at a time (slice_source.h): raw bytes at known places in files
// (headerless raw, raw NRRD), gzip data inflated in order (gzip NRRD), TIFF stacks; and read_shrunk, which crops and block-averages each
// slab as it comes so that only the result is ever held whole.
#include "slice_source.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

#include <zlib.h>

#include "endocast/errors.h"
#include "endocast/tiff.h"
#include "io_internal.h"

namespace endocast {
namespace {

namespace fs = std::filesystem;

bool is_float(RawType t) { return t == RawType::Float32 || t == RawType::Float64; }

/// Throws InvalidParameter naming `what` and the voxel when one of the n voxels at v (slices from
/// z0 of an nx x ny grid) is NaN or Inf.
void check_finite(const float* v, size_t n, int64_t nx, int64_t ny, int64_t z0, const std::string& what) {
    for (size_t i = 0; i < n; ++i) {
        if (std::isfinite(v[i])) continue;
        const int64_t x = int64_t(i) % nx, y = (int64_t(i) / nx) % ny, z = z0 + int64_t(i) / (nx * ny);
        throw InvalidParameter(what + ": voxel (" + std::to_string(x) + ", " + std::to_string(y) + ", " +
                               std::to_string(z) + ") is " + (std::isnan(v[i]) ? "NaN" : "Inf") +
                               ", expected finite values");
    }
}

void check_range(const VolumeHeader& h, int64_t z0, int64_t nz, const std::string& what) {
    if (z0 < 0 || nz < 0 || z0 + nz > h.geometry.dims[2])
        throw InvalidParameter(what + ": slices " + std::to_string(z0) + " to " + std::to_string(z0 + nz) +
                               " asked for, expected a range within the " + std::to_string(h.geometry.dims[2]) +
                               " slices");
}

struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};

/// Stored voxels in parts of files (open_raw_parts).
class RawParts final : public SliceSource {
public:
    RawParts(std::vector<RawPart> parts, RawType type, bool swap, const VolumeHeader& h, const InputInfo& info)
        : parts_(std::move(parts)), type_(type), swap_(swap) {
        header_ = h;
        header_.read_in_slabs = true;
        info_ = info;
        info_.read_path = "slabs";
        files_.resize(parts_.size());
    }

    void read(int64_t z0, int64_t nz, float* dst) override {
        const std::string& what = parts_.front().path;
        check_range(header_, z0, nz, what);
        const int64_t nx = header_.geometry.dims[0], ny = header_.geometry.dims[1];
        const size_t slice = size_t(nx) * size_t(ny), tsize = raw_type_size(type_);
        int64_t first = 0;  // first slice of part p
        for (size_t p = 0; p < parts_.size() && nz > 0; first += parts_[p].slices, ++p) {
            const int64_t last = first + parts_[p].slices;
            if (z0 >= last) continue;
            const int64_t n = std::min(nz, last - z0);
            read_part(p, z0 - first, n, slice, tsize, dst);
            if (is_float(type_)) check_finite(dst, size_t(n) * slice, nx, ny, z0, parts_[p].path);
            dst += size_t(n) * slice;
            z0 += n;
            nz -= n;
        }
    }

private:
    void read_part(size_t p, int64_t k0, int64_t n, size_t slice, size_t tsize, float* dst) {
        const RawPart& part = parts_[p];
        if (!files_[p]) {
            files_[p].reset(std::fopen(part.path.c_str(), "rb"));
            if (!files_[p]) throw IoError(part.path + ": cannot open: " + std::strerror(errno));
        }
        std::FILE* f = files_[p].get();
        const uint64_t at = part.offset + uint64_t(k0) * slice * tsize;
        if (::fseeko(f, off_t(at), SEEK_SET) != 0)
            throw IoError(part.path + ": cannot seek to byte " + std::to_string(at) + ": " + std::strerror(errno));
        const size_t count = size_t(n) * slice;
        bytes_.resize(count * tsize);
        if (std::fread(bytes_.data(), tsize, count, f) != count)
            throw IoError(part.path + ": short read of slices " + std::to_string(k0) + " to " +
                          std::to_string(k0 + n) + " (" + std::to_string(count * tsize) + " bytes from byte " +
                          std::to_string(at) + ")" +
                          (std::ferror(f) ? std::string(": ") + std::strerror(errno) : ""));
        convert_in_parallel(type_, bytes_.data(), count, swap_, dst);
    }

    std::vector<RawPart> parts_;
    RawType type_;
    bool swap_;
    std::vector<std::unique_ptr<std::FILE, FileCloser>> files_;
    std::vector<unsigned char> bytes_;  // the stored bytes of the last read
};

/// Gzip data (one or more members) from byte `offset` of a file, inflated in order with zlib:
/// reading slices behind the last one read starts again from the beginning.
class GzipSlices final : public SliceSource {
public:
    GzipSlices(std::string path, uint64_t offset, RawType type, bool swap, const VolumeHeader& h, const InputInfo& info)
        : path_(std::move(path)), offset_(offset), type_(type), swap_(swap) {
        header_ = h;
        header_.read_in_slabs = true;
        info_ = info;
        info_.read_path = "slabs";
    }
    ~GzipSlices() override { close(); }
    GzipSlices(const GzipSlices&) = delete;
    GzipSlices& operator=(const GzipSlices&) = delete;

    void read(int64_t z0, int64_t nz, float* dst) override {
        check_range(header_, z0, nz, path_);
        const int64_t nx = header_.geometry.dims[0], ny = header_.geometry.dims[1];
        const size_t slice = size_t(nx) * size_t(ny), tsize = raw_type_size(type_);
        if (!file_ || z0 < next_z_) open();
        while (next_z_ < z0) {  // skip to z0, a slice at a time
            bytes_.resize(slice * tsize);
            inflate_into(bytes_.data(), bytes_.size());
            ++next_z_;
        }
        const size_t count = size_t(nz) * slice;
        bytes_.resize(count * tsize);
        inflate_into(bytes_.data(), bytes_.size());
        next_z_ += nz;
        if (next_z_ == header_.geometry.dims[2]) check_end();
        convert_in_parallel(type_, bytes_.data(), count, swap_, dst);
        if (is_float(type_)) check_finite(dst, count, nx, ny, z0, path_);
    }

private:
    void close() {
        if (zs_open_) inflateEnd(&zs_);
        zs_open_ = false;
        file_.reset();
    }

    void open() {
        close();
        file_.reset(std::fopen(path_.c_str(), "rb"));
        if (!file_) throw IoError(path_ + ": cannot open: " + std::strerror(errno));
        if (::fseeko(file_.get(), off_t(offset_), SEEK_SET) != 0)
            throw IoError(path_ + ": cannot seek to byte " + std::to_string(offset_) + ": " + std::strerror(errno));
        zs_ = z_stream{};
        if (inflateInit2(&zs_, 16 + MAX_WBITS) != Z_OK) throw IoError(path_ + ": cannot start inflating gzip data");
        zs_open_ = true;
        in_.resize(size_t(1) << 22);
        next_z_ = 0;
        out_done_ = 0;
    }

    /// Refills the input; false at the end of the file.
    bool refill() {
        if (zs_.avail_in > 0) return true;
        const size_t got = std::fread(in_.data(), 1, in_.size(), file_.get());
        if (got == 0) {
            if (std::ferror(file_.get())) throw IoError(path_ + ": read error: " + std::strerror(errno));
            return false;
        }
        zs_.next_in = in_.data();
        zs_.avail_in = uInt(got);
        return true;
    }

    /// Inflates exactly n bytes into out (IoError when the data ends before or is corrupt).
    void inflate_into(unsigned char* out, size_t n) {
        while (n > 0) {
            if (!refill())
                throw IoError(path_ + ": gzip data ends after " + std::to_string(out_done_) +
                              " bytes, expected " + std::to_string(expected_bytes()) + " (the header's size)");
            const uInt step = uInt(std::min<size_t>(n, size_t(1) << 30));
            zs_.next_out = out;
            zs_.avail_out = step;
            const int rc = inflate(&zs_, Z_NO_FLUSH);
            const size_t made = step - zs_.avail_out;
            out += made;
            n -= made;
            out_done_ += made;
            if (rc == Z_STREAM_END) {
                if (inflateReset(&zs_) != Z_OK) throw IoError(path_ + ": cannot inflate the next gzip member");
            } else if (rc != Z_OK && !(rc == Z_BUF_ERROR && (made > 0 || zs_.avail_in == 0))) {
                throw IoError(path_ + ": corrupt gzip data after " + std::to_string(out_done_) + " bytes" +
                              (zs_.msg ? std::string(": ") + zs_.msg : ""));
            }
        }
    }

    uint64_t expected_bytes() const { return header_.geometry.voxel_count() * raw_type_size(type_); }

    /// After the last slice: nothing but empty members or the end may follow.
    void check_end() {
        unsigned char extra[64];
        while (refill()) {
            zs_.next_out = extra;
            zs_.avail_out = sizeof extra;
            const int rc = inflate(&zs_, Z_NO_FLUSH);
            if (zs_.avail_out != sizeof extra)
                throw IoError(path_ + ": holds more gzip data than the header's " + std::to_string(expected_bytes()) +
                              " bytes");
            if (rc == Z_STREAM_END) {
                if (inflateReset(&zs_) != Z_OK) throw IoError(path_ + ": cannot inflate the next gzip member");
            } else if (rc != Z_OK && !(rc == Z_BUF_ERROR && zs_.avail_in == 0)) {
                throw IoError(path_ + ": corrupt gzip data after its " + std::to_string(expected_bytes()) + " bytes");
            }
        }
    }

    std::string path_;
    uint64_t offset_;
    RawType type_;
    bool swap_;
    std::unique_ptr<std::FILE, FileCloser> file_;
    z_stream zs_{};
    bool zs_open_ = false;
    std::vector<unsigned char> in_, bytes_;
    int64_t next_z_ = 0;
    uint64_t out_done_ = 0;
};

class TiffSlices final : public SliceSource {
public:
    TiffSlices(TiffStack s, const std::vector<std::string>& inputs, const TiffReadOptions& opt) : s_(std::move(s)) {
        header_.geometry = tiff_geometry(s_, opt, info_);
        header_.stored_voxel_bytes = raw_type_size(s_.type);
        header_.read_in_slabs = true;
        info_.paths = inputs;
        info_.format = "tiff";
        info_.voxel_type = to_string(s_.type);
        info_.files_read = s_.files.size();
        info_.read_path = "slabs";
    }

    void read(int64_t z0, int64_t nz, float* dst) override {
        const std::string what = s_.multipage ? s_.files[0] : s_.files.front() + " ... " + s_.files.back();
        check_range(header_, z0, nz, what);
        read_tiff_slices(s_, z0, nz, dst);
        const Dims& d = header_.geometry.dims;
        if (is_float(s_.type)) check_finite(dst, size_t(d[0] * d[1] * nz), d[0], d[1], z0, what);
    }

private:
    TiffStack s_;
};

}  // namespace

std::unique_ptr<SliceSource> open_raw_parts(std::vector<RawPart> parts, RawType type, bool swap,
                                            const VolumeHeader& header, const InputInfo& info) {
    return std::make_unique<RawParts>(std::move(parts), type, swap, header, info);
}

std::unique_ptr<SliceSource> open_gzip_part(std::string path, uint64_t offset, RawType type, bool swap,
                                            const VolumeHeader& header, const InputInfo& info) {
    return std::make_unique<GzipSlices>(std::move(path), offset, type, swap, header, info);
}

std::unique_ptr<SliceSource> open_slice_source(const std::vector<std::string>& inputs, const ReadOptions& opt) {
    if (opt.raw) {
        const RawLayout l = scan_raw(inputs, *opt.raw);
        std::vector<RawPart> parts;
        for (const auto& f : l.files) parts.push_back({f, opt.raw->header_bytes, l.slices_per_file});
        InputInfo info;
        info.paths = inputs;
        info.format = "raw";
        info.voxel_type = to_string(opt.raw->type);
        info.files_read = l.files.size();
        const bool swap = (opt.raw->endian == Endian::Little) != host_is_little_endian();
        return open_raw_parts(std::move(parts), opt.raw->type, swap, {l.geometry, raw_type_size(opt.raw->type)}, info);
    }
    if (inputs.empty()) return nullptr;
    if (is_tiff_input(inputs)) return std::make_unique<TiffSlices>(scan_tiff(inputs), inputs, TiffReadOptions{opt.spacing, opt.origin});
    if (opt.spacing || opt.origin || inputs.size() != 1) return nullptr;  // read_volume says why
    std::error_code ec;
    if (!fs::is_regular_file(inputs[0], ec)) return nullptr;
    if (auto s = open_metaimage_slices(inputs[0])) return s;
    return open_nrrd_slices(inputs[0]);
}

int64_t shrink_slab_slices(const Dims& input, const ShrinkParams& s, int64_t slab_voxels) {
    const int64_t f = std::max(1, s.downsample);
    const int64_t per_slice = std::max<int64_t>(1, input[0] * input[1]);
    const int64_t blocks = std::max<int64_t>(1, slab_voxels / (per_slice * f));
    const int64_t depth = s.crop ? s.crop->size()[2] : input[2];
    return std::min(blocks * f, std::max<int64_t>(depth, 1));
}

uint64_t shrink_slab_bytes(const VolumeHeader& h, const ShrinkParams& s) {
    const Dims& d = h.geometry.dims;
    const Dims c = s.crop ? s.crop->size() : d;
    const int64_t f = std::max(1, s.downsample);
    const uint64_t k = uint64_t(shrink_slab_slices(d, s));
    const uint64_t read = k * uint64_t(d[0]) * uint64_t(d[1]) * (sizeof(float) + h.stored_voxel_bytes);
    const uint64_t cropped = k * uint64_t(c[0]) * uint64_t(c[1]) * sizeof(float);
    const uint64_t averaged = (k / uint64_t(f) + 1) * uint64_t((c[0] + f - 1) / f) * uint64_t((c[1] + f - 1) / f) *
                              sizeof(float);
    return read + cropped + averaged;
}

ReadResult read_shrunk(const std::vector<std::string>& inputs, const ReadOptions& opt, const ShrinkParams& s,
                       int64_t slab_voxels) {
    std::unique_ptr<SliceSource> src = s.crop || s.downsample != 1 ? open_slice_source(inputs, opt) : nullptr;
    if (!src) {
        ReadResult r = read_volume(inputs, opt);
        r.input_grid = r.volume.geometry();
        r.volume = shrink(std::move(r.volume), s);
        return r;
    }
    const VolumeHeader& h = src->header();
    if (opt.check_header) opt.check_header(h);
    const Geometry work = shrunk_geometry(h.geometry, s);  // checks the box and the factor
    const Dims& d = h.geometry.dims;
    const CropBox box = s.crop.value_or(CropBox{{0, 0, 0}, d});
    const Dims c = box.size();
    const int64_t f = s.downsample, k = shrink_slab_slices(d, s, slab_voxels);
    ReadResult r;
    r.info = src->info();
    r.input_grid = h.geometry;
    try {
        r.volume = Volume<float>(work);
        std::vector<float> slab(size_t(k) * size_t(d[0]) * size_t(d[1]));
        for (int64_t z = box.lo[2]; z < box.hi[2]; z += k) {
            const int64_t n = std::min(k, box.hi[2] - z);
            src->read(z, n, slab.data());
            Geometry cg;
            cg.dims = {c[0], c[1], n};
            Volume<float> cropped(cg);
#pragma omp parallel for schedule(static)
            for (int64_t q = 0; q < n * c[1]; ++q) {
                const int64_t kz = q / c[1], y = q % c[1];
                const float* row = slab.data() + (size_t(kz) * size_t(d[1]) + size_t(box.lo[1] + y)) * size_t(d[0]) +
                                   size_t(box.lo[0]);
                std::copy(row, row + c[0], &cropped(0, y, kz));
            }
            const Volume<float> part = f == 1 ? std::move(cropped) : downsample(cropped, s.downsample);
            const int64_t out_z = (z - box.lo[2]) / f;
            std::copy(part.data(), part.data() + part.size(), &r.volume(0, 0, out_z));
            if (opt.slab_progress) opt.slab_progress(z + n - box.lo[2], c[2]);
        }
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(inputs.front() + ": out of memory while reading in slabs into " +
                          std::to_string(work.dims[0]) + " x " + std::to_string(work.dims[1]) + " x " +
                          std::to_string(work.dims[2]) + " voxels");
    }
    return r;
}

}  // namespace endocast
