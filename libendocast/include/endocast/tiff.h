#pragma once
// TIFF volumes, as microCT scanners and ImageJ/Fiji export them: a folder of 2-D slice files, the
// files a printf pattern ("slice%04d.tif") or glob pattern names, or one multi-page file; read with
// libtiff (any compression it knows, strips or tiles), one grey sample per pixel of 8, 16, 32 or
// 64 bits (unsigned, signed or float). Slices are ordered naturally by name (slice2 before
// slice10), the first slice is z = 0, a slice's first row is y = 0.
//
// A TIFF has no standard voxel size along z and no origin or direction. The voxel size comes from,
// in order: TiffReadOptions::spacing (the CLI's --spacing); ImageJ's description ("unit=mm",
// "spacing=" for z, "xorigin=" ...) with XResolution/YResolution in pixels per that unit; or
// XResolution/YResolution with ResolutionUnit centimetre or inch (z then taken equal to x, with a
// warning). Files without a resolution, or at 72 or 96 dpi (display defaults, not a scan's), need
// the spacing given. The direction is the identity.
//
// write_tiff writes a volume as TIFF with ImageJ's tags for its voxel size and origin, so that it
// reads back with the same geometry (the direction is not stored: it must be the identity).
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "endocast/io.h"
#include "endocast/volume.h"

namespace endocast {

/// A TIFF volume's layout, before its voxels are read.
struct TiffStack {
    std::vector<std::string> files;  ///< one per slice, or the one multi-page file
    bool multipage = false;          ///< true: the slices are the pages of files[0]
    Dims dims{0, 0, 0};              ///< x = columns, y = rows, z = slices (pages)
    RawType type = RawType::UInt16;  ///< the samples as stored
    std::optional<Vec3> spacing_mm;  ///< the voxel size the tags give, when they give one
    Vec3 origin_mm{0, 0, 0};         ///< ImageJ's xorigin/yorigin/zorigin in mm (else 0)
    /// Where spacing_mm comes from ("ImageJ description: unit mm, spacing 0.05"); empty when none.
    std::string spacing_source;
    std::vector<std::string> warnings;  ///< e.g. z spacing assumed equal to x
};

/// True for a name ending in .tif or .tiff (any case).
bool is_tiff_path(const std::string& path);

/// True when `inputs` are read as TIFF by read_volume: one or more .tif/.tiff files or patterns,
/// or one directory that holds .tif/.tiff files (its other files are ignored).
bool is_tiff_input(const std::vector<std::string>& inputs);

/// The layout of the TIFF volume `inputs` name (see is_tiff_input): every slice's header is read
/// and must agree with the first's (size, sample type). Throws IoError naming the file (and page)
/// and what was expected: no TIFF found, unreadable file, colour or palette images, samples that
/// are not 8/16/32/64-bit, slices of different sizes or types.
TiffStack scan_tiff(const std::vector<std::string>& inputs);

/// Reads slices [z0, z0 + nz) of `s` into dst (dims[0] * dims[1] * nz floats, x fastest), slice
/// files in parallel. Throws IoError for a slice that cannot be decoded (truncated, corrupt).
void read_tiff_slices(const TiffStack& s, int64_t z0, int64_t nz, float* dst);

struct TiffReadOptions {
    std::optional<Vec3> spacing;  ///< mm; overrides the files' resolution (required when they have none)
    std::optional<Vec3> origin;   ///< mm, world position of voxel (0,0,0); default ImageJ's origin or 0
};

/// Reads a TIFF volume whole (scan_tiff, then read_tiff_slices), as read_volume does for TIFF
/// input; `check_header` is called before the voxels are allocated. Throws as scan_tiff, and
/// InvalidParameter when no voxel size is known (none given, none in the files) or the spacing
/// is not finite and > 0, or float samples are NaN/Inf. info.spacing_source says where the voxel
/// size came from; info.warnings what was assumed.
ReadResult read_tiff(const std::vector<std::string>& inputs, const TiffReadOptions& opt = {},
                     const std::function<void(const VolumeHeader&)>& check_header = {});

/// Writes `v` as TIFF: `path` with one printf conversion ("out/slice%04d.tif") writes one file per
/// slice numbered from 0 (the folder must exist), otherwise one multi-page file (BigTIFF above
/// 2 GiB). Uncompressed, ImageJ tags for the spacing and origin. Each file is written under a
/// temporary name and renamed; on failure the files already written are removed. Throws IoError
/// (unwritable path, pattern with no or several conversions) or InvalidParameter (a direction that
/// is not the identity).
void write_tiff(const Volume<uint8_t>& v, const std::string& path);
void write_tiff(const Volume<int16_t>& v, const std::string& path);
void write_tiff(const Volume<float>& v, const std::string& path);

/// write_tiff a slab at a time (open_slab_writer in io.h for .tif paths): pages or slice files are
/// written as the slabs come, under temporary names renamed by finish().
std::unique_ptr<SlabWriter> open_tiff_slab_writer(const std::string& path, const Geometry& whole);

}  // namespace endocast
