#pragma once
// simplify() with its guarantees checked, in the meshpost_cgal target (GPL: the self-intersection
// test uses CGAL). Each attempt simplifies the input and checks the result; when a check fails the
// next attempt starts again from the input with stricter guards (self-intersections are first
// repaired locally, see repair_locally):
//   1. the caller's parameters;
//   2. normal deviation <= 30 deg;
//   3. normal deviation <= 15 deg and aspect ratio <= 30;
//   4. normal deviation <= 8 deg and aspect ratio <= 10.
// Checks: closedness, manifoldness, orientation, components and genus as in the input; no
// degenerate face; no more self-intersecting face pairs than the input had (none for a clean input).
#include <cstddef>
#include <string>

#include "meshpost/simplify.h"
#include "meshpost/topology.h"

namespace meshpost {

struct VerifiedSimplifyResult {
    SimplifyResult simplified;            ///< the accepted attempt (or the last one when !clean)
    bool clean = false;                   ///< every check passed
    int attempts = 0;
    SimplifyParams used;                  ///< guards of the returned attempt
    TopologyReport topology_before, topology_after;
    /// Self-intersecting face pairs of the returned attempt, and of the input (counted only when an
    /// attempt had some; 0 otherwise).
    size_t self_intersections_before = 0, self_intersections_after = 0;
    std::string failure;                  ///< why the returned attempt fails a check (when !clean)
    int repair_rounds = 0;                ///< local repairs tried (see below)
    size_t locked_vertices = 0;           ///< input vertices locked by the accepted repair
};

/// Local repair, tried before stricter guards when an attempt's only defect is self-intersections:
/// the input vertices within k mean edge lengths (k = 3, 6, 12, 24) of the intersecting faces are
/// locked and the input is simplified again; the first result that passes every check is kept.
void repair_locally(const TriangleMesh& mesh, const SimplifyParams& p, VerifiedSimplifyResult& v);

/// Throws what simplify() throws.
VerifiedSimplifyResult simplify_verified(const TriangleMesh& mesh, const SimplifyParams& params);

}  // namespace meshpost
