#pragma once
// endocast: the braincase cavity (endocast) of a skull CT as a closed, oriented triangle surface in
// the scan's world coordinates (mm, LPS), and its volume (Michikawa et al. 2017, PLoS ONE 12(4)
// e0168516). One call, extract(), runs the whole method as `endocast extract` does: reading, the
// memory plan and guard, the whole-grid or coarse-to-fine path, the surface, its checks and bone
// contact. The stages' own headers (pipeline.h and those it includes) are for those who compose
// stages.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "endocast/errors.h"    // IoError, InvalidParameter, NoResult, OutOfMemory
#include "endocast/io.h"        // ReadOptions, InputInfo, read_volume, write_volume
#include "endocast/pipeline.h"  // ExtractParams, ExtractionResult
#include "endocast/volume.h"    // Volume, Geometry
#include "meshpost/mesh.h"
#include "meshpost/topology.h"

namespace endocast {

/// Peak resident memory of this process so far (MB, from /proc/self/status VmHWM; 0 if unknown).
double peak_memory_mb();

/// A memory limit and where it comes from (for messages).
struct MemoryLimit {
    uint64_t bytes = 0;   ///< 0 = unknown
    std::string source;   ///< e.g. "MemAvailable in /proc/meminfo"
};

/// The memory this process can still use: the smaller of MemAvailable (/proc/meminfo) and, when a
/// cgroup v2 limit is set, /sys/fs/cgroup/memory.max minus memory.current (cgroup v1:
/// memory/memory.limit_in_bytes minus memory.usage_in_bytes). bytes = 0 when none is readable.
MemoryLimit available_memory();

/// The ways `extract` runs the method.
enum class ExtractPath {
    WholeGrid,     ///< on the work grid (the input, or what --crop/--downsample make of it)
    CoarseToFine,  ///< on the input block-averaged by a factor, then refined on the input's grid (refine.h)
};

/// "whole-grid" or "coarse-to-fine" (the report's `path`).
const char* to_string(ExtractPath p);

/// The path `extract` takes, and why.
struct ExtractPlan {
    ExtractPath path = ExtractPath::WholeGrid;
    int factor = 1;              ///< CoarseToFine: the coarse grid's block-average factor
    uint64_t estimate_bytes = 0; ///< peak memory estimated for that path
    uint64_t whole_grid_bytes = 0;  ///< the whole-grid path's estimate
    MemoryLimit limit;           ///< what it was checked against
    std::string reason;          ///< one line for the log and the report
};

/// What to extract from: path(s) as read_volume takes them (a NRRD/NIfTI/MetaImage file, a DICOM
/// folder, a TIFF stack or slice pattern, raw files with Options::read.raw), or a CT in memory
/// (scan units, e.g. HU; `volume16` for integer data: half the memory). Exactly one is set.
struct Source {
    std::vector<std::string> paths;
    const Volume<float>* volume = nullptr;
    const Volume<int16_t>* volume16 = nullptr;
    std::string name = "volume";  ///< names an in-memory CT in messages
};

/// Everything a run takes. Lengths in mm, isovalue in scan units; defaults are the method's.
struct Options {
    ExtractParams method;                ///< the method's parameters (pipeline.h); isovalue unset = automatic
    ReadOptions read;                    ///< DICOM series, raw layout, TIFF spacing (io.h)
    std::optional<CropBox> crop;         ///< voxel box [lo, hi) of the input, applied first
    int downsample = 1;                  ///< block-average factor in [1, 64], after the crop
    int refine = 0;                      ///< coarse-to-fine factor in [2, 64]; 0 = only when the grid does not fit
    int64_t refine_slab = 64;            ///< planes of the input per slab on the coarse-to-fine path
    std::optional<double> max_memory_mb; ///< the memory guard's limit; empty = the available memory
    bool keep_ct = false;                ///< keep the CT the method ran on in Result (for pictures)
    /// The self-intersection check (meshpost/cgal: GPL, so not linked here): given the mesh and the
    /// faces to test (null: all), the number of intersecting pairs. Empty: not checked (-1).
    std::function<size_t(const meshpost::TriangleMesh&, const std::vector<uint8_t>* subject)> self_intersections;
    bool check_all_faces = false;        ///< test every face, not only those moved after marching cubes
    /// Called with the final mesh on a thread of its own while it is checked (e.g. to write it).
    std::function<void(const meshpost::TriangleMesh&)> beside_check;
};

/// Progress of a run: the path chosen (before anything is read), each stage as it starts ("read",
/// "binarize", ..., "refine", "check") and lines worth a log. Any may throw to stop the run (the
/// exception propagates).
class Progress {
public:
    virtual ~Progress() = default;
    virtual void planned(const ExtractPlan& /*plan*/) {}
    virtual void stage(const std::string& /*name*/) {}
    virtual void info(const std::string& /*line*/) {}
};

/// The coarse-to-fine path's refinement (refine.h), when it ran.
struct Refinement {
    int factor = 1;
    Geometry coarse_grid;
    double coarse_ecv_ml = 0;
    CropBox box;
    int64_t slabs = 0, band_voxels = 0, band_endocast_voxels = 0, changed_voxels = 0;
    int64_t clipped_voxels = 0, pieces_removed = 0;
};

/// A run's result: the method's (mesh in world mm, mask, ECV, bone contact, warnings, ...) and
/// what the run read, planned and checked.
struct Result {
    ExtractionResult method;
    std::vector<std::string> paths;   ///< the input (Source::name for a CT in memory)
    InputInfo input;
    Geometry input_grid;              ///< the input's grid, before crop and downsample
    Geometry mesh_grid;               ///< the grid the mesh is on
    ExtractPlan plan;
    std::optional<Refinement> refinement;
    meshpost::TopologyReport topology;
    int64_t self_intersections = -1;  ///< -1: not checked
    size_t faces_tested = 0;
    std::string ct_storage;           ///< "int16" or "float32"
    Volume<float> ct;                 ///< Options::keep_ct: the CT the method ran on (float) ...
    Volume<int16_t> ct16;             ///< ... or as int16
    double read_s = 0, refine_s = 0, check_s = 0;

    const meshpost::TriangleMesh& mesh() const { return method.mesh; }
    double ecv_ml() const { return method.ecv_ml; }
    bool closed_manifold() const { return meshpost::is_closed_manifold(topology); }
};

/// Runs the whole method on `source`. Throws IoError (unreadable input), InvalidParameter (an
/// option out of range or inconsistent with the input), OutOfMemory (the plan does not fit) or
/// NoResult (no cavity enclosed by bone), each naming the input.
Result extract(const Source& source, const Options& options = {}, Progress* progress = nullptr);

}  // namespace endocast
