#pragma once
// Marching cubes, unambiguous (the polygonizer's kernel; polygonize.h is the method's stage on it).
//
// isosurface(): the level set {f = iso} of the piecewise-linear interpolant of f on the Freudenthal
// (Kuhn) subdivision of each grid cube into six tetrahedra around its main diagonal - marching cubes
// made unambiguous. Because the subdivision is a valid triangulation of the whole grid, the surface
// is, by construction, a closed 2-manifold without self-intersections when no sample equals iso;
// vertices are placed on cube and tetrahedron edges by linear interpolation, clamped to
// [kEdgeClamp, 1-kEdgeClamp] of the edge so that no triangle degenerates. Inside = f < iso; faces
// are oriented so that normals point toward f > iso. Samples outside the volume count as outside.
#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

/// Fraction of an edge kept free at each end when placing vertices.
constexpr double kEdgeClamp = 1e-3;

/// Level set of f at iso, vertices in world mm (f's geometry). Throws InvalidParameter for a
/// non-finite iso.
meshpost::TriangleMesh isosurface(const Volume<float>& f, double iso);

}  // namespace endocast
