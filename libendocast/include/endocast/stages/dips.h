#pragma once
// Closing surfaces that dip into a hole, made flush with its rim.
//
// The void fill (morphology.h) plugs each hole in the bone up to ~2r wide (r its ball's radius:
// the jugular foramen, 15 x 10 mm, the foramina ovale and lacerum), and the plug's face toward the
// cavity is where the cavity's balls rest on the hole's rim: a cap dipping into the hole,
// r - sqrt(r^2 - (w/2)^2) deep for a hole w wide (2.7 mm for 10 mm with the paper's 6 voxels of
// 1 mm). The mesh follows it, so the opening is closed beyond the inner table. flush_dips takes
// each patch of the mesh not on bone (bone_contact.h's face_on_bone: a closing surface) that is a
// disk of at most max_area_mm2, moves its inner vertices onto the membrane spanning its rim (the
// vertices it shares with faces on bone, on the inner table; meshpost/fair.h), and keeps that
// when the patch was a dip: its vertices move into the cavity (against the patch's outward
// normal) and none farther than the void fill's ball can dip. A patch on bone's side of its
// membrane (a crease, a fossa's floor of thin bone) is left as it is, and so is every face on bone.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast {

struct DipParams {
    bool enabled = true;
    /// A patch is a dip when the volume between it and its membrane, over its area, is at least
    /// this many voxels (of the grid's smallest spacing): shallower patches are left as they are.
    double min_mean_depth_voxels = 0.1;
    /// The patch is grown by this many rings of faces across its edges before its membrane is
    /// solved: the faces on bone along a hole's rim, rounded by the scanner's blur, whose sample
    /// 1 mm out hits the hole's wall although they lie below the inner table.
    int rim_rings = 2;
    /// Where the membrane of a patch would cross the mesh, it is tried again with up to this many
    /// more rim rings (the crossing is often a fold next to the patch, where its rim turns
    /// sharply: the tilted dry skull-base phantom's right foramen lacerum, 3.20 -> 2.09 mm
    /// outside), before the wall rings are halved.
    int rim_rings_retry = 2;
    /// Before the rim rings, the patch is grown by up to this many rings of faces steep to its
    /// mean normal N (|n . N| < wall_max_cosine): the wall of an oblique hole, down which the dip
    /// runs on one side, so that the membrane spans the rim above it on the inner table. A face
    /// joins only when it lies no farther out along N than the face it is reached from (plus
    /// wall_climb_voxels of the grid's smallest spacing: the walk climbs toward the cavity, not
    /// down into a crease beside the hole) and within the patch's footprint seen along N (its
    /// widest reach from its centre, times wall_footprint: 1.5, as a narrow canal's mouth, into
    /// which the dip runs as a spike, has its walls just beyond the footprint of the spike's tip;
    /// at 1 the skull-base phantom's hypoglossal canal kept 2.02 mm outside the truth). Where the
    /// membrane of the patch grown so would cross the mesh, the rim is retried wider
    /// (rim_rings_retry), then half as many rings are tried, down to none. 0: off.
    int wall_rings = 8;
    /// With wall_length_voxels > 0, the walk up the wall is not counted in rings but by its
    /// length: the faces within that many voxels (of the grid's smallest spacing) of the patch,
    /// along the shortest path over face centroids, nearest first; wall_rings then only scales it
    /// on the retries (half the length with half the rings). The marching cubes cut an overhanging
    /// wall into slivers, and eight rings climbed 1.5 mm of the tilted dry skull-base phantom's
    /// right foramen lacerum (the wall rises 3 mm; 2.29 mm outside the truth) but 3 mm of the
    /// other side. 0: rings only.
    double wall_length_voxels = 3.0;
    double wall_max_cosine = 0.5;
    double wall_climb_voxels = 0.3;
    double wall_footprint = 1.5;
    /// Only patches of which at least this share of the area lies on the void fill's plugs (a
    /// voxel it added just outside the face) are dips: a patch on thin bone blurred below the
    /// isovalue (the cribriform plate under the olfactory groove) is a floor, not a hole.
    double min_plug_share = 0.5;
    /// A closing surface the watershed left sunk down its channel (no dip of the void fill: wider
    /// than its ball, or not on its plugs; the macaque skull-base phantom's foramen magnum, 12 mm
    /// wide, closed 2.5 mm down the canal, 2.66 mm outside the truth) is raised onto the membrane
    /// spanning the channel's mouth on the inner table, when
    ///  - it is at least a disk of the void fill's ball in area,
    ///  - at least sunk_other_share of its area faces other empty space (face_on_other: the
    ///    sella's floor of thin bone blurred below the isovalue, a pocket, faces bone's label),
    ///  - the walk up the channel's wall (sunk_wall_rings rings, steep faces as for a dip, each
    ///    within sunk_footprint_voxels of the patch's footprint: up the channel, not up the fossa
    ///    beyond its mouth) reaches at least sunk_wall_share of the faces around it (the macaque's
    ///    foramen magnum 0.61; the human phantoms' 0.13-0.20, closed at their rim already).
    /// No vertex moves farther than the patch's radius (that of a disk of its area). The caps
    /// close_openings cut are not such closures (the pipeline leaves them out of face_on_other).
    /// sunk_wall_share 0: off.
    double sunk_wall_share = 0.5;
    double sunk_other_share = 0.5;
    int sunk_wall_rings = 16;
    double sunk_footprint_voxels = 1.0;
    /// A closing surface that passes those tests of a sunk closure on its area and on facing other
    /// space but not the wall's, or lies mostly on a cut opening's cap (kCutCap), is moved onto
    /// the thin plate: the watershed's meeting surface across a wide opening (on a grid tilted 25
    /// degrees the skull-base phantom's foramen magnum was closed by a voxel staircase up to 2.75 mm
    /// inside the truth), and a cap close_openings cut by a plane fitted to a rim that is lower at
    /// its sides (the skull-base phantom with a spine: its foramen magnum's plane lay 3.5 mm above
    /// the lateral rims, 2.59 mm inside the truth over the floor beside it). It is moved onto the thin plate
    /// spanning it (meshpost::thin_plate_positions: the surface continuing the slope of the inner
    /// table around it, C1 across its rim; the membrane, C0, spans the chord above the bowl the
    /// truth sags into, 2.34 mm inside on the untilted phantom). Its rim is taken fair_rim_rings
    /// rings of faces out (past the edge the blur rounds down into the hole, whose slope the plate
    /// would continue: with one ring it sagged 2.2-2.4 mm outside). No vertex moves farther than
    /// fair_max_move_voxels (of the grid's smallest spacing); the volume may go either way.
    /// fair_max_move_voxels 0 (or sunk_wall_share 0): off.
    double fair_max_move_voxels = 4.0;
    int fair_rim_rings = 4;
    /// A closing surface over more than this share of the mesh's area is not faired: a closure
    /// across an opening is a small part of the braincase's surface (the dry skull's largest faired
    /// one 0.6 %), while one patch off bone over a quarter of it is a scan whose bone the isovalue
    /// does not hold (ge-tilt's 4 mm slices: 27 %, whose thin plate, 200 thousand vertices, took
    /// 6.6 s to solve and then moved too far). Within (0, 1]; 1: no cap.
    double fair_max_area_share = 0.1;
};

struct DipResult {
    size_t patches = 0;           ///< disks of faces not on bone within the size limits
    size_t flushed = 0;           ///< patches moved onto their membrane
    size_t crossing = 0;          ///< dips left as they are: on their membrane a face would cross the mesh
    size_t vertices_moved = 0;
    std::vector<uint32_t> moved_vertices;  ///< the vertices moved, in the order of their patches
    double max_depth_mm = 0;      ///< the largest move of a vertex (mm)
    double volume_removed_mm3 = 0;  ///< the volume between the dips and their membranes (mm^3)
    size_t sunk = 0;              ///< of the patches flushed, closures sunk down their channel (DipParams::sunk_wall_share)
    size_t faired = 0;            ///< of the patches flushed, closures across wide openings moved onto their thin plate (DipParams::fair_max_move_voxels)
};

/// A value of face_on_other: the face faces other space across the cap of an opening that
/// close_openings cut (its plane is fitted to the rim already): such a closure is not raised as
/// sunk, only faired (DipParams::fair_max_move_voxels).
constexpr uint8_t kCutCap = 2;

/// mesh: the endocast (closed, outward faces, world mm); face_on_bone: per face (bone_contact.h);
/// plug: the void fill's voxels next to the endocast (plug_contacts: flat indices into `grid`, in
/// any order; an index beyond it is ignored); void_radius_mm: the void fill's ball radius (bounds
/// the patches' size, pi (2r)^2, and their depth, r); face_on_other: per face,
/// faces_on_other_space's flags, kCutCap on cut caps (empty: no sunk or faired closures). Moves the vertices of the patches flushed; faces unchanged.
/// Deterministic.
/// beside (may be empty): the caller's work to run on a thread of its own while the patches are
/// flushed one after another (a sequential loop: with two or more threads a core is idle there):
/// the second thread of a team of two OpenMP threads, where a parallel region runs on its thread
/// alone; with one thread (omp_get_max_threads()), after the loop. It must not read the vertices'
/// positions (they move) or change the mesh; it runs once whenever flush_dips returns, and its
/// exception is rethrown after the loop.
/// Throws InvalidParameter when face_on_bone has another size than the faces or a parameter is
/// outside its range.
DipResult flush_dips(meshpost::TriangleMesh& mesh, const std::vector<uint8_t>& face_on_bone, const Geometry& grid,
                     const std::vector<size_t>& plug, double void_radius_mm, const DipParams& p = {},
                     const std::vector<uint8_t>& face_on_other = {}, const std::function<void()>& beside = {});

/// Per face of the mesh: 1 where the voxel nearest to the point one voxel (the largest spacing)
/// out along its normal is other empty space (kOther, kUnlabelled); 0 beyond the grid (the
/// volume's border, where the cavity is closed flat) and for degenerate faces.
std::vector<uint8_t> faces_on_other_space(const meshpost::TriangleMesh& mesh, const Volume<uint8_t>& labels);

/// The plugs' voxels next to the endocast: of the voxels the void fill added (`filled` and not
/// `bone`) that are still kBone in `labels`, the face-connected pieces that touch both a kEndocast
/// voxel and other empty space (kOther, kUnlabelled, or beyond the endocast's box grown by twice
/// void_radius_mm): holes through the wall, not the creases of the cavity it left closed (their
/// deepest voxels, which even the smallest crease ball closes). Their voxels with a kEndocast
/// 26-neighbour, sorted indices. Throws InvalidParameter for grids that differ.
std::vector<size_t> plug_contacts(const Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                                  const Volume<uint8_t>& filled, double void_radius_mm);

}  // namespace endocast
