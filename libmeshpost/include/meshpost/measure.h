#pragma once
// Volume, area and bounding box of a triangle mesh (world mm).
#include <array>

#include "meshpost/mesh.h"

namespace meshpost {

struct BoundingBox {
    Point min{0, 0, 0}, max{0, 0, 0};
};

/// Signed volume in mm^3 (divergence theorem); positive for a closed outward-oriented mesh.
double signed_volume_mm3(const TriangleMesh& mesh);
/// Total area in mm^2.
double surface_area_mm2(const TriangleMesh& mesh);
BoundingBox bounding_box(const TriangleMesh& mesh);
/// Area-weighted centroid of the enclosed solid (for closed meshes), mm.
Point volume_centroid(const TriangleMesh& mesh);

}  // namespace meshpost
