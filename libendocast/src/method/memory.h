#pragma once
// Memory guard of `extract`: how much memory is there, and does the work fit? Checked from the
// header, before the voxels are read, so a scan too big for the machine stops with a clear message
// instead of being killed or failing half-way (std::bad_alloc).
#include <cstdint>
#include <optional>
#include <string>

#include "endocast/endocast.h"
#include "endocast/io.h"
#include "endocast/stages/resample.h"
#include "io/slice_source.h"
#include "endocast/volume.h"

namespace endocast {

/// Estimated peak resident memory (bytes) of `endocast extract`: reading a volume of `input_dims`
/// voxels stored with `stored_voxel_bytes` bytes each (as float, plus ITK's buffer), shrinking it
/// to `work_dims` (crop/downsample; equal to input_dims when not shrunk) and running the method on
/// that grid. Fitted to measured peaks (max RSS, see docs/reliability.md "Memory guard"):
/// READ_BYTES_PER_VOXEL x input voxels while reading, WORK_BYTES_PER_VOXEL x work voxels while
/// extracting, plus a constant, with a margin. Saturates instead of overflowing.
/// `slab_bytes` > 0: the input is read in slabs (read_shrunk, slice_source.h) holding this many
/// bytes besides the result (shrink_slab_bytes), so the whole input is never held.
uint64_t estimate_extract_memory_bytes(const Dims& input_dims, size_t stored_voxel_bytes,
                                       const Dims& work_dims, uint64_t slab_bytes = 0);

/// Throws OutOfMemory when estimate_extract_memory_bytes for this header and
/// shrinking (read in slabs when header.read_in_slabs, else whole) exceeds the smaller of available_memory() and `max_memory_mb` (when set, MB = 2^20
/// bytes). The message names `what` (the input), the grid, the estimate, the limit and its source,
/// and the way the input is read, and suggests --crop / --downsample (and, for an input read
/// whole, a format read in slabs). Also throws InvalidParameter for a crop box that does not
/// fit the declared size.
void check_extract_memory(const VolumeHeader& header, const ShrinkParams& s,
                          std::optional<double> max_memory_mb, const std::string& what);

/// Coarse grids the automatic coarse-to-fine path aims at: at most this many voxels (the smallest
/// factor >= 2 that gets there, and fits in memory).
constexpr int64_t kCoarseGridMaxVoxels = int64_t(1) << 27;

/// Estimated peak resident memory (bytes) of the coarse-to-fine path on `header` (read in slabs)
/// cropped by `crop` (may be empty): the larger of the coarse run (estimate_extract_memory_bytes on
/// the grid downsampled by `factor`, read in slabs) and the fine pass: the coarse CT, labels, mask
/// and classes kept (10 bytes per coarse voxel), a plane of the input as float, the field of a slab
/// of `slab_planes` planes of the crop box (4 bytes per voxel), and the fine mesh with its checks
/// (250 bytes per face) of `fine_faces` faces (0: estimated as the surface of a sphere holding an
/// eighth of the crop box, 9 faces per square of the smallest spacing, as measured), plus 128 MiB.
uint64_t estimate_refine_memory_bytes(const VolumeHeader& header, const std::optional<CropBox>& crop, int factor,
                                      int64_t slab_planes, uint64_t fine_faces = 0);

/// Chooses the path for `header` and checks that it fits in memory. `refine` >= 2: the
/// coarse-to-fine path with that factor (InvalidParameter unless the header is read in slabs and
/// nothing is downsampled; OutOfMemory when it does not fit). `refine` 0: the whole-grid path
/// when it fits (or anything is downsampled: check_extract_memory's checks and message); else,
/// for an input read in slabs, the coarse-to-fine path with the smallest factor >= 2 whose grid
/// holds at most kCoarseGridMaxVoxels and whose estimate fits; else OutOfMemory as
/// check_extract_memory. `slab_planes`: the fine pass's slab. Throws InvalidParameter for a bad
/// --max-memory, --refine or crop box.
ExtractPlan plan_extract(const VolumeHeader& header, const ShrinkParams& s, int refine, int64_t slab_planes,
                         std::optional<double> max_memory_mb, const std::string& what);

}  // namespace endocast
