// Volume, area, bounding box and centroid of a triangle mesh.
#include "meshpost/measure.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace meshpost {
namespace {

void check_indices(const TriangleMesh& mesh, const char* fn) {
    const size_t nv = mesh.vertices.size(), f = first_face_with_bad_index(mesh);
    if (f == mesh.faces.size()) return;
    for (uint32_t v : mesh.faces[f])
        if (v >= nv)
            throw InvalidMesh(std::string(fn) + ": face " + std::to_string(f) + " references vertex " +
                              std::to_string(v) + " but the mesh has " + std::to_string(nv) + " vertices");
}

// The sum over the faces of term(face), the terms on all threads, added in face order on one (the
// same sum as a loop over the faces).
template <class Term>
double sum_over_faces(const TriangleMesh& mesh, Term term) {
    const int64_t nf = int64_t(mesh.faces.size());
    std::vector<double> t(mesh.faces.size());
#pragma omp parallel for schedule(static)
    for (int64_t f = 0; f < nf; ++f) t[size_t(f)] = term(mesh.faces[size_t(f)]);
    double sum = 0.0;
    for (double x : t) sum += x;
    return sum;
}

Point bbox_centre(const TriangleMesh& mesh) {
    const BoundingBox b = bounding_box(mesh);
    return {0.5 * (b.min[0] + b.max[0]), 0.5 * (b.min[1] + b.max[1]), 0.5 * (b.min[2] + b.max[2])};
}

/// Six times the signed volume of the tetrahedron (ref, a, b, c), with coordinates relative to ref.
double det6(const Point& ref, const Point& a, const Point& b, const Point& c) {
    const double ax = a[0] - ref[0], ay = a[1] - ref[1], az = a[2] - ref[2];
    const double bx = b[0] - ref[0], by = b[1] - ref[1], bz = b[2] - ref[2];
    const double cx = c[0] - ref[0], cy = c[1] - ref[1], cz = c[2] - ref[2];
    return ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx);
}

}  // namespace

double signed_volume_mm3(const TriangleMesh& mesh) {
    check_indices(mesh, "signed_volume_mm3");
    const Point ref = bbox_centre(mesh);
    const double sum = sum_over_faces(
        mesh, [&](const Face& f) { return det6(ref, mesh.vertices[f[0]], mesh.vertices[f[1]], mesh.vertices[f[2]]); });
    return sum / 6.0;
}

Point face_cross(const TriangleMesh& mesh, const Face& f) {
    const Point& a = mesh.vertices[f[0]];
    const Point& b = mesh.vertices[f[1]];
    const Point& c = mesh.vertices[f[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    return {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
}

double surface_area_mm2(const TriangleMesh& mesh) {
    check_indices(mesh, "surface_area_mm2");
    const double sum = sum_over_faces(mesh, [&](const Face& f) {
        const Point n = face_cross(mesh, f);
        return std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    });
    return 0.5 * sum;
}

BoundingBox bounding_box(const TriangleMesh& mesh) {
    BoundingBox b;
    if (mesh.vertices.empty()) return b;
    b.min = b.max = mesh.vertices.front();
    for (const Point& p : mesh.vertices) {
        for (int i = 0; i < 3; ++i) {
            b.min[i] = std::min(b.min[i], p[i]);
            b.max[i] = std::max(b.max[i], p[i]);
        }
    }
    return b;
}

Point volume_centroid(const TriangleMesh& mesh) {
    check_indices(mesh, "volume_centroid");
    const Point ref = bbox_centre(mesh);
    double vol6 = 0.0;
    double m[3] = {0.0, 0.0, 0.0};
    for (const Face& f : mesh.faces) {
        const Point& a = mesh.vertices[f[0]];
        const Point& b = mesh.vertices[f[1]];
        const Point& c = mesh.vertices[f[2]];
        const double d = det6(ref, a, b, c);
        vol6 += d;
        // Tetrahedron centroid relative to ref: (a + b + c - 3 ref) / 4.
        for (int i = 0; i < 3; ++i) m[i] += d * (a[i] + b[i] + c[i] - 3.0 * ref[i]);
    }
    if (!(std::fabs(vol6) > 0.0) || !std::isfinite(vol6))
        throw InvalidMesh("volume_centroid: the mesh encloses zero volume (not closed, or empty)");
    return {ref[0] + m[0] / (4.0 * vol6), ref[1] + m[1] / (4.0 * vol6), ref[2] + m[2] / (4.0 * vol6)};
}

}  // namespace meshpost
