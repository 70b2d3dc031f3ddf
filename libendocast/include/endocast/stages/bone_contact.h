#pragma once
// Bone contact: the share of an endocast mesh's area that lies on bone.
//
// An endocast traced on the inner surface of the braincase has bone just outside it everywhere,
// except across the openings (foramen magnum, canals), where the extraction closes the surface by
// a cap over empty space, and where the surface leaks out of the braincase. For each face, the CT
// is sampled `offset_mm` outside it: from the face's centroid along its outward unit normal
// (faces counter-clockwise seen from outside), by trilinear interpolation between voxel centres
// in the CT's world geometry (origin, spacing and direction, Volume<T>'s index_to_world). The
// face is on bone when that value is >= the isovalue. A point outside the box of voxel centres
// is not on bone. bone_contact = area of the faces on bone / area of all faces.
//
// A closed braincase endocast scores close to 1; every closed opening lowers it by the area of
// its cap over the total area, and so does a leak. With the segmentation's labels given, a face is
// on bone also where its sample lies in a voxel labelled bone: the skull as segmented, with the
// thin-bone ridges and the void fill's voxels (at 10-150 um a mouse's wall is 1-3 voxels, much of
// it blurred below the isovalue).
#include <cstdint>
#include <array>
#include <vector>

#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

struct BoneContactParams {
    /// Distance (mm) outside each face at which the CT is sampled; >= 0 and finite. It must clear
    /// the partial-volume layer (a voxel) and stay within the wall: the pipeline's default (0 in
    /// ExtractParams) is max(smallest spacing, depth / 50), 1 mm for a human braincase (depth
    /// ~50 mm) and a voxel for a mouse's (depth ~3 mm) at 10-150 um.
    double offset_mm = 1.0;
};

struct BoneContact {
    double share = 0;              ///< area_on_bone_mm2 / area_mm2, in [0, 1]; 0 for no area
    double area_on_bone_mm2 = 0;   ///< area of the faces on bone (mm^2)
    double area_mm2 = 0;           ///< area of all faces (mm^2)
    /// Per face of the mesh: 1 = on bone, 0 = not (a closing surface across an opening, a leak,
    /// a sample outside the volume, or a face of zero area, which has no normal).
    std::vector<uint8_t> face_on_bone;
};

/// Measures the bone contact of `mesh` (world mm, outward faces) in `ct` at `isovalue` (scan
/// units). An empty CT or an empty mesh gives share 0. Parallel (OpenMP) and deterministic: the
/// same bytes for any thread count (areas summed per fixed chunk of faces, chunks in order).
/// Throws InvalidParameter for a negative or non-finite offset, or a face that references a
/// vertex beyond the mesh's vertices.
template <class T>
BoneContact bone_contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                         const BoneContactParams& p = {});

/// bone_contact of the mesh after the vertices `moved` moved (the faces unchanged): the faces
/// around them are sampled again, every other face keeps its flag in `before` (bone_contact's
/// face_on_bone for the mesh before the move, the same CT, isovalue and parameters). The same
/// result, bit for bit, as bone_contact of the moved mesh, for a fraction of its samples.
/// Throws InvalidParameter as bone_contact, or when `before` has another size than the faces or a
/// moved vertex is beyond the mesh.
template <class T>
BoneContact bone_contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                         const BoneContactParams& p, const std::vector<uint8_t>& before,
                         const std::vector<uint32_t>& moved);

/// A closing surface: an edge-connected patch of faces not on bone (a cap across an opening, the
/// surface across a thin-bone gap, a leak).
struct ClosingSurface {
    Vec3 centre{0, 0, 0};    ///< area-weighted centroid (world mm)
    Vec3 normal{0, 0, 0};    ///< area-weighted mean of the outward face normals, unit (0 if they cancel)
    double area_mm2 = 0;
};

/// bone_contact with the skull as segmented (`skull`: the voxels labelled kBone, on the CT's grid):
/// a face whose sample lies in a skull voxel (the nearest voxel centre) is on bone too. Throws
/// InvalidParameter as bone_contact, or when `skull` is not on the CT's grid.
template <class T>
BoneContact bone_contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                         const BoneContactParams& p, const PackedMask& skull);

/// The patches of faces with face_on_bone == 0 (edge-connected: meshpost::face_patches over
/// face_neighbours, so on a 2-manifold) of at least min_area_mm2, largest first (ties: in order of
/// their first face); a face beyond face_on_bone counts as on bone. Deterministic. Throws
/// meshpost::InvalidMesh for a face that references a vertex beyond the mesh.
std::vector<ClosingSurface> closing_surfaces(const meshpost::TriangleMesh& mesh,
                                             const std::vector<uint8_t>& face_on_bone, double min_area_mm2);

/// The same with the faces' edge neighbours given (meshpost::face_neighbours of this mesh).
/// Throws meshpost::InvalidMesh also when they are not one triple per face.
std::vector<ClosingSurface> closing_surfaces(const meshpost::TriangleMesh& mesh,
                                             const std::vector<uint8_t>& face_on_bone, double min_area_mm2,
                                             const std::vector<std::array<uint32_t, 3>>& neighbours);

}  // namespace endocast
