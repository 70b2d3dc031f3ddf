#pragma once
// Combinatorial checks of a triangle mesh: closedness, manifoldness, orientation, components, genus.
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
    size_t components = 0;              ///< face-connected components
    long genus = 0;                     ///< from Euler characteristic, valid when closed && manifold
    bool closed = false;                ///< no boundary edge
    bool manifold = false;              ///< edge- and vertex-manifold
    bool oriented = false;              ///< consistently oriented (no inconsistent edge)
};

/// Analyzes the mesh combinatorics (and exact collinearity for degenerate faces).
TopologyReport analyze_topology(const TriangleMesh& mesh);

/// True when closed, manifold, consistently oriented, without degenerate faces.
bool is_closed_manifold(const TopologyReport& r);

}  // namespace meshpost
