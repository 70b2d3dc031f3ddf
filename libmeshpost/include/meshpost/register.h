#pragma once
// Rigid alignment of one triangle mesh (moving, A) to another (fixed, B) with Eigen (permissive).
//
// 1. Initial guesses: the area-weighted surface centroids and principal axes of both surfaces give
//    four proper rotations (the sign choices of the axes with determinant +1); the identity
//    rotation (centroids only) is a fifth candidate. Each runs a few ICP iterations; the one with
//    the smallest mean closest-vertex distance is kept.
// 2. Point-to-plane ICP (Chen & Medioni 1992): samples of A (its vertices, evenly thinned to at
//    most max_samples) are paired with their nearest vertex of B (k-d tree) and that vertex's
//    area-weighted normal; pairs farther than `reject_factor` times the median pair distance are
//    dropped; the linearised 6x6 system gives a small rotation and translation, applied exactly
//    (Rodrigues). Stops when an update moves no sample by more than `tolerance_mm`.
// Deterministic: nearest-neighbour queries run in parallel (OpenMP) into per-sample slots and the
// sums are accumulated sequentially.
#include <array>
#include <cstddef>

#include "meshpost/mesh.h"

namespace meshpost {

/// x -> rotation * x + translation (mm).
struct RigidTransform {
    std::array<std::array<double, 3>, 3> rotation{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};  ///< row-major
    Point translation{0, 0, 0};
    Point apply(const Point& p) const;
    /// Rotation angle in degrees (0..180).
    double angle_deg() const;
};

struct RegisterParams {
    size_t max_samples = 50000;       ///< samples of A used by ICP
    int max_iterations = 100;         ///< ICP iterations after the initial guess
    int guess_iterations = 8;         ///< ICP iterations to rank each initial guess
    double tolerance_mm = 1e-7;       ///< stop when no sample moves by more than this
    double reject_factor = 3.0;       ///< drop pairs farther than this times the median distance
    bool principal_axes = true;       ///< try the principal-axes guesses (else centroids only)
};

struct RegisterResult {
    RigidTransform transform;         ///< maps A onto B
    double rmse_mm = 0;               ///< RMS point-to-plane distance of the kept pairs at the end
    double mean_distance_mm = 0;      ///< mean closest-vertex distance of all samples at the end
    int iterations = 0;               ///< ICP iterations after the initial guess
    size_t samples = 0, pairs = 0;    ///< samples of A, pairs kept in the last iteration
    bool converged = false;
};

/// Aligns `moving` (A) to `fixed` (B) rigidly. Throws InvalidMesh when a mesh has no faces, a face
/// index is out of range, a coordinate is not finite, or a surface has zero area.
RegisterResult register_rigid(const TriangleMesh& moving, const TriangleMesh& fixed, const RegisterParams& params = {});

/// A copy of `mesh` with every vertex mapped by `t`.
TriangleMesh transformed(const TriangleMesh& mesh, const RigidTransform& t);

}  // namespace meshpost
