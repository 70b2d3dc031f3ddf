#pragma once
// Volume, area and bounding box of a triangle mesh (world mm).
// Volume and centroid sum tetrahedra from the bounding-box centre (not the origin), which keeps
// them accurate for meshes far from the origin. Functions that use faces throw InvalidMesh when a
// face references a vertex index >= vertices.size().
#include <array>

#include "meshpost/mesh.h"

namespace meshpost {

struct BoundingBox {
    Point min{0, 0, 0}, max{0, 0, 0};
};

/// Signed volume in mm^3 (divergence theorem); positive for a closed outward-oriented mesh.
/// Cross product (b - a) x (c - a) of a face's corners: its normal, with length twice its area (mm^2).
Point face_cross(const TriangleMesh& mesh, const Face& f);

double signed_volume_mm3(const TriangleMesh& mesh);
/// Total area in mm^2.
double surface_area_mm2(const TriangleMesh& mesh);
/// Box of all vertices (isolated ones included); all zeros for a mesh without vertices.
BoundingBox bounding_box(const TriangleMesh& mesh);
/// Centroid of the enclosed solid (volume-weighted over signed tetrahedra; for closed meshes), mm.
/// Throws InvalidMesh when the signed volume is zero.
Point volume_centroid(const TriangleMesh& mesh);

}  // namespace meshpost
