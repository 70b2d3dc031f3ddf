#pragma once
// Making a volume smaller before extraction: cropping to a box of voxels and block-averaging by an
// integer factor. Both keep the world placement: a voxel of the result sits at the same world
// position (mm) as the voxels of the input it came from, so a mesh extracted from the smaller
// volume overlays the original scan.
#include <cstdint>
#include <optional>
#include <string>

#include "endocast/volume.h"

namespace endocast {

/// A box of voxel indices, inclusive-exclusive: lo[a] <= i < hi[a] along each axis a.
struct CropBox {
    Dims lo{0, 0, 0};
    Dims hi{0, 0, 0};

    Dims size() const { return {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}; }
};

/// "X0 Y0 Z0 X1 Y1 Z1" for messages and reports.
std::string to_string(const CropBox& b);

/// Throws InvalidParameter unless 0 <= lo < hi <= dims on every axis (the message names the box
/// and the volume size).
void check_crop_box(const CropBox& box, const Dims& dims);

/// Grid of `g` cropped to `box` (checked): dims = box size, origin = world position of voxel lo;
/// spacing and direction unchanged.
Geometry cropped_geometry(const Geometry& g, const CropBox& box);

/// Grid of `g` reduced by `factor` (>= 1): dims = ceil(dims / factor), spacing x factor, origin =
/// the centre of the first block (index (factor-1)/2 of the input on each axis, through the
/// direction matrix). Throws InvalidParameter for factor < 1.
Geometry downsampled_geometry(const Geometry& g, int factor);

/// The voxels of `box` (checked with check_crop_box), geometry from cropped_geometry.
template <class T>
Volume<T> crop(const Volume<T>& v, const CropBox& box);  // T: float, int16_t or uint8_t

/// The inverse of crop: a volume of grid `whole` holding `part` in `box` (part's dims = box size)
/// and `fill` elsewhere. Throws InvalidParameter when the box does not fit `whole` or `part`.
Volume<uint8_t> uncrop(const Volume<uint8_t>& part, const Geometry& whole, const CropBox& box, uint8_t fill);

/// Block average: each output voxel is the mean of a factor^3 block of input voxels. Blocks at the
/// far faces that stick out of the volume (dims not divisible by factor) average the voxels they
/// hold, so their centre lies up to (factor-1)/2 input voxels nearer the volume than the output
/// grid says. factor 1 returns a copy. Throws InvalidParameter for factor < 1.
Volume<float> downsample(const Volume<float>& v, int factor);

/// Smallest box holding every voxel > threshold, grown by `margin` voxels on each side (clamped
/// to the volume). Throws NoResult when no voxel is above the threshold.
CropBox bounding_box_above(const Volume<float>& v, double threshold, int64_t margin);

/// How `extract` shrinks the volume before the method runs: crop first, then downsample.
struct ShrinkParams {
    std::optional<CropBox> crop;  ///< voxel box of the input
    int downsample = 1;           ///< block-average factor >= 1
};

/// Grid the method works on: `input` cropped then downsampled (checked; throws InvalidParameter).
Geometry shrunk_geometry(const Geometry& input, const ShrinkParams& s);

/// `v` cropped then downsampled as `s` says (moved through unchanged when s does nothing). The
/// input is released before the downsampled copy is made when both are asked for.
Volume<float> shrink(Volume<float> v, const ShrinkParams& s);

}  // namespace endocast
