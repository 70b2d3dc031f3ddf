#pragma once
// Synthetic skull CT phantoms with a known (analytic) endocranial volume: the ground truth of the
// accuracy tests and the embedded default of the demo.
//
// Phantom frame (before tilt): x = left->right, y = posterior->anterior, z = inferior->superior,
// centred on the braincase centre. The braincase (true cavity) is an ellipsoid; the skull is the
// shell between it and a larger ellipsoid; openings (foramina) are closed at the inner skull surface
// for the ground truth, so the true ECV is exactly the ellipsoid's volume (or, for a volume cropped
// at the skull base, the part of it inside the volume: see PhantomParams::crop_base_mm).
//
// Every added structure (spine, sinus, orbits, body, couch) lies outside the inner ellipsoid, with
// its blur band clear of the inner surface's, except the openings listed in PhantomResult::openings:
// wherever there is no opening, the isovalue crossing of the inner skull surface is the ellipsoid.
//
// Sizes below are those of the human presets; the macaque preset scales the skull's features by
// 0.4 (PresetSpec::scale in phantom.cpp) unless a size is given for it.
#include <array>
#include <functional>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "endocast/volume.h"

namespace endocast {

struct SkullBaseModel;  // the implicit truth of the skull-base phantom (library-internal)

enum class PhantomPreset {
    Human,    ///< adult human head: brain ~35 HU, scalp, ~1300 mL
    Dry,      ///< dry human cranium: air-filled braincase, no soft tissue
    Macaque,  ///< small braincase (~90 mL), brain-filled, 0.5 mm voxels by default
    Mouse,    ///< adult mouse skull (~0.45 mL), 0.07 mm voxels: always the anatomical phantom
              ///< of "Mouse phantom" below
};
/// "human|dry|macaque|mouse" ("rodent" = mouse), case-insensitive; InvalidParameter otherwise.
PhantomPreset parse_phantom_preset(const std::string& s);
std::string to_string(PhantomPreset p);

struct PhantomParams {
    PhantomPreset preset = PhantomPreset::Human;
    uint64_t seed = 1;                 ///< noise and void placement
    double tilt_deg = 0.0;             ///< rotation of the skull about the x axis (pitch), degrees
    /// Voxels; 0 = automatic: the head plus a 10 mm margin (mouse: 1 mm), centred on the cavity,
    /// extended to hold the added structures (spine, face, body) or cut by crop_base_mm. An
    /// explicit size puts the cavity centre (or grid_centre_mm) at the grid's centre (z: at the
    /// crop when cropped).
    Dims size{0, 0, 0};
    /// mm; 0 = preset default (1 mm human/dry, 0.5 mm macaque, 0.07 mm mouse)
    Vec3 spacing{0.0, 0.0, 0.0};
    Vec3 origin{0.0, 0.0, 0.0};        ///< world mm of voxel (0,0,0)
    /// Skull-base and mouse phantoms: the phantom-frame point (mm, before tilt) put at the centre
    /// of the grid along each axis of explicit size (0 = the cavity centre), e.g. to render a small
    /// window around a structure at a fine spacing. Must be 0 for the ellipsoid phantoms
    /// (InvalidParameter otherwise).
    Vec3 grid_centre_mm{0.0, 0.0, 0.0};
    bool noise = true;                 ///< Gaussian noise (sigma 20 HU)
    bool blur = true;                  ///< partial-volume blur (Gaussian, sigma 0.6 voxel)
    bool diploic_voids = true;         ///< low-density voids inside the bone shell
    bool crack = true;                 ///< a thin crack through the vault
    bool small_foramina = true;        ///< several 1.5-3 mm openings through the shell
    bool foramen_magnum = true;        ///< the large opening at the skull base
    bool scalp = true;                 ///< soft tissue around the skull (ignored for Dry)

    /// Cervical spine below the foramen magnum: a spinal canal (radius 8 mm; macaque 3.5 mm)
    /// filled with the braincase content (cord/CSF; air for Dry) from the foramen magnum (radius
    /// 14 mm, wider than the canal) down to the lower volume border, inside bony vertebral rings
    /// (1300 HU; wall 5 mm, 15 mm tall, 4 mm soft-tissue gaps, every 19 mm down to the border; the
    /// first one 2 mm below the skull) with vertebral bodies in front, and two lateral articular
    /// pillars (radius 4 mm) that join the column to the occipital condyles, so the spine and the
    /// skull are one bone component. The automatic grid reaches 7 rings down.
    bool spine = false;
    /// Air-filled frontal sinus (-1000 HU; an oblate spheroid 24 x 24 x 12 mm) inside a thickened
    /// frontal bone (glabella), max(3.5 mm, 8 blur sigmas) of bone (4.8 mm at 1 mm voxels) from the
    /// inner skull surface, drained by a 2 mm duct
    /// into an air-filled nasal cavity (a 18 x 34 x 28 mm box below it) that opens at the front
    /// (piriform aperture) and through two nostrils (radius 4 mm) to the outside air.
    bool frontal_sinus = false;
    /// Two orbits in front of the braincase below the frontal region: cones (48 mm deep, opening
    /// radius 20 mm) carved into the facial bone, filled with fat (-80 HU; air for Dry) around an
    /// eyeball (radius 12 mm, 10 HU), each joined to the braincase by an optic canal of radius
    /// optic_canal_radius_mm filled with the braincase content.
    bool orbits = false;
    /// Optic canal radius, mm; 0 = preset default: 7 mm (human, dry), 3.5 mm (macaque) - just
    /// wider than the pipeline's void-closing ball (6 voxels at the default spacing), so the canal
    /// stays open and the segmentation must cut it. An anatomical 3 mm canal is sealed by the closing.
    double optic_canal_radius_mm = 0.0;
    /// Large field of view of a clinical scan: shoulders and upper chest (an elliptic cylinder with
    /// an ellipsoidal top, 340 x 200 mm, 40 HU) with clavicles (radius 7 mm, 1300 HU) below the
    /// neck, a curved CT couch (radius 500 mm, 25 mm thick, 3 mm skins of 400 HU around a 280 HU
    /// core, 420 mm wide) touching the back of the head (and of the chest), and the automatic grid
    /// extended to 430 x 320 mm in x/y and from the chest (195 mm below the braincase centre) to
    /// the vertex: 431 x 321 x 277 voxels at 1 mm. Body and couch are world-fixed (the tilt turns
    /// the head, neck and spine only). Needs soft tissue: InvalidParameter for Dry or scalp=false.
    bool body = false;
    /// Anatomical skull base instead of the ellipsoidal braincase (see "Skull-base phantom" below
    /// PhantomResult). With it: spine, crop_base_mm, tilt, scalp, seed, size, spacing, origin,
    /// noise and blur apply as described; frontal_sinus, orbits, body and optic_canal_radius_mm
    /// are refused (InvalidParameter: the phantom has its own orbits and nasal cavity);
    /// diploic_voids, crack, small_foramina and foramen_magnum are ignored (its anatomical
    /// openings are always present). An explicit size is not checked against the head (a small
    /// grid is allowed, e.g. to get the truth quickly: the truth does not depend on the grid).
    bool skull_base = false;
    /// > 0: the volume stops at the skull base: its lower face (the outer face of the first slice,
    /// half a voxel below its centres) lies this many mm above the lowest point of the cavity
    /// (world z, after tilt), so the cavity touches the volume border. The true cavity is then the
    /// part of the ellipsoid above that plane. 0 = off. Must be below the cavity's height.
    double crop_base_mm = 0.0;
};

/// The human study case: Human with spine, frontal sinus and orbits (CLI: --preset human-full).
PhantomParams human_full_phantom_params();

/// An opening of the braincase (foramen, crack, canal): the disk that closes it at the inner skull
/// surface for the ground truth.
struct PhantomOpening {
    std::string name;                  ///< "foramen_magnum", "foramen_1".."foramen_5", "crack",
                                       ///< "optic_canal_left", "optic_canal_right"
    Vec3 centre_world{0, 0, 0};        ///< centre on the inner skull surface, mm
    Vec3 axis_world{0, 0, 1};          ///< unit, pointing out of the braincase
    double radius_mm = 0;              ///< radius of a disk covering the opening (crack: half length)
};

/// Landmarks of the mouse phantom (world mm, after the tilt; normals are unit vectors).
struct PhantomLandmarks {
    Vec3 basion{0, 0, 0};     ///< the foramen magnum's most anterior-inferior rim point on the midline
    Vec3 opisthion{0, 0, 0};  ///< its most posterior-superior rim point on the midline
    /// The plane that closes the foramen magnum for the truth: through basion and opisthion,
    /// perpendicular to the symmetry plane; the point is midway between them, the normal points
    /// out of the braincase.
    Vec3 foramen_magnum_plane_point{0, 0, 0};
    Vec3 foramen_magnum_plane_normal{0, 0, -1};
    Vec3 cribriform_plate_centre{0, 0, 0};  ///< on the plate's inner surface (the truth surface), midline
    Vec3 symmetry_plane_point{0, 0, 0};     ///< the midsagittal plane
    Vec3 symmetry_plane_normal{1, 0, 0};
};

struct PhantomResult {
    Volume<int16_t> ct;                ///< HU (empty when rendered by generate_phantom_slabs)
    Geometry geometry;                 ///< the CT's grid (also when ct is empty)
    double true_ecv_ml = 0;            ///< analytic endocranial volume (inside the volume when cropped)
    /// Bound on |true_ecv_ml - the exact volume| (mL): the rounding of the closed formula
    /// (1e-12 relative) for the ellipsoid phantoms, the numerical integration's stated bound for
    /// the skull-base phantom.
    double true_ecv_error_ml = 0;
    double suggested_iso = 0;          ///< HU, midway between cavity content and bone
    Vec3 cavity_centre_world{0, 0, 0}; ///< mm
    Vec3 cavity_semi_axes_mm{0, 0, 0}; ///< inner ellipsoid semi-axes (phantom frame)
    /// World-from-phantom rotation, row-major: world = cavity_centre_world + R * q.
    std::array<double, 9> cavity_rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
    Vec3 foramen_magnum_world{0, 0, 0};///< centre of the foramen magnum on the inner surface, mm
    Vec3 foramen_magnum_axis{0, 0, -1};///< unit, along the canal, pointing down/out of the braincase
    double foramen_magnum_radius_mm = 0;
    double spinal_canal_radius_mm = 0; ///< 0 without spine
    double optic_canal_radius_mm = 0;  ///< 0 without orbits
    double shell_thickness_mm = 0;     ///< skull thickness (outer semi-axes = inner + this)
    double sigma_mm = 0;               ///< partial-volume blur sigma used (0 when blur is off)
    std::vector<PhantomOpening> openings;  ///< every opening of the braincase
    bool cropped = false;              ///< crop_base_mm > 0
    /// Cropped: world z of the plane bounding the true cavity from below (the lower face of the
    /// volume); the cavity is {ellipsoid} ∩ {z >= crop_plane_z_mm}. -infinity when not cropped.
    double crop_plane_z_mm = 0;
    /// Cropped: the ECV if the cut were at the centres of the first slice instead (mL); equals
    /// true_ecv_ml when not cropped.
    double true_ecv_slice_centres_ml = 0;
    std::string description;           ///< one line: preset, size, spacing, features
    /// Skull-base and mouse phantoms: the implicit truth (for phantom_cavity_signed_distance);
    /// null otherwise.
    std::shared_ptr<const SkullBaseModel> skull_base;
    std::optional<PhantomLandmarks> landmarks;  ///< the mouse phantom's; empty for the others
};

// ---- Skull-base phantom (PhantomParams::skull_base) ------------------------------------------
// The braincase of an adult human (human: brain 35 HU, orbital fat -80 HU, scalp and neck 30 HU,
// air outside; dry: air wherever there is no bone; macaque: the human anatomy scaled by 0.4,
// thin plates by 0.5, brain-filled, 0.5 mm voxels), bone 1400 HU, spine 1300 HU. Sizes (human,
// phantom frame, mm): ECV ~1423 mL, length 168, breadth 136. The inner table is the zero set of
// one implicit function: cerebrum flat over the anterior fossa (z = -20 for y > 5) with the
// olfactory groove (cribriform plate 7 mm lower), sella turcica with the dorsum sellae behind it,
// the clivus sloping to the foramen magnum, middle fossae as pockets 26 mm below the anterior
// floor whose temporal-pole tips reach forward under the sphenoid wings (an overhang), petrous
// ridges between the middle and the posterior fossa, two cerebellar lobes. Bone: vault 6 mm,
// squamous temporal and the middle fossa floor ~2.5-3.5 mm, solid sphenoid body, petrous bones
// and face; the orbital roofs are 0.5 mm thick around (+-22, 60) (x, y) rising to 1 mm 12 mm
// away, the cribriform plate 1 mm over an air-filled nasal cavity open at the front.
// Openings (PhantomResult::openings: "foramen_magnum" first as for the ellipsoid phantoms, then
// NAME_left and NAME_right, then "cribriform_hole_left_1".."cribriform_hole_right_5"): straight
// canals along axis_world, filled with the cavity content, leading out of the skull (to the orbit
// for the optic canal and the superior orbital fissure, to the nasal cavity for the cribriform
// holes, below the base for the others; those of >= 3 mm are open along their axis for 45 mm):
// optic canal 5 mm, superior orbital fissure 20 x 4 mm, foramen rotundum 3, ovale 7 x 4,
// spinosum 2, lacerum 6, jugular foramen 15 x 10, internal acoustic meatus 4.5 (here open through
// the petrous bone), hypoglossal canal 3, cribriform holes 1, foramen magnum 35 x 30 (macaque:
// x 0.4, cribriform holes 0.5). radius_mm covers the hole on the inner table: its semi-major axis
// over the cosine between the axis and the surface normal (cosine floored at 0.3).
// Truth: {f < 0}, the cavity closed flush with the inner table across every hole (the canals are
// not cavity); with crop_base_mm the part above the crop plane, placed crop_base_mm above the
// cavity's lowest point (world z). true_ecv_ml integrates it with an adaptive octree (leaves of
// 0.25 mm, 0.1 mm for macaque) in the phantom frame, independent of the CT grid and the tilt;
// true_ecv_error_ml = |V(leaves h) - V(leaves 2h)|, ~0.02 mL for the human: the integration
// converges as h^2 (human, leaves 1, 0.5, 0.25, 0.125 mm: 1422.606, 1422.529, 1422.510,
// 1422.504 mL), so the bound is about three times its own error. cavity_semi_axes_mm: the half sizes of the
// phantom-frame box (centred at (0, 0, 2 s) mm) that holds the cavity. Generation of the human at
// 1 mm: ~2-4 s on 2 cores.

// ---- Mouse phantom (PhantomPreset::Mouse) -----------------------------------------------------
// The cranium of an adult C57BL/6 mouse (phantom frame as above, mm), built as the skull-base
// phantom (an implicit inner table, erfc-blended regions, an octree-integrated truth); the preset
// alone selects it (skull_base, spine and the ellipsoid phantoms' opening flags are ignored).
// Default spacing 0.07 mm (0.02-0.2 mm supported); automatic grid: the head plus a 1 mm margin,
// from the snout back over the atlas and two vertebrae. Brain, nerves and soft tissue 40 HU, bone
// 1500 HU, vertebrae 1400 HU, air -1000 HU; suggested_iso 770 HU.
// Cavity (ECV 0.4488 mL; 14.6 mm long, 10.4 mm wide, 6.2 mm high over its flat floor, 6.7 with the
// hypophyseal fossa): two cerebral hemispheres, the cerebellum (7.2 mm wide) with the paraflocculi,
// the brainstem, and the olfactory bulbs' chamber (3.3 mm wide, 2.5 mm high, 2.7 mm long) closed in
// front by the cribriform plate: 0.12 mm thick, tilted 15 degrees (top forward), with 66 pores of
// 0.04-0.15 mm over 25 % of its flat part (2 mm^2): a sieve below the isovalue at 0.14 mm voxels,
// its pores resolved at 0.035 mm.
// Bone: vault 0.2 mm, 0.1 mm at the orbits, floor 0.3, basioccipital 0.4; solid basisphenoid, snout
// and zygomatic arches; in the snout the nasal cavity (air) with a 0.1 mm septum and turbinate
// scrolls and shelves 0.07 mm thick, open at the nostrils; tympanic bullae (3 x 4 x 3 mm, 0.1 mm
// walls, air) ventrolateral to the braincase. Soft tissue: scalp (0.6 mm), eyes and orbits, jaws,
// neck. Foramen magnum 2.8 mm wide, 2.1 mm from basion to opisthion, its plane 45 degrees from the
// horizontal (facing posterior-inferior), leading to a spinal canal of radius 1 mm (content) inside
// the atlas and vertebrae (walls 0.3 mm) with 0.35 mm soft-tissue gaps.
// Openings (PhantomResult::openings): "foramen_magnum", then NAME_left / NAME_right for the optic
// canal (0.25 mm), foramen ovale (0.6 x 0.4), jugular foramen (0.36) and hypoglossal canal (0.2),
// then "cribriform_plate" (a disk covering its pores).
// Truth (the convention of expert mouse labels): {f < 0} on the braincase side of the foramen
// magnum's plane (through basion and opisthion, perpendicular to the symmetry plane): the olfactory
// chamber up to the plate's inner surface, every foramen and pore closed flush with the inner
// table. true_ecv_ml by the octree with leaves of 0.02 mm; true_ecv_error_ml = |V(0.02) - V(0.04)|
// = 1.1e-5 mL (0.0025 %), which bounds the integration's error (it converges as h^2).
// PhantomResult::landmarks holds basion, opisthion, the foramen magnum's plane, the plate's centre
// and the symmetry plane. cavity_semi_axes_mm: the half sizes of the phantom-frame box centred at
// the origin that holds the cavity. Throws as generate_phantom, and InvalidParameter for
// crop_base_mm > 0, frontal_sinus, orbits, body or optic_canal_radius_mm.

/// Generates a phantom. Deterministic for a given seed (the same bytes on every machine and
/// thread count). Throws InvalidParameter for non-positive spacing, a size too small for the head,
/// a crop outside (0, cavity height), body without soft tissue, or 2^31 voxels or more (see
/// generate_phantom_slabs for larger ones).
PhantomResult generate_phantom(const PhantomParams& p = {});

/// Receives a phantom's CT one slab at a time: `slab` holds slices [z0, z0 + slab.nz()) of the
/// grid `whole` (the slab's geometry: whole's, with its own dims and the origin of slice z0).
using PhantomSlabSink = std::function<void(const Geometry& whole, int64_t z0, const Volume<int16_t>& slab)>;

/// generate_phantom at any size (microCT: 2048 x 2048 x 1500 and beyond, < 2^40 voxels) in memory
/// bounded by one slab: the CT is rendered in slabs of whole slices, at most `slab_voxels` voxels
/// each (at least one slice), in order, each slab's slices in parallel, and handed to `sink`; it is
/// never held whole (res.ct stays empty; res.geometry is the grid). The voxels are those
/// generate_phantom gives (the noise is a hash of the voxel's index). Throws as generate_phantom,
/// and InvalidParameter for slab_voxels < 1 or no sink; whatever `sink` throws stops the rendering.
PhantomResult generate_phantom_slabs(const PhantomParams& p, int64_t slab_voxels, const PhantomSlabSink& sink);

/// Exact signed distance (mm, negative inside) from p to the axis-aligned ellipsoid centred at 0
/// with semi-axes `semi` (> 0), by Eberly's robust bisection ("Distance from a Point to an
/// Ellipse, an Ellipsoid, or a Hyperellipsoid", 2013); accurate to ~1e-12 relative. `closest`, when
/// given, receives the nearest point of the surface.
double ellipsoid_signed_distance(const Vec3& p, const Vec3& semi, Vec3* closest = nullptr);

/// Signed distance (mm, negative inside) from a world point to the boundary of the true cavity:
/// the inner ellipsoid, closed across every opening; for a cropped phantom the ellipsoid cut by the
/// plane z = crop_plane_z_mm (the exact distance to that intersection: ellipsoid part, flat cap or
/// their rim). The other faces of the volume never cut the cavity.
/// Skull-base phantom: the sign is exact (the sign of f, and of the crop plane); within 6 mm of
/// the surface the magnitude is the distance to a foot point found by Newton projection and a
/// descent along the surface (converged to 1e-7 mm), with 14 more starts beyond 0.5 mm to find a
/// nearer sheet: within 0.02 mm of the true distance within 3 mm of the surface (tested against
/// offsets along the normal); beyond 6 mm it is the estimate f / |grad f|. Thread-safe; ~1-3 us
/// per point near the surface.
double phantom_cavity_signed_distance(const PhantomResult& r, const Vec3& world);

/// True when the world point lies within margin_mm of one of r.openings, measured to the flat
/// disk (centre, axis, radius) of the opening.
bool phantom_near_opening(const PhantomResult& r, const Vec3& world, double margin_mm);

}  // namespace endocast
