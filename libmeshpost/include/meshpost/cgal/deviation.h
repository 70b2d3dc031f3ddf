#pragma once
// Surface-to-surface deviation between two triangle meshes (e.g. an automatic endocast against a
// manual segmentation), as in Michikawa et al. 2017, Fig 8. Implemented in meshpost_cgal (GPL):
// exact point-to-triangle distances from a TriangleGrid (triangle_grid.h), and from CGAL's AABB
// tree for points more than 3 grid cells (mean edge lengths) from the other surface.
//
// Sampling: every face of a mesh is split into n x n congruent sub-triangles and sampled at each
// sub-triangle's centroid. Each sample stands for its sub-triangle (weight = its area); statistics
// are area-weighted, so they estimate the surface integrals independently of the tessellation. The
// distance to the other surface is 1-Lipschitz, and every point of a face lies within
// r = (2/3) * (longest median of its sub-triangle) of a sample, so the true maximum (and the
// Hausdorff distance) exceeds the sampled one by at most `sampling_error_bound_mm` (the largest r
// over all faces); mean, rms and the quantiles are off by at most the same amount. The bound is
// the one that splitting every face of both meshes with n = ceil(longest edge / h) gives (so it is
// <= 2h/3); each face then gets the smallest n, no larger than that, that keeps its r within it.
//
// Deterministic: distances are computed in parallel (OpenMP) into per-sample slots and reduced
// sequentially in sample order, so results are identical for any thread count.
#include <cstddef>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

struct DeviationParams {
    /// Sample spacing h in mm (> 0), or 0 for automatic: h = sqrt(area / target_samples) of the
    /// larger of the two surfaces (every face gets at least one sample whatever h).
    double sample_spacing_mm = 0.0;
    /// Used when sample_spacing_mm == 0 to set h. The samples taken are more: each face is split
    /// into n x n (see above), at least one per face (a simplified cthead endocast against its
    /// input: about 2.5 million per side for 400,000).
    size_t target_samples = 400000;
    /// Compute the median and p95 (false: they are left 0; saves two weighted selections over
    /// the samples of each side, which are not parallel).
    bool quantiles = true;
    /// Keep the per-sample distances and weights (for histograms).
    bool keep_samples = false;
    /// Compute the distance of each vertex of A to B (for colouring A).
    bool vertex_distances = false;
};

/// Area-weighted statistics of the distances from the samples of one surface to the other, mm.
struct DistanceStats {
    size_t samples = 0;
    double mean = 0, rms = 0, median = 0, p95 = 0, max = 0;
};

struct DeviationResult {
    DistanceStats a_to_b, b_to_a;
    double hausdorff_mm = 0;              ///< max(a_to_b.max, b_to_a.max) (sampled)
    double sample_spacing_mm = 0;         ///< h used
    double sampling_error_bound_mm = 0;   ///< true max/Hausdorff <= sampled + this
    /// With keep_samples: per-sample distances and weights (mm, mm^2), in sample order.
    std::vector<double> a_distances, a_weights, b_distances, b_weights;
    /// With vertex_distances: distance of vertex i of A to surface B, mm.
    std::vector<double> a_vertex_distances;
};

struct HausdorffParams {
    /// Sample spacing h in mm (> 0), or 0 for automatic, as DeviationParams: the error bound is
    /// the one surface_deviation would have with it (<= 2h/3).
    double sample_spacing_mm = 0.0;
    size_t target_samples = 400000;  ///< as DeviationParams::target_samples
};

struct HausdorffResult {
    double hausdorff_mm = 0;              ///< the largest distance found (<= the true one)
    double sampling_error_bound_mm = 0;   ///< true Hausdorff <= hausdorff_mm + this
    /// Area-weighted means of the distances of the faces' centroids to the other surface, mm
    /// (estimates of the mean distances; a face is one sample).
    double mean_a_to_b_mm = 0, mean_b_to_a_mm = 0;
    size_t points = 0;                    ///< distances computed
};

/// The Hausdorff distance between the surfaces of `a` and `b` with surface_deviation's error
/// bound, from far fewer distances. First the distances of every vertex of both meshes; their
/// largest, M, is a lower bound of the Hausdorff distance. Then each face is split in 4
/// recursively, its corners' distances computed, until each piece is proven within M of the
/// other surface (its corners within M - R of it, R the piece's cover radius, the distance being
/// 1-Lipschitz; or its corners within M of one triangle, the distance to which is convex) or its
/// cover radius is within the bound (a sampled piece). Every point of a mesh then lies within
/// max(M, largest distance computed + bound) of the other. Deterministic (per-face results
/// reduced in face order, nearest triangles independent of the search order). Same input
/// requirements and exceptions as surface_deviation.
HausdorffResult hausdorff_distance(const TriangleMesh& a, const TriangleMesh& b, const HausdorffParams& params = {});

/// Distances between the surfaces of `a` and `b` in both directions. Both meshes need at least one
/// non-degenerate face; any mesh works otherwise (open, non-manifold). Throws InvalidMesh for an
/// empty mesh, an out-of-range face index or a non-finite coordinate, and std::invalid_argument for
/// a negative spacing or a spacing so small that more than 100 million samples would be needed.
DeviationResult surface_deviation(const TriangleMesh& a, const TriangleMesh& b, const DeviationParams& params = {});

}  // namespace meshpost
