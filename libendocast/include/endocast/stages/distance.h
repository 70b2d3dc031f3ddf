#pragma once
// Exact Euclidean distance transforms on anisotropic grids.
//
// Algorithm: Felzenszwalb & Huttenlocher, "Distance Transforms of Sampled Functions" (Theory of
// Computing 8, 2012): the squared distance transform is separable; along each line it is the lower
// envelope of parabolas f(p) + (w*(q-p))^2, found in linear time. Three passes (x, y, z), each
// parallel over lines with OpenMP; the cost is O(V) whatever the distances, and each line is
// computed in double and stored as float. The result does not depend on the thread count.
#include <cstdint>

#include "endocast/volume.h"

namespace endocast {

/// Squared distance (mm^2) from each voxel centre to the nearest voxel centre whose `feature` value
/// is non-zero, using the volume's spacing. Feature voxels get 0; when there is no feature voxel at
/// all, every voxel gets +infinity. Voxels outside the volume are not features.
Volume<float> squared_distance_transform(const Volume<uint8_t>& feature);

/// Euclidean distance (mm) to the nearest non-zero voxel of `feature` (sqrt of the above).
Volume<float> distance_transform(const Volume<uint8_t>& feature);

/// Squared distance (mm^2) to the nearest voxel where (mask != 0) != invert, except that every value
/// above `clamp_mm2` is +infinity. A value is <= t (for any t <= clamp_mm2) exactly when the true
/// squared distance is; lines of the grid far from the features are skipped, so thresholded
/// transforms (ball morphology) are faster than a full transform.
Volume<float> squared_distance_transform_clamped(const Volume<uint8_t>& mask, bool invert,
                                                 float clamp_mm2);

/// Generalized squared distance transform in place: f(x) <- min_y ( f(y) + |x - y|^2_mm ), over all
/// voxels y of the grid `g`. Entries may be +infinity (no parabola) or negative (used for unions of
/// balls of varying radius: f0(b) = -r_b^2 gives f(x) <= 0 exactly on the union of the balls).
void generalized_squared_distance(std::vector<float>& f, const Geometry& g);

}  // namespace endocast
