#pragma once
// Stage 6: polygonization.
//
// isosurface(): the level set {f = iso} of the piecewise-linear interpolant of f on the Freudenthal
// (Kuhn) subdivision of each grid cube into six tetrahedra around its main diagonal - marching cubes
// made unambiguous. Because the subdivision is a valid triangulation of the whole grid, the surface
// is, by construction, a closed 2-manifold without self-intersections when no sample equals iso;
// vertices are placed on cube and tetrahedron edges by linear interpolation, clamped to
// [kEdgeClamp, 1-kEdgeClamp] of the edge so that no triangle degenerates. Inside = f < iso; faces
// are oriented so that normals point toward f > iso. Samples outside the volume count as outside.
//
// polygonize(): the paper's masked marching cubes. The endocast label region E (largest
// 6-component, enclosed holes filled) is meshed from the CT: inside E the CT is used as it is
// (sub-voxel accuracy at the bone); bone voxels (CT >= T) keep their value, nudged strictly above
// T; every other voxel outside E - filled voids and "other" empty space - is raised to T + contrast
// (contrast = T minus the median CT inside E), so the surface closes across openings midway between
// the last endocast voxel and the first other voxel, never on a grid point.
#include <cstddef>

#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

/// Fraction of an edge kept free at each end when placing vertices.
constexpr double kEdgeClamp = 1e-3;

/// Level set of f at iso, vertices in world mm (f's geometry). Throws InvalidParameter for a
/// non-finite iso.
meshpost::TriangleMesh isosurface(const Volume<float>& f, double iso);

struct PolygonizeParams {
    double isovalue = 0;            ///< T, in the CT's units
};

struct PolygonizeResult {
    meshpost::TriangleMesh mesh;    ///< closed, outward oriented, world mm
    Volume<uint8_t> mask;           ///< 1 = endocast region that was meshed (input geometry)
    size_t mask_voxels = 0;
    size_t holes_filled = 0;        ///< enclosed non-endocast voxels added to the region
    size_t fragments_removed = 0;   ///< endocast voxels outside the largest component
    double other_value = 0;         ///< the value non-endocast voxels were raised to
};

/// Meshes the kEndocast voxels of `labels` from `ct`. Throws NoResult when there are none.
PolygonizeResult polygonize(const Volume<float>& ct, const Volume<uint8_t>& labels,
                            const PolygonizeParams& p);

}  // namespace endocast
