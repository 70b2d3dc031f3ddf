#pragma once
// The coarse-to-fine path of `extract`: a scan too large for the method's memory (microCT, 2048 x
// 2048 x 1500 voxels) meshed on its own grid, a slab of planes at a time.
//
// The method (extract_endocast) runs first on the scan block-averaged by a factor F (the coarse
// grid): the void fill, the distances, the seeds, the watershed and the closures (openings, creases,
// handles), all in mm on that grid. Its region E_c is then refined on the scan's own grid, where the
// wall is: the fine voxels of the band - region voxels within band_coarse_voxels of its boundary,
// and bone voxels (label kBone with the coarse CT >= T: not the void fill's plugs, nor thin bone
// below T) within as many voxels of it - are endocast where the fine CT is below T; the fine voxels
// of the region's core are endocast whatever their CT (as polygonize() fills the region's holes),
// the others are not. The wall is then the full-resolution isosurface, and the cuts across the
// openings stay where the coarse method put them (on the faces between coarse voxels).
// Where the coarse mesh closes an opening (its faces not on bone: bone_contact.h), the closure was
// moved at the mesh (flush_dips raises a closure sunk into a plugged hole to its rim): the fine
// voxels of the band near such faces are endocast only inside the coarse mesh too, so that the
// refined surface keeps the coarse closure there.
// The field is meshed as polygonize() meshes it (SurfaceMode::Iso), a slab of planes at a time
// (IsosurfaceStream), reading each plane once; only the box of the core and the band is processed.
// Mesh components other than the largest (bubbles: pores of the bone layer that do not open into
// the cavity at full resolution, bone specks within the band) are dropped.
#include <cstdint>
#include <functional>
#include <vector>

#include "endocast/stages/resample.h"
#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

/// Fills `dst` (nx * ny floats, x fastest) with plane z of the fine volume, in the scan's units.
using PlaneReader = std::function<void(int64_t z, float* dst)>;

/// What the fine pass does with the fine voxels of a coarse voxel.
enum RefineClass : uint8_t {
    kRefineOut = 0,      ///< not endocast
    kRefineCore = 1,     ///< endocast whatever the fine CT
    kRefineBandIn = 2,   ///< a region voxel of the band: endocast where the fine CT < T
    kRefineBandBone = 3, ///< a bone voxel of the band: endocast where the fine CT < T
    /// Flag on the band's classes: near a closing face of the coarse mesh, also only inside it.
    kRefineClip = 0x80,
};

/// The classes of the coarse voxels (see the top of this file): `region` = ExtractionResult::mask,
/// `labels` = ExtractionResult::labels (ExtractParams::keep_labels), `ct` the coarse CT, `T` the
/// isovalue, `band_coarse_voxels` the band's half-width (box distance). `mesh` and `face_on_bone`
/// (ExtractionResult::mesh and ::face_on_bone; may be empty): the band's voxels within a voxel of
/// a closing face's corner get kRefineClip. Throws InvalidParameter when the volumes differ in
/// size, face_on_bone does not match the mesh, or the band is < 1.
Volume<uint8_t> refine_classes(const Volume<uint8_t>& region, const Volume<uint8_t>& labels, const Volume<float>& ct,
                               double T, const meshpost::TriangleMesh& mesh, const std::vector<uint8_t>& face_on_bone,
                               int band_coarse_voxels = 2);

struct RefineParams {
    double isovalue = 0;             ///< T (scan units)
    /// Value of the empty voxels outside the region (ExtractionResult::other_value of the coarse
    /// run: T + the cavity's contrast).
    double other_value = 0;
    int64_t slab_planes = 64;        ///< fine planes per slab
    /// The coarse mesh (world mm) that kRefineClip voxels must lie inside; required when the
    /// classes hold kRefineClip.
    const meshpost::TriangleMesh* clip_mesh = nullptr;
    /// Called after each slab with the fine planes done and their total.
    std::function<void(int64_t done, int64_t total)> progress;
};

struct RefineResult {
    meshpost::TriangleMesh mesh;     ///< closed, outward, world mm, on the fine grid
    CropBox box;                     ///< fine voxels processed (the core's and the band's box)
    size_t slabs = 0;
    size_t band_voxels = 0;          ///< fine voxels decided by the fine CT
    size_t band_endocast_voxels = 0; ///< of those, endocast
    size_t changed_voxels = 0;       ///< band voxels on the other side than their coarse voxel
    size_t clipped_voxels = 0;       ///< band voxels below T left out as outside the coarse mesh
    size_t region_voxels = 0;        ///< fine voxels of the refined region
    size_t pieces_removed = 0;       ///< mesh components dropped (all but the largest)
    double region_volume_ml = 0;     ///< region_voxels x the fine voxel volume
};

/// Refines the region on the grid `fine`, reading its planes through `read`; `classes` =
/// refine_classes() on downsampled_geometry(fine, factor). Throws InvalidParameter when the grids
/// do not match or a parameter is out of range, NoResult when no voxel is endocast.
RefineResult refine_full_resolution(const Geometry& fine, const PlaneReader& read, const Volume<uint8_t>& classes,
                                    int factor, const RefineParams& p);

}  // namespace endocast
