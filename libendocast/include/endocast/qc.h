#pragma once
// Quality-control picture of an extraction: the CT with the endocast's outline drawn over it, and
// shaded views of the mesh, in one image a reader can check at a glance.
//
// Layout (top to bottom): a title line; the three orthogonal planes through the centroid of the
// mask (axial = the k plane, coronal = the j plane, sagittal = the i plane of the voxel grid); a
// row of `row_slices` axial slices spread evenly through the mask's k extent (cropped to the
// mask's i/j extent plus a margin); shaded renderings of the mesh seen from the left, the top and
// the front (meshpost/render.h), the faces not on bone (QcParams::face_on_bone) in a second
// colour and those facing other empty space (QcParams::face_leaks) in a third; and, when
// QcParams::closures lists any, a last row of slices through each closure (an opening's cap),
// centred on it, in the voxel plane that best holds its normal, so the cap shows as a line across
// the opening. Every slice is resized so its pixels are square in mm
// (anisotropic spacing keeps its true proportions), labelled with its plane and index, and shown
// with superior, anterior and the patient's right towards the top / top / left of the picture
// when the direction matrix is close to the axes (LPS).
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

struct QcParams {
    std::string title;                   ///< first line of the picture (e.g. specimen name, ECV)
    /// Bone isovalue of the extraction (scan units); sets the grey window when none is given.
    double isovalue = 0;
    /// Grey window (scan units): values <= low are black, >= high white. Default: from the
    /// median t of the CT inside the mask (soft tissue) and the isovalue T:
    /// low = t - 0.5 (T - t), high = t + 2 (T - t).
    std::optional<double> window_low, window_high;
    int panel_px = 400;                  ///< box of each mid-plane and mesh view, pixels (>= 64)
    int row_slices = 6;                  ///< axial slices in the second row (1..12)
    cv::Vec3b contour_bgr{0, 255, 0};    ///< outline colour (BGR); nothing else is drawn in it
    int contour_thickness = 2;           ///< pixels, in the mid-plane panels (1 in the row)
    /// Optional, one flag per face of the mesh (BoneContact::face_on_bone, 1 = on bone): the faces
    /// with flag 0 (closing surfaces across openings, leaks) are drawn in off_bone_bgr in the
    /// mesh views, and when there is any, a legend line in that colour says what it means.
    /// nullptr: every face in the bone colour, no legend.
    const std::vector<uint8_t>* face_on_bone = nullptr;
    cv::Vec3b off_bone_bgr{0, 140, 255}; ///< colour of the faces not on bone (BGR, orange)
    /// Optional, one flag per face (ExtractionResult::face_leaks, 1 = facing other empty space:
    /// a possible leak): drawn in leak_bgr over the off-bone colour, with a legend line.
    const std::vector<uint8_t>* face_leaks = nullptr;
    cv::Vec3b leak_bgr{40, 40, 230};     ///< colour of the faces facing other space (BGR, red)
    /// A closure to show in the last row: its centre and normal (world mm), its radius and label.
    struct Closure {
        Vec3 centre{0, 0, 0}, normal{0, 0, 1};
        double radius_mm = 0;
        std::string label;
    };
    std::vector<Closure> closures;       ///< at most 6 are drawn, in order
    cv::Vec3b closure_bgr{255, 0, 255};  ///< the mark at a closure's centre (BGR, magenta)
};

/// Where render_qc puts its panels, in the picture's pixels: the 3 planes (axial, coronal,
/// sagittal), then the `row_slices` axial slices, then the 3 mesh views (left, top, front), then
/// one per closure drawn (min(6, closures.size()), a row below the mesh views). Each slice panel
/// carries its label in a black box at its top-left corner.
std::vector<cv::Rect> qc_panels(const QcParams& p = {});

/// Draws the quality-control picture (CV_8UC3, BGR). `mask` (1 = endocast) must have the CT's
/// dims; `mesh` is in world mm (may be empty: the mesh views stay blank). With an empty mask the
/// planes go through the volume's centre. Deterministic. Throws InvalidParameter for mismatched
/// dims, an empty CT, panel_px < 64, row_slices outside 1..12, window_low >= window_high or
/// face_on_bone or face_leaks of another size than the mesh's faces.
template <class T>
cv::Mat render_qc(const Volume<T>& ct, const Volume<uint8_t>& mask, const meshpost::TriangleMesh& mesh,
                  const QcParams& p = {});

/// PNG bytes of an 8-bit image with 1 (grey), 3 (BGR, OpenCV's order) or 4 (BGRA) channels,
/// lossless, written with libpng (zlib level 6). Throws IoError for other images or if libpng fails.
std::string encode_png(const cv::Mat& image);

}  // namespace endocast
