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
#include <cstdint>
#include <memory>

#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

/// Fraction of an edge kept free at each end when placing vertices.
constexpr double kEdgeClamp = 1e-3;

/// Level set of f at iso, vertices in world mm (f's geometry). Throws InvalidParameter for a
/// non-finite iso.
meshpost::TriangleMesh isosurface(const Volume<float>& f, double iso);

/// isosurface() fed the field a slab of sample planes at a time, in order, so that a field larger
/// than memory (microCT at full resolution) is never held whole: the result is the same mesh, vertex
/// for vertex and face for face, as isosurface() on the whole field. Cube layer z spans planes z
/// and z + 1; the layers run from -1 to nz - 1 (the first and last close the surface at the border).
class IsosurfaceStream {
public:
    /// `grid`: the whole field's geometry (its dims, and the world placement of the vertices).
    /// Throws InvalidParameter for a non-finite iso.
    IsosurfaceStream(const Geometry& grid, double iso);
    ~IsosurfaceStream();
    IsosurfaceStream(const IsosurfaceStream&) = delete;
    IsosurfaceStream& operator=(const IsosurfaceStream&) = delete;

    /// Meshes the cube layers from next_layer() up to `layer_end` (exclusive; nz meshes the rest).
    /// `planes` holds the field's planes [z_first, z_first + planes.nz()) with the grid's nx x ny
    /// samples, and must hold every plane inside the grid those layers touch. Throws
    /// InvalidParameter otherwise.
    void add(const Volume<float>& planes, int64_t z_first, int64_t layer_end);
    /// The first cube layer not meshed yet (-1 at the start).
    int64_t next_layer() const;
    /// The mesh (world mm, as isosurface()). Throws InvalidParameter unless every layer was meshed.
    meshpost::TriangleMesh finish();

private:
    struct State;
    std::unique_ptr<State> s_;
};

}  // namespace endocast
