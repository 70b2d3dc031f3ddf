#pragma once
// Shared by the readers in io.cpp, raw_io.cpp and dicom_direct.cpp (not installed).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "endocast/io.h"

namespace endocast {

/// The whole file's bytes; nullopt when it cannot be opened or read.
std::optional<std::string> slurp(const std::string& path);

/// Converts n stored samples of type t at src (bytes reversed if `swap`) to float, one thread.
void convert_samples(RawType t, const unsigned char* src, size_t n, bool swap, float* dst);

/// ImagePositionPatient (0020,0032) from its DICOM text, e.g. "-249.5\\-432.0\\551.5" (mm); nullopt if unreadable.
std::optional<Vec3> parse_image_position(std::string value);

/// Reads the pixels of a DICOM series, one slice per file in the order given, into `out`
/// (nx * ny * files.size() floats, x fastest), without GDCM and in parallel, with the values GDCM
/// gives through ITK (bits above BitsStored cleared or sign-filled, RescaleSlope and
/// RescaleIntercept applied). Only for the common case: CT Image Storage, uncompressed implicit or
/// explicit VR little endian, one frame of 16-bit MONOCHROME2 pixels, nx columns and ny rows,
/// integer slope and intercept. Returns the slices' ImagePositionPatient up to the first slice
/// without one, or nullopt when any file is outside that case or unreadable (then `out` holds
/// nothing useful and the series must be read with ITK).
std::optional<std::vector<Vec3>> read_dicom_pixels(const std::vector<std::string>& files, int64_t nx,
                                                   int64_t ny, float* out);

}  // namespace endocast
