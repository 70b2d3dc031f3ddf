// libFuzzer target for the readers of io.cpp (endocast::read_volume): ITK's for NRRD and NIfTI
// headers, ours for MetaImage (metaimage_header.cpp; ITK's MetaIO is no longer reached):
// built as fuzz_nrrd (.nrrd), fuzz_nifti (.nii) and fuzz_mhd (.mha), the extension compiled in as
// FUZZ_ITK_EXT. The input is written to <dir>/input<ext> in one temporary directory per process
// (libFuzzer runs the inputs one after another in one process, so the name is reused), beside a
// fixed 4096-byte data file "data.raw", so that headers with a detached data file ("data file:
// data.raw" in NRRD, "ElementDataFile = data.raw" in MetaImage) are exercised as well.
// A check_header hook refuses more than 2^24 voxels: a valid header may declare a huge volume,
// which read_volume would rightly try to allocate (the fuzzer runs with -rss_limit_mb=2048).
// endocast::Error (IoError, InvalidParameter, OutOfMemory) is the expected rejection; any other
// exception, crash, leak or sanitizer report is a finding. ITK itself is not instrumented: the
// coverage guidance comes from our code only, but crashes inside ITK are caught all the same.
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "endocast/errors.h"
#include "endocast/io.h"
#include "endocast/stages/resample.h"
#include "io/slice_source.h"

#ifndef FUZZ_ITK_EXT
#error "FUZZ_ITK_EXT must be defined (\".nrrd\", \".nii\", \".mha\")"
#endif

namespace {

namespace fs = std::filesystem;

constexpr int64_t kMaxFuzzVoxels = int64_t{1} << 24;

void write_file(const fs::path& p, const void* data, size_t size) {
    std::FILE* f = std::fopen(p.c_str(), "wb");
    if (!f) {
        std::perror(p.c_str());
        std::abort();
    }
    if (size && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
}

/// The per-process directory, created once with its data.raw, removed at exit. Held by a pointer
/// that is never freed: the atexit handler is registered while it is made, so a static path would
/// be destroyed before the handler ran (valgrind: a read of the freed path, at exit).
const fs::path& dir() {
    static const fs::path* d = new fs::path([] {
        const char* tmp = std::getenv("TMPDIR");
        fs::path p = fs::path(tmp && *tmp ? tmp : "/tmp") /
                     ("endocast_fuzz_" + std::to_string(::getpid()));
        // libFuzzer ends with _Exit() on a finding or a time limit, so the atexit cleanup below
        // does not always run: remove the directories of fuzz processes that are gone.
        std::error_code ec;
        for (const auto& e : fs::directory_iterator(p.parent_path(), ec)) {
            const std::string n = e.path().filename().string();
            const std::string prefix = "endocast_fuzz_";
            if (n.rfind(prefix, 0) != 0 || n.size() == prefix.size() ||
                n.find_first_not_of("0123456789", prefix.size()) != std::string::npos)
                continue;
            const long pid = std::atol(n.c_str() + prefix.size());
            if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)
                fs::remove_all(e.path(), ec);
        }
        fs::create_directories(p);
        unsigned char raw[4096];
        for (size_t i = 0; i < sizeof raw; ++i) raw[i] = static_cast<unsigned char>(i * 7);
        write_file(p / "data.raw", raw, sizeof raw);
        std::atexit([] {
            std::error_code ec;
            fs::remove_all(dir(), ec);
        });
        return p;
    }());
    return *d;
}

}  // namespace

// Known leaks inside ITK 5.2 (Debian's libinsighttoolkit5), on its own error paths while reading
// the voxels, after the header was accepted (docs/reliability.md, "Fuzzing"). A few hundred bytes
// per failed read, in a program that reads one volume: documented and suppressed here, by the ITK
// function that leaks, so that any other leak is still a finding.
//  - itk::NrrdImageIO::Read does not free the nrrd struct and the biff error message when teem's
//    nrrdLoad fails (e.g. a non-number in ASCII-encoded data).
//  - MetaImage::Read (and MetaImage::ReadStream, which it calls) leaks when the data cannot be
//    read (e.g. ElementDataFile naming a file that does not exist) or when it throws
//    std::length_error (regress_length_error.mha). The template matches both names.
extern "C" const char* __lsan_default_suppressions() {
    return "leak:itk::NrrdImageIO::Read\n"
           "leak:MetaImage::Read\n";
}
// ITK is built without frame pointers: the fast unwinder stops at its first frame, and the
// suppressions above need the whole allocation stack.
extern "C" const char* __asan_default_options() { return "fast_unwind_on_malloc=0"; }

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const fs::path path = dir() / ("input" FUZZ_ITK_EXT);
    write_file(path, data, size);

    endocast::ReadOptions opt;
    opt.check_header = [](const endocast::VolumeHeader& h) {
        const auto& d = h.geometry.dims;
        if (d[0] * d[1] * d[2] > kMaxFuzzVoxels)  // read_volume checked each > 0, product < 2^40
            throw endocast::InvalidParameter("fuzz: more than 2^24 voxels");
    };
    static const bool verbose = std::getenv("FUZZ_VERBOSE") != nullptr;  // for triage and seeds
    try {
        const endocast::ReadResult r = endocast::read_volume({path.string()}, opt);
        if (verbose)
            std::fprintf(stderr, "read: %lld x %lld x %lld %s\n",
                         static_cast<long long>(r.volume.dims()[0]),
                         static_cast<long long>(r.volume.dims()[1]),
                         static_cast<long long>(r.volume.dims()[2]), r.info.voxel_type.c_str());
        // Guarantees of read_volume (io.h, to_volume): a non-empty volume of finite values.
        if (r.volume.empty()) std::abort();
        for (float v : r.volume.buffer())
            if (!std::isfinite(v)) {
                std::fprintf(stderr, "finding: non-finite voxel accepted\n");
                std::abort();
            }
        // Read in slabs (raw NRRD) and downsampled on the way: the voxels of the whole read,
        // downsampled (slice_source.h). Slabs of one block, so that several are read.
        endocast::ShrinkParams s;
        s.downsample = 2;
        const endocast::ReadResult slabs = endocast::read_shrunk({path.string()}, opt, s, 1);
        const endocast::Volume<float> want = endocast::shrink(r.volume, s);
        if (slabs.volume.dims() != want.dims() ||
            !std::equal(want.buffer().begin(), want.buffer().end(), slabs.volume.buffer().begin())) {
            std::fprintf(stderr, "finding: read in slabs (%s) differs from the whole read downsampled\n",
                         slabs.info.read_path.c_str());
            std::abort();
        }
    } catch (const endocast::Error& e) {
        if (verbose) std::fprintf(stderr, "rejected: %s\n", e.what());
        return 0;  // rejected input: expected
    }
    return 0;
}
