#pragma once
// DICOM series written from scratch for the tests (explicit VR little endian, signed 16-bit
// MONOCHROME2 slices, one file per slice): clinical geometries made from a phantom (gantry tilt,
// mixed slice spacing) and study folders (localizers, secondary captures, several series).
// Header-only; needs only the library's Volume.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "endocast/volume.h"

namespace endocast::testing {

/// One series: what its headers say and where its slices lie.
struct DicomSeriesSpec {
    std::string study_uid = "1.2.826.0.1.3680043.9.7777.1";
    std::string series_uid = "1.2.826.0.1.3680043.9.7777.1.1";
    std::string series_description = "HEAD 1.0 H30s";
    std::string modality = "CT";
    std::string sop_class_uid = "1.2.840.10008.5.1.4.1.1.2";  ///< CT Image Storage (secondary capture: ...1.1.7)
    std::string image_type = "ORIGINAL\\PRIMARY\\AXIAL";      ///< "...\\LOCALIZER" for a scout
    std::string kernel = "H30s";                             ///< (0018,1210) ConvolutionKernel; empty: none
    double slice_thickness_mm = 1.0;
    double gantry_tilt_deg = 0;                               ///< (0018,1120), as scanners write it
    int series_number = 1;
    int rows = 0, columns = 0;                                ///< pixels per slice (y, x)
    double row_spacing_mm = 1.0, column_spacing_mm = 1.0;     ///< (0028,0030): between rows, between columns
    Vec3 row_direction{1, 0, 0};                              ///< direction of a row (increasing column index)
    Vec3 column_direction{0, 1, 0};                           ///< direction of a column (increasing row index)
    std::vector<Vec3> positions;                              ///< ImagePositionPatient of each slice (mm)
};

/// Writes slice k of `spec` to `path`; pixel(x, y) gives its stored value (HU; int16).
inline void write_dicom_slice(const std::string& path, const DicomSeriesSpec& spec, size_t k,
                              const std::function<int16_t(int x, int y)>& pixel) {
    auto u16 = [](uint16_t v) { return std::string{char(v & 0xFF), char(v >> 8)}; };
    auto u32 = [](uint32_t v) {
        return std::string{char(v & 0xFF), char((v >> 8) & 0xFF), char((v >> 16) & 0xFF), char(v >> 24)};
    };
    auto element = [&](uint16_t g, uint16_t e, const std::string& vr, std::string v) {
        if (v.size() % 2) v += vr == "UI" ? '\0' : ' ';
        std::string o = u16(g) + u16(e);
        const bool long_form = vr == "OB" || vr == "OW" || vr == "SQ" || vr == "UN" || vr == "UT";
        if (long_form) o += vr + u16(0) + u32(uint32_t(v.size()));
        else o += vr + u16(uint16_t(v.size()));
        return o + v;
    };
    auto ds3 = [](const Vec3& v) {
        std::ostringstream s;
        s.precision(10);
        s << v[0] << '\\' << v[1] << '\\' << v[2];
        return s.str();
    };
    auto num = [](double v) {
        std::ostringstream s;
        s.precision(10);
        s << v;
        return s.str();
    };
    const std::string sop_uid = spec.series_uid + "." + std::to_string(k + 1);
    const std::string syntax = "1.2.840.10008.1.2.1";
    std::string meta = element(2, 1, "OB", std::string("\0\1", 2)) + element(2, 2, "UI", spec.sop_class_uid) +
                       element(2, 3, "UI", sop_uid) + element(2, 0x10, "UI", syntax) +
                       element(2, 0x12, "UI", "1.2.826.0.1.3680043.9.7777");
    meta = element(2, 0, "UL", u32(uint32_t(meta.size()))) + meta;
    std::ostringstream iop;
    iop.precision(10);
    iop << spec.row_direction[0] << '\\' << spec.row_direction[1] << '\\' << spec.row_direction[2] << '\\'
        << spec.column_direction[0] << '\\' << spec.column_direction[1] << '\\' << spec.column_direction[2];
    // Elements in ascending tag order.
    std::string ds = element(8, 8, "CS", spec.image_type) + element(8, 0x16, "UI", spec.sop_class_uid) +
                     element(8, 0x18, "UI", sop_uid) + element(8, 0x60, "CS", spec.modality) +
                     element(8, 0x103E, "LO", spec.series_description) +
                     element(0x18, 0x50, "DS", num(spec.slice_thickness_mm));
    if (spec.gantry_tilt_deg != 0) ds += element(0x18, 0x1120, "DS", num(spec.gantry_tilt_deg));
    if (!spec.kernel.empty()) ds += element(0x18, 0x1210, "SH", spec.kernel);
    ds += element(0x20, 0xD, "UI", spec.study_uid) + element(0x20, 0xE, "UI", spec.series_uid) +
          element(0x20, 0x11, "IS", std::to_string(spec.series_number)) +
          element(0x20, 0x13, "IS", std::to_string(k + 1)) + element(0x20, 0x32, "DS", ds3(spec.positions[k])) +
          element(0x20, 0x37, "DS", iop.str()) + element(0x28, 2, "US", u16(1)) +
          element(0x28, 4, "CS", "MONOCHROME2") + element(0x28, 0x10, "US", u16(uint16_t(spec.rows))) +
          element(0x28, 0x11, "US", u16(uint16_t(spec.columns))) +
          element(0x28, 0x30, "DS", num(spec.row_spacing_mm) + "\\" + num(spec.column_spacing_mm)) +
          element(0x28, 0x100, "US", u16(16)) + element(0x28, 0x101, "US", u16(16)) +
          element(0x28, 0x102, "US", u16(15)) + element(0x28, 0x103, "US", u16(1)) +
          element(0x28, 0x1052, "DS", "0") + element(0x28, 0x1053, "DS", "1");
    std::string px;
    px.reserve(size_t(spec.rows) * size_t(spec.columns) * 2);
    for (int y = 0; y < spec.rows; ++y)
        for (int x = 0; x < spec.columns; ++x) px += u16(uint16_t(pixel(x, y)));
    ds += element(0x7FE0, 0x10, "OW", px);
    std::ofstream f(path, std::ios::binary);
    const std::string all = std::string(128, '\0') + "DICM" + meta + ds;
    f.write(all.data(), std::streamsize(all.size()));
    if (!f) throw std::runtime_error("cannot write " + path);
}

/// Trilinear sample of `v` at a world point (its geometry's transform); `outside` beyond it.
inline double sample_world(const Volume<int16_t>& v, const Vec3& w, double outside) {
    const Vec3 c = v.geometry().world_to_index(w);
    const int64_t x0 = int64_t(std::floor(c[0])), y0 = int64_t(std::floor(c[1])), z0 = int64_t(std::floor(c[2]));
    const double fx = c[0] - double(x0), fy = c[1] - double(y0), fz = c[2] - double(z0);
    double acc = 0;
    for (int dz = 0; dz < 2; ++dz)
        for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
                const double wgt = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
                if (wgt == 0) continue;
                const int64_t x = x0 + dx, y = y0 + dy, z = z0 + dz;
                acc += wgt * (v.contains(x, y, z) ? double(v(x, y, z)) : outside);
            }
    return acc;
}

/// Writes the series `spec` into directory `dir` (created), slices sampled from `ct` at their
/// world positions (trilinear, `outside` beyond it), files named IM0001.dcm, ... in slice order
/// (or in `file_order` when given: file i holds slice file_order[i]).
inline void write_dicom_series_from(const std::string& dir, const DicomSeriesSpec& spec, const Volume<int16_t>& ct,
                                    double outside = -1024, const std::vector<size_t>& file_order = {}) {
    std::filesystem::create_directories(dir);
    for (size_t i = 0; i < spec.positions.size(); ++i) {
        const size_t k = file_order.empty() ? i : file_order[i];
        const Vec3 p = spec.positions[k];
        char name[32];
        std::snprintf(name, sizeof name, "IM%04zu.dcm", i + 1);
        write_dicom_slice((std::filesystem::path(dir) / name).string(), spec, k, [&](int x, int y) {
            Vec3 w;
            for (int a = 0; a < 3; ++a)
                w[a] = p[a] + x * spec.column_spacing_mm * spec.row_direction[a] +
                       y * spec.row_spacing_mm * spec.column_direction[a];
            return int16_t(std::lround(sample_world(ct, w, outside)));
        });
    }
}

/// A series over `ct`'s x-y extent: slices perpendicular to column_direction x row_direction,
/// tilted by tilt_deg about the x axis (the gantry tilt: the slice normal leans, the positions
/// step along the table axis z), at table positions z_positions (mm, world). Rows/columns and
/// pixel spacing as ct's x-y grid; the rows are lengthened to cover the tilted plane.
inline DicomSeriesSpec tilted_series_over(const Volume<int16_t>& ct, double tilt_deg,
                                          const std::vector<double>& z_positions) {
    DicomSeriesSpec s;
    const Geometry& g = ct.geometry();
    const double t = tilt_deg * M_PI / 180.0;
    s.row_direction = {1, 0, 0};
    s.column_direction = {0, std::cos(t), std::sin(t)};
    s.gantry_tilt_deg = tilt_deg;
    s.columns = int(g.dims[0]);
    s.column_spacing_mm = g.spacing[0];
    s.row_spacing_mm = g.spacing[1];
    s.rows = int(std::ceil(double(g.dims[1]) / std::cos(t)));
    const Vec3 o = g.index_to_world(0, 0, 0);
    for (double z : z_positions) s.positions.push_back({o[0], o[1], z});
    return s;
}

}  // namespace endocast::testing
