// libFuzzer target for our headerless raw reader (libendocast/src/io/raw_io.cpp, endocast::read_raw).
// The first 5 bytes choose the RawOptions, the rest is the file content:
//   byte 0..2: size x, y, z = 1 + (b % 8)     (at most 512 voxels: every run stays fast)
//   byte 3   : type = b % 8 (int8 .. float64)
//   byte 4   : bit 0 endian (1 = big); bits 1..4 header_bytes (0..15); bit 5: pad/truncate the
//              content to exactly the expected size, so that the voxel conversion and the NaN/Inf
//              check are reached as well as the size checks.
// The content is written to one temporary file per process (read_raw reads files only).
// endocast::Error (IoError, InvalidParameter) is the expected rejection; anything else is a finding.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "endocast/errors.h"
#include "endocast/io.h"

namespace {

std::string temp_path() {
    const char* dir = std::getenv("TMPDIR");
    std::string t = std::string(dir && *dir ? dir : "/tmp") + "/endocast-fuzz-raw-XXXXXX";
    const int fd = ::mkstemp(t.data());
    if (fd < 0) {
        std::perror("mkstemp");
        std::abort();
    }
    ::close(fd);
    return t;
}

const std::string& path() {
    static const std::string p = [] {
        std::string t = temp_path();
        std::atexit([] { ::unlink(path().c_str()); });
        return t;
    }();
    return p;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 5) return 0;
    endocast::RawOptions o;
    o.size = {1 + data[0] % 8, 1 + data[1] % 8, 1 + data[2] % 8};
    o.type = static_cast<endocast::RawType>(data[3] % 8);
    o.endian = (data[4] & 1) ? endocast::Endian::Big : endocast::Endian::Little;
    o.header_bytes = (data[4] >> 1) & 15;
    const bool exact = (data[4] >> 5) & 1;
    std::string content(reinterpret_cast<const char*>(data + 5), size - 5);
    if (exact) {
        const size_t n = static_cast<size_t>(o.size[0] * o.size[1] * o.size[2]);
        content.resize(o.header_bytes + n * endocast::raw_type_size(o.type), '\0');
    }
    std::FILE* f = std::fopen(path().c_str(), "wb");
    if (!f) {
        std::perror("fopen");
        std::abort();
    }
    if (!content.empty() && std::fwrite(content.data(), 1, content.size(), f) != content.size()) std::abort();
    std::fclose(f);

    try {
        const endocast::ReadResult r = endocast::read_raw({path()}, o);
        // Guarantees of read_raw (io.h): the declared size, finite values.
        for (int a = 0; a < 3; ++a)
            if (r.volume.dims()[a] != o.size[a]) std::abort();
        for (float v : r.volume.buffer())
            if (!std::isfinite(v)) {
                std::fprintf(stderr, "finding: non-finite voxel accepted\n");
                std::abort();
            }
    } catch (const endocast::Error&) {
        return 0;  // rejected input: expected
    }
    return 0;
}
