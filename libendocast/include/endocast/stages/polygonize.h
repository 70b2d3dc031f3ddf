#pragma once
// Stage 6: polygonization (the kernel: isosurface(), marching_cubes.h).
//
// polygonize(): the paper's masked marching cubes. The endocast label region E (largest
// 6-component, enclosed holes filled) is meshed from the CT: inside E the CT is used as it is
// (sub-voxel accuracy at the bone); bone voxels (CT >= T) keep their value, nudged strictly above
// T; every other voxel outside E - filled voids and "other" empty space - is raised to T + contrast
// (contrast = T minus the median CT inside E), so the surface closes across openings midway between
// the last endocast voxel and the first other voxel, never on a grid point.
//
// SurfaceMode::HalfMax replaces the one threshold T by a local one near the boundary, the
// half-maximum-height rule of Spoor et al. (1993), the usual edge criterion for CT in physical
// anthropology: c = median CT of the region's core (voxels more than band_voxels inside it); for
// every voxel in a band of band_voxels layers on each side of the region's boundary, b = the
// largest CT within peak_radius_voxels (smallest spacing, in mm) among voxels neither in the
// region nor "other"; tau = (c + b) / 2 where b - c >= (T - c) / 2 (a bone edge), spread from there
// to the rest of the band by neighbour means (T where it does not reach), then averaged over the
// band (smoothing_passes x 3x3x3). The band is re-classified: inside the region a voxel stays
// cavity iff CT < tau; outside it a voxel with CT < tau joins when it is neither "other",
// unlabelled, next to "other" (bone beyond an opening's cut plane) nor part of a channel (a filled
// void - bone-labelled below T - joined to "other": foramina, cracks), and grows from a cavity
// face-neighbour whose CT is not above its own (uphill: it stops at the edge's peak, never crosses
// a thin wall). A voxel changes side only where that keeps the topology of the surface meshed at T
// (a simple point of the Freudenthal triangulation: no new handle, hole or piece). The cavity is
// the largest 6-component, holes filled. The surface is the zero level
// of CT - tau (CT - median tau away from the band); non-cavity voxels below tau and "other" ones
// are raised to tau - c above it, as T + contrast in the iso mode, so it is a closed 2-manifold
// that never enters "other".
#include <cstddef>
#include <string>

#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

/// Where the surface lies between the cavity and the bone.
enum class SurfaceMode {
    Iso,      ///< the isosurface at T (the paper's method)
    HalfMax,  ///< half-maximum height (Spoor et al. 1993): half-way between the cavity content and
              ///< the local bone peak, voxel by voxel near the boundary (see polygonize())
};

/// "iso" or "half-max" (the CLI parses them).
const char* to_string(SurfaceMode m);

struct PolygonizeParams {
    double isovalue = 0;            ///< T, in the CT's units
    SurfaceMode surface = SurfaceMode::Iso;
    /// HalfMax: voxels re-classified on each side of the boundary of the region segmented at T
    /// (26-connected layers).
    int band_voxels = 3;
    /// HalfMax: the local bone peak of a band voxel is the largest CT within this many voxels (of
    /// the smallest spacing, as mm).
    double peak_radius_voxels = 3;
    /// HalfMax: passes of 3x3x3 averaging of the local thresholds over the band.
    int smoothing_passes = 2;
};

/// What the half-maximum surface used (PolygonizeResult::half_max).
struct HalfMaxInfo {
    double cavity_level = 0;        ///< c: median CT of the region's core (band excluded)
    double threshold_min = 0;       ///< smallest local threshold tau in the band (after smoothing)
    double threshold_median = 0;
    double threshold_max = 0;
    size_t band_voxels = 0;         ///< voxels whose class was decided by tau
    size_t fallback_voxels = 0;     ///< band voxels without a bone edge nearby: tau = T
    size_t voxels_added = 0;        ///< cavity voxels that were not in the region segmented at T
    size_t voxels_removed = 0;      ///< region voxels at T that are not cavity at tau
};

struct PolygonizeResult {
    meshpost::TriangleMesh mesh;    ///< closed, outward oriented, world mm
    Volume<uint8_t> mask;           ///< 1 = endocast region that was meshed (input geometry)
    size_t mask_voxels = 0;
    size_t holes_filled = 0;        ///< enclosed non-endocast voxels added to the region
    size_t fragments_removed = 0;   ///< endocast voxels outside the largest component
    double other_value = 0;         ///< the value non-endocast voxels were raised to
    HalfMaxInfo half_max;           ///< SurfaceMode::HalfMax only
};

/// Meshes the kEndocast voxels of `labels` from `ct`. Throws NoResult when there are none.
template <class T>
PolygonizeResult polygonize(const Volume<T>& ct, const Volume<uint8_t>& labels,
                            const PolygonizeParams& p);

}  // namespace endocast
