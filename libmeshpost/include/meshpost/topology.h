#pragma once
// Combinatorial checks of a triangle mesh: closedness, manifoldness, orientation, components, genus.
//
// Conventions:
// - Faces with a repeated vertex index count as degenerate_faces and are otherwise left out of the
//   edge, fan, component and genus analysis. Faces whose three points are exactly collinear (exact
//   arithmetic; assumes no floating-point overflow/underflow in the coordinate differences and
//   products) or have a non-finite coordinate also count as degenerate but take part in the rest.
// - Edges are undirected vertex pairs of the (non-repeated) faces.
// - A vertex's fans are its incident faces connected through manifold edges (exactly two faces,
//   whatever their orientation) incident to the vertex. A vertex on a non-manifold edge is therefore
//   usually counted as a non-manifold vertex too.
// - Components are connected through shared edges (not through a shared vertex alone): two cubes
//   touching at one corner are 2 components with 1 non-manifold vertex.
// - O(F + V) apart from sorting the few edges around each vertex.
#include <cstddef>

#include "meshpost/mesh.h"

namespace meshpost {

struct TopologyReport {
    size_t vertices = 0, faces = 0, edges = 0;
    size_t boundary_edges = 0;          ///< edges with one incident face
    size_t nonmanifold_edges = 0;       ///< edges with more than two incident faces
    size_t nonmanifold_vertices = 0;    ///< vertices whose incident faces form more than one fan
    size_t inconsistent_edges = 0;      ///< manifold edges whose two faces traverse it the same way
    size_t isolated_vertices = 0;       ///< vertices used by no face
    size_t degenerate_faces = 0;        ///< repeated vertex index or zero area (exactly collinear)
    size_t components = 0;              ///< edge-connected components of the faces
    /// Sum over the closed, edge- and vertex-manifold components of (2 - (V - E + F)) / 2 (Euler).
    /// Components with a boundary or non-manifold element are left out. Meaningful for orientable
    /// surfaces (face orientation itself does not change it).
    long genus = 0;
    bool closed = false;                ///< no boundary edge (and at least one face)
    bool manifold = false;              ///< edge- and vertex-manifold
    bool oriented = false;              ///< manifold and consistently oriented (no inconsistent edge)
};

/// Analyzes the mesh combinatorics (and exact collinearity for degenerate faces):
/// analyze_connectivity plus count_collinear_faces.
/// Throws InvalidMesh when a face references a vertex index >= vertices.size().
TopologyReport analyze_topology(const TriangleMesh& mesh);

/// analyze_topology from the faces alone: of the vertices only their number is read, so it may run
/// on one thread while another moves them (the faces and the number of vertices fixed).
/// degenerate_faces counts only the faces with a repeated index; add count_collinear_faces of the
/// final positions for analyze_topology's count. One thread. Throws as analyze_topology.
TopologyReport analyze_connectivity(const TriangleMesh& mesh);

/// The faces with three distinct vertex indices whose points are exactly collinear (zero area) or
/// have a non-finite coordinate: the rest of analyze_topology's degenerate_faces. All threads.
/// Throws InvalidMesh when a face references a vertex index >= vertices.size().
size_t count_collinear_faces(const TriangleMesh& mesh);

/// True when closed, manifold, consistently oriented, without degenerate faces.
bool is_closed_manifold(const TopologyReport& r);

/// Genus of the part of a manifold mesh inside a ball: the faces whose three vertices lie within
/// `radius` of `centre`, taken as a surface with boundary, (2 C - B - (V - E + F)) / 2 with C its
/// edge-connected components and B its boundary loops. Finds a handle near a point (e.g. at an
/// opening of the endocast). Approximate where the patch is not a manifold surface (two boundary
/// loops touching at a vertex count as one); 0 for an empty patch.
long genus_within_ball(const TriangleMesh& mesh, const Point& centre, double radius);

}  // namespace meshpost
