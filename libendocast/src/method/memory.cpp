// Memory guard (memory.h): the estimate of extract's peak memory, the memory available (from
// /proc/meminfo and the cgroup) and the check of the one against the other; the peak so far.
#include "endocast/memory.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>


namespace endocast {
namespace {

/// First number in a file ("max" or unreadable: nullopt).
std::optional<uint64_t> read_number(const std::string& path) {
    std::ifstream in(path);
    uint64_t v = 0;
    if (in >> v) return v;
    return std::nullopt;
}

std::optional<uint64_t> meminfo_available() {
    std::ifstream in("/proc/meminfo");
    std::string key;
    uint64_t kb = 0;
    std::string unit;
    while (in >> key >> kb) {
        std::getline(in, unit);
        if (key == "MemAvailable:") return kb * 1024;
    }
    return std::nullopt;
}

std::string mb(uint64_t bytes) { return std::to_string((bytes + (1 << 19)) >> 20) + " MB"; }

std::string dims_text(const Dims& d) {
    return std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " + std::to_string(d[2]);
}

}  // namespace

uint64_t estimate_extract_memory_bytes(const Dims& input_dims, size_t stored_voxel_bytes,
                                       const Dims& work_dims, uint64_t slab_bytes) {
    auto voxels = [](const Dims& d) {
        long double n = 1;
        for (int64_t x : d) n *= static_cast<long double>(std::max<int64_t>(x, 0));
        return n;
    };
    const long double in = voxels(input_dims), work = voxels(work_dims);
    // Max RSS measured with /usr/bin/time -v (2 threads; docs/reliability.md, "Memory guard"):
    // the method fits 16.1 bytes per voxel + 107 MB (phantoms 192^3..320^3, cthead, the DICOM
    // head phantom); reading takes the ITK image and our copy as float (8 bytes per voxel) plus
    // the stored data. Rounded up: 18 bytes per voxel + 128 MiB, 13-18% above every measurement.
    // Closing a handle (close_handles: its growth arrays, beside the distance kept over the
    // openings' sub-volume) adds ~5 bytes per voxel: the dry skull (36.7 M voxels) peaked at
    // 922 MB, above 18 bytes per voxel: 22.
    const long double kConstant = 128.0L * (1 << 20);
    // In slabs: the result as float and one slab (its bytes as read, cropped and averaged).
    const long double read = slab_bytes > 0 ? work * 4.0L + static_cast<long double>(slab_bytes)
                                            : in * (8.0L + static_cast<long double>(stored_voxel_bytes));
    const long double shrink = slab_bytes == 0 && work != in ? in * 4.0L + work * 4.0L : 0.0L;
    const long double method = work * 22.0L;
    const long double need = kConstant + std::max({read, shrink, method});
    if (need >= 1.8e19L) return UINT64_MAX;
    return static_cast<uint64_t>(need);
}

double peak_memory_mb() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("VmHWM:", 0) == 0) {
            std::istringstream s(line.substr(6));
            double kb = 0;
            s >> kb;
            return kb / 1024.0;
        }
    }
    return 0;
}


MemoryLimit available_memory() {
    MemoryLimit m;
    if (auto a = meminfo_available()) m = {*a, "MemAvailable in /proc/meminfo"};
    const struct {
        const char *limit, *usage, *name;
    } cgroups[] = {{"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current",
                    "the cgroup limit /sys/fs/cgroup/memory.max"},
                   {"/sys/fs/cgroup/memory/memory.limit_in_bytes",
                    "/sys/fs/cgroup/memory/memory.usage_in_bytes",
                    "the cgroup limit memory.limit_in_bytes"}};
    for (const auto& c : cgroups) {
        const auto limit = read_number(c.limit);
        if (!limit || *limit >= (uint64_t{1} << 60)) continue;  // "max" or v1's "unlimited"
        const uint64_t used = read_number(c.usage).value_or(0);
        const uint64_t left = *limit > used ? *limit - used : 0;
        if (m.bytes == 0 || left < m.bytes) m = {left, c.name};
        break;
    }
    return m;
}

void check_extract_memory(const VolumeHeader& header, const ShrinkParams& s,
                          std::optional<double> max_memory_mb, const std::string& what) {
    const Geometry work = shrunk_geometry(header.geometry, s);
    const bool shrinks = work.dims != header.geometry.dims;
    const bool slabs = header.read_in_slabs && shrinks;
    const uint64_t need = estimate_extract_memory_bytes(header.geometry.dims, header.stored_voxel_bytes, work.dims,
                                                        slabs ? shrink_slab_bytes(header, s) : 0);
    MemoryLimit limit = available_memory();
    if (max_memory_mb) {
        if (!(*max_memory_mb > 0) || !std::isfinite(*max_memory_mb))
            throw InvalidParameter("--max-memory " + std::to_string(*max_memory_mb) +
                                   ", expected a number of MB > 0");
        const auto cap = static_cast<uint64_t>(*max_memory_mb * double(1 << 20));
        if (limit.bytes == 0 || cap < limit.bytes) limit = {cap, "--max-memory"};
    }
    if (limit.bytes == 0 || need <= limit.bytes) return;
    std::ostringstream m;
    m << what << ": extracting from " << dims_text(header.geometry.dims) << " voxels";
    if (shrinks) m << " (" << dims_text(work.dims) << " after crop/downsample)";
    m << (slabs ? ", reading it in slabs of " + std::to_string(shrink_slab_slices(header.geometry.dims, s)) +
                      " slices and shrinking each as it is read,"
                : std::string(", reading the whole volume first,"));
    m << " needs about " << mb(need) << " of memory (estimate), more than the " << mb(limit.bytes)
      << " allowed by " << limit.source
      << "; use --crop X0 Y0 Z0 X1 Y1 Z1 to keep only the head, or --downsample 2 (1/8 of the voxels)";
    if (shrinks && !header.read_in_slabs)
        m << "; this input is read whole before it is shrunk (a TIFF stack, raw data or a NRRD with raw or gzip "
             "data would be read in slabs)";
    throw OutOfMemory(m.str());
}

}  // namespace endocast
