#pragma once
// Reading a volume a slab of slices at a time, so that a scan larger than memory (microCT: 2048 x
// 2048 x 1500 uint16 is 12.6 GB stored, 25 GB as float) can be cropped and downsampled while it is
// read, and is never held whole. read_shrunk is what `extract --crop/--downsample` calls.
//
// Inputs read in slabs: TIFF (a folder, pattern or multi-page file; tiff.h), headerless raw data
// (one file or slice files), and NRRD whose data is raw or gzip (inflated in order with zlib, one
// thread) in the file itself or in one detached data file, with perpendicular axes. Every other
// input (NIfTI, MetaImage, DICOM) is read whole and then shrunk, as before.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "endocast/io.h"
#include "endocast/stages/resample.h"
#include "endocast/volume.h"

namespace endocast {

/// A volume on disk whose slices are read on demand.
class SliceSource {
public:
    virtual ~SliceSource() = default;
    /// The geometry and stored voxel size (header().read_in_slabs is true).
    const VolumeHeader& header() const { return header_; }
    /// What a whole read would report (format, voxel type, files, the TIFF's spacing source and
    /// warnings); read_path "slabs".
    const InputInfo& info() const { return info_; }
    /// Reads slices [z0, z0 + nz) into dst (dims[0] * dims[1] * nz floats, x fastest) in the
    /// scan's units. Throws IoError (short read, undecodable slice) or InvalidParameter (NaN/Inf
    /// in float data, or a range outside the volume).
    virtual void read(int64_t z0, int64_t nz, float* dst) = 0;

protected:
    VolumeHeader header_;
    InputInfo info_;
};

/// A SliceSource for `inputs` when they can be read in slabs (see the top of this file), else
/// nullptr (read_volume reads them). Reads only headers; throws what read_volume throws for a
/// bad header or bad options (IoError, InvalidParameter).
std::unique_ptr<SliceSource> open_slice_source(const std::vector<std::string>& inputs,
                                               const ReadOptions& opt = {});

/// Voxels read_shrunk reads at a time by default: 64 M (256 MB as float).
constexpr int64_t kShrinkSlabVoxels = int64_t(1) << 26;

/// Slices read at a time by read_shrunk for a volume of `input` voxels shrunk as `s` says: a
/// multiple of the downsample factor holding about `slab_voxels` voxels, but at least one block of
/// factor slices, and never more than the crop box's (or the volume's) depth.
int64_t shrink_slab_slices(const Dims& input, const ShrinkParams& s, int64_t slab_voxels = kShrinkSlabVoxels);

/// The bytes read_shrunk holds besides its result while it reads `input` in slabs: the slab as read
/// (stored and as float), the slab cropped, and its block average (as float).
uint64_t shrink_slab_bytes(const VolumeHeader& input, const ShrinkParams& s);

/// Reads `inputs` (as read_volume) cropped, then downsampled, as `s` says: the same voxels and
/// geometry as shrink(read_volume(inputs, opt).volume, s). When `s` shrinks and the input can be
/// read in slabs (open_slice_source), it is read a slab of shrink_slab_slices at a time, the crop
/// box's slices only, so memory holds the result and one slab (opt.check_header then gets
/// read_in_slabs = true, and info.read_path is "slabs"); otherwise the whole volume is read first
/// (read_path "whole"). opt.slab_progress, when set, is called after each slab. `slab_voxels`:
/// see shrink_slab_slices (tests make it small to read many slabs).
ReadResult read_shrunk(const std::vector<std::string>& inputs, const ReadOptions& opt,
                       const ShrinkParams& s, int64_t slab_voxels = kShrinkSlabVoxels);

}  // namespace endocast
