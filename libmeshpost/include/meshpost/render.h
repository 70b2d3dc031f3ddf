#pragma once
// A small software renderer for quality-control pictures: an orthographic z-buffer rasterizer of
// the triangles with Lambert (diffuse) shading from a light at the viewer, interpolated between
// vertex normals (Gouraud). No GPU, no window: the result is an OpenCV image.
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "meshpost/mesh.h"

namespace meshpost {

/// Where the viewer stands, in the mesh's world axes (ITK/LPS for endocast meshes: +x = patient's
/// left, +y = posterior, +z = superior). The image's up direction is +z for the side views and
/// -y (anterior) for the top and bottom views.
enum class ViewSide { Left, Right, Front, Back, Top, Bottom };

const char* to_string(ViewSide v);

struct RenderParams {
    ViewSide side = ViewSide::Left;
    int width = 400;    ///< image size, pixels (> 0)
    int height = 400;
    /// Scale in pixels per mm; 0 = fit the mesh's bounding box into the image with `margin`.
    double pixels_per_mm = 0;
    double margin = 0.05;                   ///< fraction of the image left free on each side (fit)
    cv::Vec3b background{255, 255, 255};    ///< BGR
    cv::Vec3b colour{170, 215, 235};        ///< BGR of a surface facing the viewer (ivory)
    double ambient = 0.25;                  ///< fraction of the colour seen in unlit parts
    /// Optional marks, one per face of the mesh: a face whose mark is 1 is drawn in `mark_colour`
    /// instead of `colour`, one of 2 or more in `mark2_colour` (same shading). nullptr: every face
    /// in `colour`.
    const std::vector<uint8_t>* face_marks = nullptr;
    cv::Vec3b mark_colour{0, 140, 255};     ///< BGR of a face marked 1 facing the viewer (orange)
    cv::Vec3b mark2_colour{40, 40, 230};    ///< BGR of a face marked 2 or more (red)
};

/// Renders `mesh` seen from `p.side`, orthographically, centred on the centre of its bounding box.
/// Returns a CV_8UC3 (BGR) image of p.width x p.height; pixels no triangle covers keep
/// p.background. Faces are lit from both sides (a mesh that is not closed still renders).
/// Deterministic. Throws std::invalid_argument for a size <= 0, pixels_per_mm < 0 or face_marks
/// of another size than the faces.
cv::Mat render_mesh(const TriangleMesh& mesh, const RenderParams& p = {});

}  // namespace meshpost
