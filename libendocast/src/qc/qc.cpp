// Quality-control picture (see qc.h): CT slices windowed to grey, the mask's outline found with
// cv::findContours on the slice resized to square millimetre pixels (nearest neighbour, so the
// outline follows the voxel boundary), and the mesh rendered by meshpost::render_mesh.
#include "endocast/qc.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <png.h>

#include "endocast/errors.h"
#include "meshpost/render.h"

namespace endocast {
namespace {

constexpr int kGap = 4;          // pixels between panels
constexpr int kMaxClosures = 6;  // closure slices drawn (QcParams::closures)
constexpr int kTitleHeight = 30;
const cv::Scalar kWhite(255, 255, 255), kBlack(0, 0, 0), kPanelBg(24, 24, 24);

/// One slice of the CT and of the mask as 2D images, with the mm size of a column and a row.
struct Slice {
    cv::Mat ct;    // CV_32F
    cv::Mat mask;  // CV_8U, 0/255
    double col_mm = 1, row_mm = 1;
    int col_axis = 0, row_axis = 1;      // voxel axes along columns and rows
    bool flip_c = false, flip_r = false;  // column / row 0 is the axis' last voxel
};

/// axis: the voxel axis held fixed (2 = axial k plane, 1 = coronal j plane, 0 = sagittal i plane).
/// Columns run along i (axial, coronal) or j (sagittal); rows along j (axial) or k. An axis whose
/// direction points against the world axis (direction diagonal < 0) is flipped, and k is shown
/// with superior (+z in LPS) at the top, so the picture is in radiological orientation.
template <class T>
Slice take_slice(const Volume<T>& ct, const Volume<uint8_t>& mask, int axis, int64_t index) {
    const Geometry& g = ct.geometry();
    const int ca = axis == 0 ? 1 : 0;  // axis along columns
    const int ra = axis == 2 ? 1 : 2;  // axis along rows
    const int64_t nc = g.dims[ca], nr = g.dims[ra];
    const bool flip_c = g.direction[ca * 4] < 0;
    const bool flip_r = ra == 2 ? g.direction[8] > 0 : g.direction[4] < 0;
    Slice s;
    s.ct.create(int(nr), int(nc), CV_32F);
    s.mask.create(int(nr), int(nc), CV_8U);
    for (int64_t r = 0; r < nr; ++r)
        for (int64_t c = 0; c < nc; ++c) {
            std::array<int64_t, 3> ijk{};
            ijk[axis] = index;
            ijk[ca] = flip_c ? nc - 1 - c : c;
            ijk[ra] = flip_r ? nr - 1 - r : r;
            s.ct.at<float>(int(r), int(c)) = ct(ijk[0], ijk[1], ijk[2]);
            s.mask.at<uchar>(int(r), int(c)) = mask(ijk[0], ijk[1], ijk[2]) ? 255 : 0;
        }
    s.col_mm = g.spacing[ca];
    s.row_mm = g.spacing[ra];
    s.col_axis = ca;
    s.row_axis = ra;
    s.flip_c = flip_c;
    s.flip_r = flip_r;
    return s;
}

/// Crops a slice to the voxel box [lo, hi] (inclusive, per axis) grown by `margin` times its
/// extent on each side (at least 4 voxels), clamped to the volume; returns the part kept (in the
/// slice's pixels before the crop).
cv::Rect crop(Slice& s, const Dims& dims, const std::array<int64_t, 3>& lo, const std::array<int64_t, 3>& hi,
              double margin) {
    auto range = [&](int axis, bool flip) {
        const int64_t m = std::max<int64_t>(4, int64_t(margin * double(hi[size_t(axis)] - lo[size_t(axis)])));
        const int64_t a = std::max<int64_t>(0, lo[size_t(axis)] - m);
        const int64_t b = std::min<int64_t>(dims[size_t(axis)] - 1, hi[size_t(axis)] + m);
        return flip ? std::pair<int64_t, int64_t>{dims[size_t(axis)] - 1 - b, b - a + 1}
                    : std::pair<int64_t, int64_t>{a, b - a + 1};
    };
    const auto c = range(s.col_axis, s.flip_c), r = range(s.row_axis, s.flip_r);
    const cv::Rect roi(int(c.first), int(r.first), int(c.second), int(r.second));
    s.ct = s.ct(roi).clone();
    s.mask = s.mask(roi).clone();
    return roi;
}

/// The slice windowed to grey, resized into a box of bw x bh with square mm pixels, outlined and
/// labelled; returned as a bw x bh panel.
cv::Mat draw_slice(const Slice& s, double lo, double hi, int bw, int bh, const std::string& label,
                   const QcParams& p, int thickness) {
    cv::Mat grey;
    s.ct.convertTo(grey, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));  // saturates
    const double wmm = s.ct.cols * s.col_mm, hmm = s.ct.rows * s.row_mm;
    const double scale = std::min(bw / wmm, bh / hmm);
    const cv::Size size(std::max(1, int(std::lround(wmm * scale))), std::max(1, int(std::lround(hmm * scale))));
    cv::Mat big, big_mask;
    cv::resize(grey, big, size, 0, 0, cv::INTER_LINEAR);
    cv::resize(s.mask, big_mask, size, 0, 0, cv::INTER_NEAREST);
    cv::Mat colour;
    cv::cvtColor(big, colour, cv::COLOR_GRAY2BGR);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(big_mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
    const cv::Scalar c(p.contour_bgr[0], p.contour_bgr[1], p.contour_bgr[2]);
    cv::drawContours(colour, contours, -1, c, thickness, cv::LINE_8);
    cv::Mat panel(bh, bw, CV_8UC3, kPanelBg);
    colour.copyTo(panel(cv::Rect((bw - size.width) / 2, (bh - size.height) / 2, size.width, size.height)));
    const int font = cv::FONT_HERSHEY_SIMPLEX;
    const double fs = bw >= 300 ? 0.5 : 0.4;
    int base = 0;
    const cv::Size ts = cv::getTextSize(label, font, fs, 1, &base);
    cv::rectangle(panel, {0, 0}, {ts.width + 8, ts.height + base + 6}, kBlack, cv::FILLED);
    cv::putText(panel, label, {4, ts.height + 3}, font, fs, kWhite, 1, cv::LINE_AA);
    return panel;
}

/// Median of the CT inside the mask (the soft tissue of the braincase); nullopt if the mask is empty.
template <class T>
std::optional<double> median_in_mask(const Volume<T>& ct, const Volume<uint8_t>& mask) {
    std::vector<float> v;
    for (size_t i = 0; i < ct.size(); ++i)
        if (mask[i]) v.push_back(ct[i]);
    if (v.empty()) return std::nullopt;
    auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return double(*mid);
}

std::string plane_label(const char* name, const char* axis, int64_t index, int64_t n) {
    return std::string(name) + " " + axis + "=" + std::to_string(index) + "/" + std::to_string(n - 1);
}

}  // namespace

std::vector<cv::Rect> qc_panels(const QcParams& p) {
    const int P = p.panel_px, n = std::max(1, p.row_slices);
    const int W = 3 * P + 2 * kGap;
    const int row_box = (W - (n - 1) * kGap) / n;
    std::vector<cv::Rect> r;
    for (int i = 0; i < 3; ++i) r.emplace_back(i * (P + kGap), kTitleHeight, P, P);
    for (int i = 0; i < n; ++i) r.emplace_back(i * (row_box + kGap), kTitleHeight + P + kGap, row_box, row_box);
    const int mesh_y = kTitleHeight + P + kGap + row_box + kGap;
    for (int i = 0; i < 3; ++i) r.emplace_back(i * (P + kGap), mesh_y, P, P);
    const int closures = int(std::min<size_t>(kMaxClosures, p.closures.size()));
    const int closure_box = (W - (kMaxClosures - 1) * kGap) / kMaxClosures;
    for (int i = 0; i < closures; ++i) r.emplace_back(i * (closure_box + kGap), mesh_y + P + kGap, closure_box, closure_box);
    return r;
}

template <class T>
cv::Mat render_qc(const Volume<T>& ct, const Volume<uint8_t>& mask, const meshpost::TriangleMesh& mesh,
                  const QcParams& p) {
    const Geometry& g = ct.geometry();
    if (ct.empty()) throw InvalidParameter("render_qc: the CT volume is empty, expected voxels");
    if (mask.dims() != ct.dims())
        throw InvalidParameter("render_qc: mask of " + std::to_string(mask.nx()) + " x " + std::to_string(mask.ny()) +
                               " x " + std::to_string(mask.nz()) + " voxels, expected the CT's " +
                               std::to_string(ct.nx()) + " x " + std::to_string(ct.ny()) + " x " +
                               std::to_string(ct.nz()));
    if (p.panel_px < 64) throw InvalidParameter("QC panel size " + std::to_string(p.panel_px) + " px, expected >= 64");
    if (p.row_slices < 1 || p.row_slices > 12)
        throw InvalidParameter("QC row of " + std::to_string(p.row_slices) + " slices, expected 1..12");
    if (p.face_on_bone && p.face_on_bone->size() != mesh.faces.size())
        throw InvalidParameter("render_qc: " + std::to_string(p.face_on_bone->size()) +
                               " face flags, expected one per face of the mesh (" + std::to_string(mesh.faces.size()) + ")");
    if (p.face_leaks && p.face_leaks->size() != mesh.faces.size())
        throw InvalidParameter("render_qc: " + std::to_string(p.face_leaks->size()) +
                               " leak flags, expected one per face of the mesh (" + std::to_string(mesh.faces.size()) + ")");

    // Grey window.
    double lo = 0, hi = 1;
    if (p.window_low && p.window_high) {
        lo = *p.window_low;
        hi = *p.window_high;
    } else {
        const std::optional<double> t = median_in_mask(ct, mask);
        if (t && p.isovalue > *t) {
            lo = *t - 0.5 * (p.isovalue - *t);
            hi = *t + 2.0 * (p.isovalue - *t);
        } else {
            const auto mm = std::minmax_element(ct.buffer().begin(), ct.buffer().end());
            lo = *mm.first;
            hi = *mm.second;
        }
        if (p.window_low) lo = *p.window_low;
        if (p.window_high) hi = *p.window_high;
    }
    if (!(lo < hi))
        throw InvalidParameter("QC grey window " + std::to_string(lo) + " .. " + std::to_string(hi) +
                               ", expected low < high");

    // Centroid and extent of the mask (voxel indices).
    std::array<double, 3> sum{0, 0, 0};
    std::array<int64_t, 3> bmin{g.dims[0], g.dims[1], g.dims[2]}, bmax{-1, -1, -1};
    size_t count = 0;
    for (int64_t z = 0; z < ct.nz(); ++z)
        for (int64_t y = 0; y < ct.ny(); ++y)
            for (int64_t x = 0; x < ct.nx(); ++x) {
                if (!mask(x, y, z)) continue;
                const int64_t q[3] = {x, y, z};
                for (int a = 0; a < 3; ++a) {
                    sum[a] += double(q[a]);
                    bmin[a] = std::min(bmin[a], q[a]);
                    bmax[a] = std::max(bmax[a], q[a]);
                }
                ++count;
            }
    std::array<int64_t, 3> centre{};
    for (int a = 0; a < 3; ++a) {
        if (count == 0) {
            bmin[a] = 0;
            bmax[a] = g.dims[a] - 1;
        }
        centre[a] = count ? int64_t(std::lround(sum[a] / double(count))) : g.dims[a] / 2;
    }

    const std::vector<cv::Rect> panels = qc_panels(p);
    const int P = p.panel_px, row_box = panels[3].width;
    int width = 0, height = 0;
    for (const cv::Rect& r : panels) width = std::max(width, r.br().x), height = std::max(height, r.br().y);
    cv::Mat img(height, width, CV_8UC3, kBlack);
    cv::putText(img, p.title, {8, 21}, cv::FONT_HERSHEY_SIMPLEX, std::min(0.6, 0.6 * P / 400.0), kWhite, 1, cv::LINE_AA);

    // Row 1: the three planes through the centroid.
    const char* names[3] = {"sagittal", "coronal", "axial"};
    const char* axis_names[3] = {"i", "j", "k"};
    const int order[3] = {2, 1, 0};  // axial, coronal, sagittal
    for (int n = 0; n < 3; ++n) {
        const int axis = order[n];
        Slice s = take_slice(ct, mask, axis, centre[size_t(axis)]);
        crop(s, g.dims, bmin, bmax, 0.35);
        const cv::Mat panel = draw_slice(s, lo, hi, P, P, plane_label(names[axis], axis_names[axis],
                                         centre[size_t(axis)], g.dims[size_t(axis)]), p, p.contour_thickness);
        panel.copyTo(img(panels[size_t(n)]));
    }

    // Row 2: axial slices through the mask's k extent, cropped to its i/j extent.
    for (int n = 0; n < p.row_slices; ++n) {
        const int64_t k = bmin[2] + int64_t(std::floor((bmax[2] - bmin[2]) * (n + 0.5) / p.row_slices));
        Slice s = take_slice(ct, mask, 2, k);
        crop(s, g.dims, bmin, bmax, 0.125);
        const cv::Mat panel = draw_slice(s, lo, hi, row_box, row_box, plane_label("axial", "k", k, g.dims[2]), p, 1);
        panel.copyTo(img(panels[size_t(3 + n)]));
    }

    // Row 3: the mesh, the faces not on bone marked (1), those facing other space over them (2).
    std::vector<uint8_t> off_bone;
    if (p.face_on_bone || p.face_leaks) {
        off_bone.assign(mesh.faces.size(), 0);
        for (size_t f = 0; f < off_bone.size(); ++f) {
            if (p.face_on_bone && !(*p.face_on_bone)[f]) off_bone[f] = 1;
            if (p.face_leaks && (*p.face_leaks)[f]) off_bone[f] = 2;
        }
    }
    const bool any_off_bone = std::find(off_bone.begin(), off_bone.end(), 1) != off_bone.end();
    const bool any_leak = std::find(off_bone.begin(), off_bone.end(), 2) != off_bone.end();
    const meshpost::ViewSide sides[3] = {meshpost::ViewSide::Left, meshpost::ViewSide::Top, meshpost::ViewSide::Front};
    for (int n = 0; n < 3; ++n) {
        meshpost::RenderParams rp;
        rp.side = sides[n];
        rp.width = rp.height = P;
        rp.background = {24, 24, 24};
        if (any_off_bone || any_leak) {
            rp.face_marks = &off_bone;
            rp.mark_colour = p.off_bone_bgr;
            rp.mark2_colour = p.leak_bgr;
        }
        cv::Mat view = meshpost::render_mesh(mesh, rp);
        const std::string label = std::string("mesh, ") + meshpost::to_string(sides[n]) + " view";
        cv::putText(view, label, {4, 16}, cv::FONT_HERSHEY_SIMPLEX, 0.5, kWhite, 1, cv::LINE_AA);
        const double fs = std::min(0.5, 0.5 * P / 400.0);
        if (any_off_bone && n == 0) {
            const cv::Scalar c(p.off_bone_bgr[0], p.off_bone_bgr[1], p.off_bone_bgr[2]);
            cv::putText(view, "orange: surface not on bone (closed opening)", {4, P - 8}, cv::FONT_HERSHEY_SIMPLEX,
                        fs, c, 1, cv::LINE_AA);
        }
        if (any_leak && n == 1) {
            const cv::Scalar c(p.leak_bgr[0], p.leak_bgr[1], p.leak_bgr[2]);
            cv::putText(view, "red: facing other space (a closure, or a leak)", {4, P - 8}, cv::FONT_HERSHEY_SIMPLEX, fs, c, 1,
                        cv::LINE_AA);
        }
        view.copyTo(img(panels[size_t(3 + p.row_slices + n)]));
    }

    // Row 4: a slice through each closure, in the voxel plane that best holds its normal (the cap
    // then crosses the slice as a line), cropped around it.
    const size_t first_closure = size_t(6 + p.row_slices);
    for (size_t c = 0; c + first_closure < panels.size(); ++c) {
        const QcParams::Closure& cl = p.closures[c];
        const Vec3 ci = g.world_to_index(cl.centre);
        int axis = 0;
        double least = 2;
        for (int a = 0; a < 3; ++a) {  // |normal . the axis' world direction|: smallest holds the normal
            const double d = std::abs(cl.normal[0] * g.direction[size_t(a)] + cl.normal[1] * g.direction[size_t(3 + a)] +
                                      cl.normal[2] * g.direction[size_t(6 + a)]);
            if (d < least) least = d, axis = a;
        }
        const int64_t index = std::clamp<int64_t>(std::llround(ci[size_t(axis)]), 0, g.dims[size_t(axis)] - 1);
        Slice s = take_slice(ct, mask, axis, index);
        // The box: the closure's centre +- max(2 radii, 12 voxels) along the slice's axes.
        std::array<int64_t, 3> clo{}, chi{};
        for (int a = 0; a < 3; ++a) {
            const double half = std::max(2.0 * cl.radius_mm / g.spacing[size_t(a)], 12.0);
            clo[size_t(a)] = std::clamp<int64_t>(std::llround(ci[size_t(a)] - half), 0, g.dims[size_t(a)] - 1);
            chi[size_t(a)] = std::clamp<int64_t>(std::llround(ci[size_t(a)] + half), 0, g.dims[size_t(a)] - 1);
        }
        // The centre's pixel in the slice before cropping (flips as take_slice's), then after.
        auto pixel = [&](int a, bool flip) { return flip ? double(g.dims[size_t(a)] - 1) - ci[size_t(a)] : ci[size_t(a)]; };
        const double pc = pixel(s.col_axis, s.flip_c), pr = pixel(s.row_axis, s.flip_r);
        const cv::Rect kept = crop(s, g.dims, clo, chi, 0.0);
        const cv::Rect& box = panels[first_closure + c];
        const char* axes[3] = {"i", "j", "k"};
        const std::string label = cl.label + " " + axes[axis] + "=" + std::to_string(index);
        cv::Mat panel = draw_slice(s, lo, hi, box.width, box.height, label, p, 1);
        // draw_slice centres the slice scaled into the box: the same scale maps the centre.
        const double wmm = s.ct.cols * s.col_mm, hmm = s.ct.rows * s.row_mm;
        const double scale = std::min(box.width / wmm, box.height / hmm);
        const double ox = (box.width - std::lround(wmm * scale)) / 2.0, oy = (box.height - std::lround(hmm * scale)) / 2.0;
        const cv::Point at(int(std::lround(ox + (pc - kept.x + 0.5) * s.col_mm * scale)),
                           int(std::lround(oy + (pr - kept.y + 0.5) * s.row_mm * scale)));
        const cv::Scalar m(p.closure_bgr[0], p.closure_bgr[1], p.closure_bgr[2]);
        cv::drawMarker(panel, at, m, cv::MARKER_CROSS, std::max(8, box.width / 12), 1, cv::LINE_8);
        panel.copyTo(img(box));
    }
    return img;
}

namespace {

// libpng reports errors by longjmp back to encode_rows' setjmp; nothing with a destructor is
// created between the two. The bytes go to a std::string owned by the caller.
void png_append(png_structp png, png_bytep data, png_size_t length) {
    static_cast<std::string*>(png_get_io_ptr(png))->append(reinterpret_cast<const char*>(data), length);
}
void png_flush_nothing(png_structp) {}

// Returns false when libpng failed (it then called longjmp).
bool encode_rows(const cv::Mat& image, int color_type, bool bgr, std::string& out) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
    if (!png) return false;
    png_infop info = png_create_info_struct(png);
    if (!info || setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, info ? &info : nullptr);
        return false;
    }
    png_set_write_fn(png, &out, png_append, png_flush_nothing);
    png_set_compression_level(png, 6);
    png_set_IHDR(png, info, png_uint_32(image.cols), png_uint_32(image.rows), 8, color_type,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    if (bgr) png_set_bgr(png);
    for (int y = 0; y < image.rows; ++y) png_write_row(png, image.ptr<png_byte>(y));
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    return true;
}

}  // namespace

std::string encode_png(const cv::Mat& image) {
    const std::string size = std::to_string(image.cols) + " x " + std::to_string(image.rows) + " pixels";
    if (image.empty() || image.depth() != CV_8U || image.dims != 2)
        throw IoError("PNG encoding: expected a non-empty 8-bit image, got " + size +
                      " of OpenCV type " + std::to_string(image.type()));
    int color_type;
    switch (image.channels()) {
        case 1: color_type = PNG_COLOR_TYPE_GRAY; break;
        case 3: color_type = PNG_COLOR_TYPE_RGB; break;   // OpenCV's BGR order, swapped by libpng
        case 4: color_type = PNG_COLOR_TYPE_RGB_ALPHA; break;
        default:
            throw IoError("PNG encoding: expected 1, 3 or 4 channels, got " +
                          std::to_string(image.channels()) + " (" + size + ")");
    }
    std::string out;
    if (!encode_rows(image, color_type, image.channels() >= 3, out))
        throw IoError("PNG encoding failed (libpng) for an image of " + size);
    return out;
}

template cv::Mat render_qc<float>(const Volume<float>&, const Volume<uint8_t>&, const meshpost::TriangleMesh&, const QcParams&);
template cv::Mat render_qc<int16_t>(const Volume<int16_t>&, const Volume<uint8_t>&, const meshpost::TriangleMesh&, const QcParams&);

}  // namespace endocast
