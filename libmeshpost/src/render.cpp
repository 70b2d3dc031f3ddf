// Orthographic z-buffer rasterizer with Gouraud-interpolated Lambert shading (see render.h).
//
// Each vertex is projected onto the image plane of the chosen view (right, up axes; depth along
// the viewing direction). Triangles are scanned over their pixel bounding box with edge functions
// (pixel centres, top-left rule not needed: a pixel covered twice keeps the nearer depth, and a
// tie keeps the first face, so the picture is deterministic). Vertex normals are the area-weighted
// sums of face normals; the light is a headlight, so intensity = ambient + (1 - ambient) * |n.d|.
#include "meshpost/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "meshpost/measure.h"

namespace meshpost {
namespace {

struct ViewAxes {
    Point right, up, toward_viewer;
};

ViewAxes axes(ViewSide v) {
    switch (v) {
        case ViewSide::Left: return {{0, -1, 0}, {0, 0, 1}, {1, 0, 0}};    // +x is the patient's left
        case ViewSide::Right: return {{0, 1, 0}, {0, 0, 1}, {-1, 0, 0}};
        case ViewSide::Front: return {{-1, 0, 0}, {0, 0, 1}, {0, -1, 0}};  // anterior is -y
        case ViewSide::Back: return {{1, 0, 0}, {0, 0, 1}, {0, 1, 0}};
        case ViewSide::Top: return {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}};
        case ViewSide::Bottom: return {{-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
    }
    return {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
}

double dot(const Point& a, const Point& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace

const char* to_string(ViewSide v) {
    switch (v) {
        case ViewSide::Left: return "left";
        case ViewSide::Right: return "right";
        case ViewSide::Front: return "front";
        case ViewSide::Back: return "back";
        case ViewSide::Top: return "top";
        case ViewSide::Bottom: return "bottom";
    }
    return "?";
}

cv::Mat render_mesh(const TriangleMesh& mesh, const RenderParams& p) {
    if (p.width <= 0 || p.height <= 0)
        throw std::invalid_argument("render_mesh: image size " + std::to_string(p.width) + " x " +
                                    std::to_string(p.height) + ", expected positive");
    if (!(p.pixels_per_mm >= 0))
        throw std::invalid_argument("render_mesh: pixels_per_mm " + std::to_string(p.pixels_per_mm) +
                                    ", expected >= 0 (0 = fit)");
    if (p.face_marks && p.face_marks->size() != mesh.faces.size())
        throw std::invalid_argument("render_mesh: " + std::to_string(p.face_marks->size()) + " face marks, expected one per face (" +
                                    std::to_string(mesh.faces.size()) + ")");
    cv::Mat img(p.height, p.width, CV_8UC3, cv::Scalar(p.background[0], p.background[1], p.background[2]));
    if (mesh.faces.empty() || mesh.vertices.empty()) return img;
    const ViewAxes ax = axes(p.side);
    const BoundingBox box = bounding_box(mesh);
    const Point c{0.5 * (box.min[0] + box.max[0]), 0.5 * (box.min[1] + box.max[1]),
                  0.5 * (box.min[2] + box.max[2])};

    // Project; fit the projected extent if no scale was given.
    const size_t nv = mesh.vertices.size();
    std::vector<double> u(nv), w(nv), depth(nv);
    double umax = 0, wmax = 0;
    for (size_t i = 0; i < nv; ++i) {
        const Point d{mesh.vertices[i][0] - c[0], mesh.vertices[i][1] - c[1], mesh.vertices[i][2] - c[2]};
        u[i] = dot(d, ax.right);
        w[i] = dot(d, ax.up);
        depth[i] = dot(d, ax.toward_viewer);  // larger = nearer the viewer
        umax = std::max(umax, std::abs(u[i]));
        wmax = std::max(wmax, std::abs(w[i]));
    }
    double scale = p.pixels_per_mm;
    if (scale == 0) {
        const double free = std::max(0.0, 1.0 - 2.0 * p.margin);
        scale = std::min(umax > 0 ? 0.5 * free * p.width / umax : 1.0, wmax > 0 ? 0.5 * free * p.height / wmax : 1.0);
        if (!(scale > 0) || !std::isfinite(scale)) scale = 1.0;
    }
    std::vector<double> px(nv), py(nv);
    for (size_t i = 0; i < nv; ++i) {
        px[i] = 0.5 * p.width + u[i] * scale;
        py[i] = 0.5 * p.height - w[i] * scale;
    }

    // Vertex intensities from area-weighted vertex normals (headlight, two-sided).
    std::vector<Point> vn(nv, Point{0, 0, 0});
    for (const Face& f : mesh.faces) {
        if (f[0] >= nv || f[1] >= nv || f[2] >= nv)
            throw InvalidMesh("render_mesh: a face references a vertex beyond the " + std::to_string(nv) + " vertices");
        const Point n = face_cross(mesh, f);
        for (uint32_t v : f)
            for (int k = 0; k < 3; ++k) vn[v][k] += n[k];
    }
    std::vector<float> shade(nv);
    for (size_t i = 0; i < nv; ++i) {
        const double len = std::sqrt(dot(vn[i], vn[i]));
        const double lambert = len > 0 ? std::abs(dot(vn[i], ax.toward_viewer)) / len : 0.0;
        shade[i] = float(p.ambient + (1.0 - p.ambient) * lambert);
    }

    std::vector<double> zbuf(size_t(p.width) * size_t(p.height), -std::numeric_limits<double>::infinity());
    for (size_t fi = 0; fi < mesh.faces.size(); ++fi) {
        const Face& f = mesh.faces[fi];
        const uint8_t mark = p.face_marks ? (*p.face_marks)[fi] : 0;
        const cv::Vec3b& colour = mark == 0 ? p.colour : mark == 1 ? p.mark_colour : p.mark2_colour;
        const double x0 = px[f[0]], y0 = py[f[0]], x1 = px[f[1]], y1 = py[f[1]], x2 = px[f[2]], y2 = py[f[2]];
        const double area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);
        if (area == 0) continue;  // seen edge-on
        const int xa = std::max(0, int(std::floor(std::min({x0, x1, x2}))));
        const int xb = std::min(p.width - 1, int(std::ceil(std::max({x0, x1, x2}))));
        const int ya = std::max(0, int(std::floor(std::min({y0, y1, y2}))));
        const int yb = std::min(p.height - 1, int(std::ceil(std::max({y0, y1, y2}))));
        for (int y = ya; y <= yb; ++y) {
            const double sy = y + 0.5;
            for (int x = xa; x <= xb; ++x) {
                const double sx = x + 0.5;
                // barycentric weights of vertices 0, 1, 2
                const double b0 = ((x1 - sx) * (y2 - sy) - (x2 - sx) * (y1 - sy)) / area;
                const double b1 = ((x2 - sx) * (y0 - sy) - (x0 - sx) * (y2 - sy)) / area;
                const double b2 = 1.0 - b0 - b1;
                if (b0 < 0 || b1 < 0 || b2 < 0) continue;
                const double z = b0 * depth[f[0]] + b1 * depth[f[1]] + b2 * depth[f[2]];
                double& zb = zbuf[size_t(y) * size_t(p.width) + size_t(x)];
                if (z <= zb) continue;
                zb = z;
                const double s = b0 * shade[f[0]] + b1 * shade[f[1]] + b2 * shade[f[2]];
                cv::Vec3b& out = img.at<cv::Vec3b>(y, x);
                for (int k = 0; k < 3; ++k) out[k] = cv::saturate_cast<uchar>(s * colour[k]);
            }
        }
    }
    return img;
}

}  // namespace meshpost
