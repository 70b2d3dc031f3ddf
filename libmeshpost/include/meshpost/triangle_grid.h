#pragma once
// TriangleGrid: the triangles of a mesh in a uniform grid of cubic cells, each cell listing the
// triangles whose bounding boxes overlap it (compressed rows). Answers "the nearest triangle to p"
// exactly by visiting the cells in rings of growing Chebyshev radius around p's cell until no
// unvisited cell can hold a closer triangle, and serves simplify()'s "is some triangle within t of
// p" queries. Built once, queried from many threads (const methods are thread-safe).
//
// Determinism: nearest() returns the smallest sq_dist_point_triangle() over all triangles (cells
// and triangles are skipped only when a lower bound exceeds the best distance by a margin far
// above rounding), so its value does not depend on the hint or the order of the queries.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "meshpost/mesh.h"

namespace meshpost {

/// Squared distance from p to triangle abc (Ericson, Real-Time Collision Detection, 5.1.5); for a
/// degenerate triangle, the smallest squared distance to its corners (an upper bound).
double sq_dist_point_triangle(const double* p, const double* a, const double* b, const double* c);

class TriangleGrid {
public:
    /// Faces of `m` in order (triangle i = face i), cells of edge `cell` mm (> 0), enlarged by
    /// x1.25 steps while the grid would have more than `max_cells` cells (0: max(2^20, 4 x faces)).
    /// Throws InvalidMesh for an out-of-range index.
    TriangleGrid(const TriangleMesh& m, double cell, size_t max_cells = 0);

    struct Tri {
        double p[3][3];  ///< corners
        double n[3];     ///< unit normal, or zero for a degenerate triangle
        double lo[3], hi[3];  ///< bounding box
    };
    size_t size() const { return tris_.size(); }
    const Tri& triangle(uint32_t i) const { return tris_[i]; }

    /// Nearest triangle to p within `max_rings` rings of cells around p's cell (the cell p falls
    /// in, clamped to the grid): true when that settles it, with `d2` the squared distance and
    /// `tri` the triangle; false when farther triangles could still be closer (d2 and tri then
    /// hold the best found so far, d2 = HUGE_VAL when none; nothing is searched when p lies more
    /// than max_rings cells outside the grid's box). `tri` on entry, when a valid index, is a hint
    /// tried first (it only makes the search faster).
    bool nearest(const double* p, int max_rings, double& d2, uint32_t& tri) const;

    /// Calls f(triangle index) for the triangles listed in the cells that overlap the box
    /// [lo, hi] (a triangle can come more than once) until f returns true; returns whether it did.
    template <class F>
    bool for_triangles_in_box(const double* lo, const double* hi, F&& f) const {
        int64_t i0[3], i1[3];
        for (int k = 0; k < 3; ++k) {
            i0[k] = clamp_index(lo[k], k);
            i1[k] = clamp_index(hi[k], k);
        }
        for (int64_t z = i0[2]; z <= i1[2]; ++z)
            for (int64_t y = i0[1]; y <= i1[1]; ++y)
                for (int64_t x = i0[0]; x <= i1[0]; ++x) {
                    const size_t c = size_t((z * n_[1] + y) * n_[0] + x);
                    for (uint32_t k = start_[c]; k < start_[c + 1]; ++k)
                        if (f(items_[k])) return true;
                }
        return false;
    }

    /// Squared distance from p to triangle i, or a number > limit2 when the triangle's bounding box
    /// or plane alone puts it beyond sqrt(limit2) (the exact distance is then not computed).
    double sq_dist_within(uint32_t i, const double* p, double limit2) const;

private:
    int64_t clamp_index(double x, int axis) const;

    std::vector<Tri> tris_;
    double lo_[3] = {0, 0, 0}, hi_[3] = {0, 0, 0};
    double cell_ = 1, inv_cell_ = 1;
    double margin_ = 0;  ///< absolute slack of the lower-bound tests (far above rounding)
    int64_t n_[3] = {1, 1, 1};
    std::vector<uint32_t> start_, items_;
};

}  // namespace meshpost
