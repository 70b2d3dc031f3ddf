// libFuzzer target for the direct DICOM pixel reader (libendocast/src/io/dicom_direct.cpp,
// endocast::read_dicom_pixels): the input is one slice file. It is read as a 5 x 6 slice (the
// seeds' size) and as the size its own Rows/Columns would give if they were 1..64 (first two
// bytes), so that both the rejections and the conversion are reached. The reader must only accept
// or decline: no read outside the file, no write outside the slice, no crash.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "../../libendocast/src/io/io_internal.h"

namespace {

const std::string& path() {
    static const std::string p = [] {
        const char* dir = std::getenv("TMPDIR");
        std::string t = std::string(dir && *dir ? dir : "/tmp") + "/endocast-fuzz-dicom-XXXXXX";
        const int fd = ::mkstemp(t.data());
        if (fd < 0) {
            std::perror("mkstemp");
            std::abort();
        }
        ::close(fd);
        std::atexit([] { ::unlink(path().c_str()); });
        return t;
    }();
    return p;
}

void read_as(int64_t nx, int64_t ny) {
    std::vector<float> out(size_t(nx * ny));
    const auto positions = endocast::read_dicom_pixels({path()}, nx, ny, out.data());
    if (positions && positions->size() > 1) std::abort();  // one slice, at most one position
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::FILE* f = std::fopen(path().c_str(), "wb");
    if (!f) std::abort();
    if (size && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
    read_as(5, 6);
    if (size >= 2) read_as(1 + data[0] % 64, 1 + data[1] % 64);
    return 0;
}
