// libFuzzer target for our TIFF reader (libendocast/src/io/tiff_io.cpp, endocast::read_tiff): the
// input is the content of one .tif file (one or several pages), read with a given spacing; volumes
// over 2^20 voxels are refused by the header check before they are allocated (as the CLI's memory
// guard does), so that every run stays small. endocast::Error (IoError, InvalidParameter,
// OutOfMemory) is the expected rejection; anything else is a finding.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "endocast/errors.h"
#include "endocast/tiff.h"

namespace {

const std::string& path() {
    static const std::string p = [] {
        const char* dir = std::getenv("TMPDIR");
        std::string t = std::string(dir && *dir ? dir : "/tmp") + "/endocast-fuzz-tiff-XXXXXX";
        const int fd = ::mkstemp(t.data());
        if (fd < 0) {
            std::perror("mkstemp");
            std::abort();
        }
        ::close(fd);
        ::unlink(t.c_str());
        t += ".tif";  // read as TIFF by its name
        std::atexit([] { ::unlink(path().c_str()); });
        return t;
    }();
    return p;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::FILE* f = std::fopen(path().c_str(), "wb");
    if (!f) {
        std::perror("fopen");
        std::abort();
    }
    if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
    try {
        endocast::TiffReadOptions o;
        o.spacing = endocast::Vec3{1, 1, 1};
        const endocast::ReadResult r = endocast::read_tiff({path()}, o, [](const endocast::VolumeHeader& h) {
            if (h.geometry.voxel_count() > (uint64_t{1} << 20)) throw endocast::InvalidParameter("too large");
        });
        for (float v : r.volume.buffer())
            if (!std::isfinite(v)) {
                std::fprintf(stderr, "finding: non-finite voxel accepted\n");
                std::abort();
            }
    } catch (const endocast::Error&) {
        return 0;
    }
    return 0;
}
