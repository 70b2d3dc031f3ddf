// Memory guard (memory.h): the estimate of extract's peak memory, the memory available (from
// /proc/meminfo and the cgroup) and the check of the one against the other; the peak so far.
#include "memory.h"

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

namespace {

MemoryLimit memory_limit(std::optional<double> max_memory_mb) {
    MemoryLimit limit = available_memory();
    if (max_memory_mb) {
        if (!(*max_memory_mb > 0) || !std::isfinite(*max_memory_mb))
            throw InvalidParameter("--max-memory " + std::to_string(*max_memory_mb) +
                                   ", expected a number of MB > 0");
        const auto cap = static_cast<uint64_t>(*max_memory_mb * double(1 << 20));
        if (limit.bytes == 0 || cap < limit.bytes) limit = {cap, "--max-memory"};
    }
    return limit;
}

uint64_t whole_grid_estimate(const VolumeHeader& header, const ShrinkParams& s) {
    const Geometry work = shrunk_geometry(header.geometry, s);
    const bool shrinks = work.dims != header.geometry.dims;
    const bool slabs = header.read_in_slabs && shrinks;
    return estimate_extract_memory_bytes(header.geometry.dims, header.stored_voxel_bytes, work.dims,
                                         slabs ? shrink_slab_bytes(header, s) : 0);
}

}  // namespace

const char* to_string(ExtractPath p) { return p == ExtractPath::CoarseToFine ? "coarse-to-fine" : "whole-grid"; }

uint64_t estimate_refine_memory_bytes(const VolumeHeader& header, const std::optional<CropBox>& crop, int factor,
                                      int64_t slab_planes, uint64_t fine_faces) {
    ShrinkParams s;
    s.crop = crop;
    s.downsample = factor;
    const Geometry coarse = shrunk_geometry(header.geometry, s);
    const Geometry fine = shrunk_geometry(header.geometry, {crop, 1});
    const long double coarse_run = static_cast<long double>(estimate_extract_memory_bytes(
        header.geometry.dims, header.stored_voxel_bytes, coarse.dims, shrink_slab_bytes(header, s)));
    const Dims& c = coarse.dims;
    const Dims& f = fine.dims;
    const long double coarse_kept = 10.0L * c[0] * c[1] * c[2];
    const long double plane = 4.0L * header.geometry.dims[0] * header.geometry.dims[1];
    const long double field = 4.0L * f[0] * f[1] * (std::min<int64_t>(slab_planes, f[2]) + 1);
    long double faces = static_cast<long double>(fine_faces);
    if (fine_faces == 0) {
        const long double box = (long double)(f[0] * fine.spacing[0]) * (f[1] * fine.spacing[1]) * (f[2] * fine.spacing[2]);
        const long double radius = std::cbrt(box / 8.0L * 3.0L / (4.0L * M_PI));
        const long double s2 = fine.smallest_spacing() * fine.smallest_spacing();
        faces = 9.0L * 4.0L * M_PI * radius * radius / s2;
    }
    const long double fine_pass = 128.0L * (1 << 20) + coarse_kept + plane + field + 250.0L * faces;
    const long double need = std::max(coarse_run, fine_pass);
    if (need >= 1.8e19L) return UINT64_MAX;
    return static_cast<uint64_t>(need);
}

ExtractPlan plan_extract(const VolumeHeader& header, const ShrinkParams& s, int refine, int64_t slab_planes,
                         std::optional<double> max_memory_mb, const std::string& what) {
    if (refine < 0 || refine == 1)
        throw InvalidParameter("--refine " + std::to_string(refine) + ", expected 0 (automatic) or a factor >= 2");
    ExtractPlan plan;
    plan.limit = memory_limit(max_memory_mb);
    plan.whole_grid_bytes = whole_grid_estimate(header, s);  // checks the crop box and the factor
    const bool fits = plan.limit.bytes == 0 || plan.whole_grid_bytes <= plan.limit.bytes;
    if (refine == 0 && (fits || s.downsample != 1 || !header.read_in_slabs)) {
        check_extract_memory(header, s, max_memory_mb, what);
        plan.estimate_bytes = plan.whole_grid_bytes;
        plan.reason = "the method runs on the work grid (estimated " + mb(plan.estimate_bytes) + ")";
        return plan;
    }
    if (refine >= 2) {
        if (s.downsample != 1)
            throw InvalidParameter("--refine " + std::to_string(refine) +
                                   " with --downsample: the coarse-to-fine path meshes the input's own grid; "
                                   "give one of them");
        if (!header.read_in_slabs)
            throw InvalidParameter(what + ": --refine needs an input read in slabs (a TIFF stack, raw data, or a NRRD "
                                          "with raw or gzip data); convert it to one of these");
    }
    plan.path = ExtractPath::CoarseToFine;
    const Geometry fine = shrunk_geometry(header.geometry, {s.crop, 1});
    // The smallest factor >= 2 whose grid holds at most kCoarseGridMaxVoxels (automatic choice).
    const long double fine_voxels = (long double)fine.dims[0] * fine.dims[1] * fine.dims[2];
    int smallest = 2;
    while (smallest < 64 && fine_voxels / ((long double)smallest * smallest * smallest) > (long double)kCoarseGridMaxVoxels)
        ++smallest;
    for (int f = refine >= 2 ? refine : smallest; f <= (refine >= 2 ? refine : 64); ++f) {
        const uint64_t need = estimate_refine_memory_bytes(header, s.crop, f, slab_planes);
        if (plan.limit.bytes != 0 && need > plan.limit.bytes) {
            if (refine >= 2) {
                std::ostringstream m;
                m << what << ": the coarse-to-fine path with --refine " << refine << " on "
                  << dims_text(fine.dims) << " voxels needs about " << mb(need) << " of memory (estimate), more than the "
                  << mb(plan.limit.bytes) << " allowed by " << plan.limit.source
                  << "; use a larger --refine factor, or --crop X0 Y0 Z0 X1 Y1 Z1 to keep only the head";
                throw OutOfMemory(m.str());
            }
            continue;
        }
        plan.factor = f;
        plan.estimate_bytes = need;
        std::ostringstream m;
        m << "coarse-to-fine: the method on the grid block-averaged by " << f << ", then the band around its cavity "
          << "re-decided and meshed on the " << dims_text(fine.dims) << " grid in slabs (estimated " << mb(need) << "; ";
        if (refine >= 2) m << "--refine " << refine << ")";
        else m << "the whole grid would need about " << mb(plan.whole_grid_bytes) << ", more than the " << mb(plan.limit.bytes)
               << " allowed by " << plan.limit.source << ")";
        plan.reason = m.str();
        return plan;
    }
    // Nothing fits: check_extract_memory's message, and what the coarse-to-fine path would need.
    try {
        check_extract_memory(header, s, max_memory_mb, what);
    } catch (const OutOfMemory& e) {
        throw OutOfMemory(std::string(e.what()) + "; the coarse-to-fine path (--refine " + std::to_string(smallest) +
                          ") would need about " + mb(estimate_refine_memory_bytes(header, s.crop, smallest, slab_planes)));
    }
    return plan;
}

void check_extract_memory(const VolumeHeader& header, const ShrinkParams& s,
                          std::optional<double> max_memory_mb, const std::string& what) {
    const Geometry work = shrunk_geometry(header.geometry, s);
    const bool shrinks = work.dims != header.geometry.dims;
    const bool slabs = header.read_in_slabs && shrinks;
    const uint64_t need = whole_grid_estimate(header, s);
    const MemoryLimit limit = memory_limit(max_memory_mb);
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
