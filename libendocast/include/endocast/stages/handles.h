#pragma once
// Handles of the endocast region, and closing them where they are thinnest.
//
// The mesh of the endocast region E is the boundary of E's full subcomplex in the Freudenthal
// triangulation that the polygonizer contours, so its genus is that of E in that triangulation.
// A braincase is a ball: a handle is a defect, e.g. a thin bony shelf inside the cavity (the
// lesser wing of the sphenoid, an orbital roof) blurred below the isovalue in one place, so that
// the cavity runs around the shelf's edge and through the gap. close_handles grows a ball inside E
// from its deepest voxel, a simple point at a time in order of decreasing distance to bone, so a
// loop of E closes last where it is narrowest: the voxels never added (a membrane one voxel thick
// across each handle's narrowest section, e.g. across the gap in the shelf) leave E.
#include <cstddef>
#include <cstdint>

#include "endocast/volume.h"

namespace endocast {

/// Euler characteristic of the voxels of `labels` equal to `label` in the Freudenthal triangulation
/// (vertices - edges + triangles - tetrahedra of their full subcomplex): components - handles +
/// enclosed voids. 1 for a set shaped like a ball. Deterministic, parallel.
long freudenthal_euler_characteristic(const Volume<uint8_t>& labels, uint8_t label);

struct HandleClosing {
    long euler_before = 1;      ///< Euler characteristic of E before (1: a ball, nothing done)
    long euler_after = 1;
    size_t voxels_closed = 0;   ///< E voxels that left E (relabelled kBone)
    /// Voxels changed first to make E what the polygonizer meshes (its largest face-connected
    /// piece, enclosed holes filled), so that no handle hides behind a void or a second piece.
    size_t voxels_matched = 0;
};

/// First makes E (labels == kEndocast) what the polygonizer meshes: its largest face-connected
/// piece (the others become kBone), its enclosed holes filled (kEndocast). Then, when E is not
/// ball-shaped (Euler characteristic != 1), grows a ball in E
/// from `seed` (an E voxel index in `labels`, e.g. the deepest) by simple points in order of
/// decreasing `distance` (mm, the distance to bone; any grid holding E's voxels: `distance_origin`
/// is the index in `labels` of its voxel (0, 0, 0)); E voxels not reached become kBone. The grown set
/// is connected and without handles or voids, so its mesh has genus 0; E pieces not joined to the
/// seed's are dropped too. Serial (the same result for any thread count).
HandleClosing close_handles(Volume<uint8_t>& labels, size_t seed, const Volume<float>& distance,
                            const std::array<int64_t, 3>& distance_origin);

}  // namespace endocast
