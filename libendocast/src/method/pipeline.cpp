// The whole method as one extraction, stage by stage (pipeline.h).
#include "endocast/pipeline.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>

#include "endocast/stages/distance.h"
#include "endocast/stages/handles.h"
#include "endocast/stages/resample.h"
#include "method/label_box.h"
#include "meshpost/measure.h"
#include "meshpost/patches.h"
#include "meshpost/topology.h"

namespace endocast {
namespace {

class Stopwatch {
public:
    double lap() {
        const auto now = std::chrono::steady_clock::now();
        const double s = std::chrono::duration<double>(now - last_).count();
        last_ = now;
        return s;
    }

private:
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

}  // namespace

size_t apply_cut_planes(Volume<uint8_t>& labels, const std::vector<CutPlane>& planes) {
    const Geometry& g = labels.geometry();
    for (const CutPlane& c : planes) {
        const double n = std::sqrt(c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1] +
                                   c.normal[2] * c.normal[2]);
        if (!(n > 0) || !std::isfinite(n))
            throw InvalidParameter("cut plane normal (" + std::to_string(c.normal[0]) + ", " +
                                   std::to_string(c.normal[1]) + ", " +
                                   std::to_string(c.normal[2]) + "), expected a non-zero vector");
    }
    size_t cut = 0;
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                uint8_t& l = labels(x, y, z);
                if (l == kBone || l == kOther) continue;
                const Vec3 w = g.index_to_world(double(x), double(y), double(z));
                for (const CutPlane& c : planes) {
                    const double s = (w[0] - c.point[0]) * c.normal[0] +
                                     (w[1] - c.point[1]) * c.normal[1] +
                                     (w[2] - c.point[2]) * c.normal[2];
                    if (s > 0) {
                        l = kOther;
                        ++cut;
                        break;
                    }
                }
            }
    return cut;
}

EnclosureFaces enclosure_faces(const Volume<uint8_t>& labels) {
    const Dims& d = labels.dims();
    const int64_t nx = d[0], ny = d[1], nz = d[2];
    const Vec3& sp = labels.geometry().spacing;
    const double face_area[3] = {sp[1] * sp[2], sp[0] * sp[2], sp[0] * sp[1]};
    size_t bone = 0, other = 0, border = 0;
    size_t border_faces[3] = {0, 0, 0};  // per axis (the area is summed once, from the counts)
    // A row at a time: its E voxels found by a byte search, their neighbours read from the four
    // rows around it (null beyond the volume: the border).
#pragma omp parallel for schedule(static) reduction(+ : bone, other, border_faces[:3])
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            const uint8_t* row = labels.data() + labels.index(0, y, z);
            const uint8_t* end = row + nx;
            const uint8_t* e = std::find(row, end, kEndocast);
            if (e == end) continue;
            const uint8_t* around[4] = {y > 0 ? row - nx : nullptr, y + 1 < ny ? row + nx : nullptr,
                                        z > 0 ? row - nx * ny : nullptr, z + 1 < nz ? row + nx * ny : nullptr};
            auto face = [&](uint8_t l) {
                if (l == kEndocast) return;
                if (l == kBone) ++bone;
                else ++other;
            };
            for (; e != end; e = std::find(e + 1, end, kEndocast)) {
                const int64_t x = e - row;
                if (x > 0) face(row[x - 1]);
                else ++border_faces[0];
                if (x + 1 < nx) face(row[x + 1]);
                else ++border_faces[0];
                for (int k = 0; k < 4; ++k) {
                    if (around[k]) face(around[k][x]);
                    else ++border_faces[1 + k / 2];
                }
            }
        }
    EnclosureFaces e;
    e.bone = bone;
    e.other = other;
    for (int a = 0; a < 3; ++a) border += border_faces[a];
    e.border = border;
    e.border_area_mm2 = double(border_faces[0]) * face_area[0] + double(border_faces[1]) * face_area[1] +
                        double(border_faces[2]) * face_area[2];
    return e;
}

double enclosure_by_bone(const Volume<uint8_t>& labels) {
    const EnclosureFaces e = enclosure_faces(labels);
    const size_t total = e.bone + e.other + e.border;
    return total ? double(e.bone) / double(total) : 0.0;
}

namespace {

// The faces of the caps close_openings cut (within 1.5 voxels of an opening's plane and 3 voxels
// of its rim) are marked kCutCap for flush_dips: such a closure is not raised as sunk (the plane
// is fitted to the rim on the inner table already, and the walls it meets are the hole's funnel,
// cthead's and headphantom's foramen magnum, not a channel the closure sank into), only faired.
void mark_cut_caps(std::vector<uint8_t>& face_on_other, const meshpost::TriangleMesh& mesh,
                    const std::vector<Opening>& openings, double step) {
    for (const Opening& op : openings) {
        if (!op.plane_fitted) continue;
        const Vec3& c = op.centre_world;
        const Vec3& n = op.normal;
        for (size_t f = 0; f < mesh.faces.size(); ++f) {
            if (!face_on_other[f]) continue;
            Vec3 d{0, 0, 0};
            for (uint32_t v : mesh.faces[f])
                for (size_t a = 0; a < 3; ++a) d[a] += mesh.vertices[v][a] / 3.0;
            for (size_t a = 0; a < 3; ++a) d[a] -= c[a];
            const double h = d[0] * n[0] + d[1] * n[1] + d[2] * n[2];
            const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - h * h;
            const double rim = op.radius_mm + 3 * step;
            if (std::fabs(h) <= 1.5 * step && r2 <= rim * rim) face_on_other[f] = kCutCap;
        }
    }
}

// Where the cavity meets the volume border the watershed leaves the border voxels themselves to the
// outside seeds: they join the cavity when their inward neighbour is cavity, so that the mesh is
// closed flat at the volume's face (half a voxel beyond them), where the scan stops.
size_t extend_to_border(Volume<uint8_t>& labels) {
    const Dims& d = labels.dims();
    size_t added = 0;
    for (int a = 0; a < 3; ++a) {
        const int u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
        for (int side = 0; side < 2; ++side) {
            const int64_t at = side ? d[a] - 1 : 0, in = side ? d[a] - 2 : 1;
            if (in < 0 || in >= d[a]) continue;
            std::array<int64_t, 3> q{}, n{};
            for (int64_t j = 0; j < d[v]; ++j)
                for (int64_t i = 0; i < d[u]; ++i) {
                    q[a] = at, q[u] = i, q[v] = j;
                    n = q;
                    n[a] = in;
                    uint8_t& l = labels(q[0], q[1], q[2]);
                    if ((l == kOther || l == kUnlabelled) && labels(n[0], n[1], n[2]) == kEndocast) {
                        l = kEndocast;
                        ++added;
                    }
                }
        }
    }
    return added;
}

// A braincase holding tissue (a living head) holds no air. With thin bone recovered, an air
// sinus whose thin walls close (the sphenoid sinus) can join the cavity through a gap: the cavity's
// voxels below Otsu's air/tissue threshold, and those within two voxels of them, leave it when
// the cavity's median is tissue (above that threshold). Returns how many left.
template <class T>
size_t exclude_air(Volume<uint8_t>& labels, const Volume<T>& ct, double t) {  // t: Otsu's air threshold
    std::vector<float> v;
    for (size_t i = 0; i < labels.size(); i += 16)
        if (labels[i] == kEndocast) v.push_back(ct[i]);
    if (v.empty()) return 0;
    auto m = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), m, v.end());
    if (!(*m > t)) return 0;  // an air-filled braincase (a dry skull)
    // Only the box of those voxels, grown by the dilation's reach, is dilated (the same result as
    // dilating the whole volume: every air voxel lies inside the box).
    const Dims& d = labels.dims();
    auto is_air = [&](size_t i) { return labels[i] == kEndocast && double(ct[i]) < t; };
    int64_t lo0 = d[0], lo1 = d[1], lo2 = d[2], hi0 = -1, hi1 = -1, hi2 = -1;
    size_t n = 0;
#pragma omp parallel for schedule(static) reduction(+ : n) reduction(min : lo0, lo1, lo2) \
    reduction(max : hi0, hi1, hi2)
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x)
                if (is_air(labels.index(x, y, z))) {
                    ++n;
                    lo0 = std::min(lo0, x), lo1 = std::min(lo1, y), lo2 = std::min(lo2, z);
                    hi0 = std::max(hi0, x), hi1 = std::max(hi1, y), hi2 = std::max(hi2, z);
                }
    if (n == 0) return 0;
    const Geometry& g = labels.geometry();
    const double radius = 2 * g.smallest_spacing();
    const std::array<int64_t, 3> first{lo0, lo1, lo2}, last{hi0, hi1, hi2};
    CropBox box;
    for (int a = 0; a < 3; ++a) {
        const int64_t reach = int64_t(std::ceil(radius / g.spacing[a])) + 1;
        box.lo[a] = std::max<int64_t>(0, first[a] - reach);
        box.hi[a] = std::min<int64_t>(d[a], last[a] + reach + 1);
    }
    const Geometry sub = cropped_geometry(g, box);
    const Dims& lo = box.lo;
    Volume<uint8_t> air(sub, 0);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < sub.dims[2]; ++z)
        for (int64_t y = 0; y < sub.dims[1]; ++y)
            for (int64_t x = 0; x < sub.dims[0]; ++x)
                air(x, y, z) = is_air(labels.index(x + lo[0], y + lo[1], z + lo[2])) ? 1 : 0;
    const Volume<uint8_t> near = dilate_ball(air, radius);
    size_t left = 0;
#pragma omp parallel for schedule(static) reduction(+ : left)
    for (int64_t z = 0; z < sub.dims[2]; ++z)
        for (int64_t y = 0; y < sub.dims[1]; ++y)
            for (int64_t x = 0; x < sub.dims[0]; ++x) {
                uint8_t& l = labels(x + lo[0], y + lo[1], z + lo[2]);
                if (near(x, y, z) && l == kEndocast) {
                    l = kOther;
                    ++left;
                }
            }
    return left;
}

// The automatic isovalue between air and the rest (no soft tissue found) can be far too low for a
// dry skull: whatever lies between air and bone counts as bone (the shared dry skull: -313.5 HU,
// its plastic inserts of ~90 HU divide the cavity) - which value to try, for a warning or an
// error; empty otherwise.
std::string isovalue_hint(const ResolvedParams& rp) {
    if (rp.isovalue_rule != "otsu-air-bone" || !std::isfinite(rp.isovalue_other)) return "";
    std::ostringstream msg;
    msg << "; the isovalue " << rp.isovalue
        << " was chosen automatically between air and the rest (no soft tissue found), which can be too low "
           "for a dry skull: Otsu's threshold of the voxels above it is "
        << rp.isovalue_other << " (try --iso " << rp.isovalue_other << ")";
    return msg.str();
}

// A braincase is enclosed by bone apart from where the volume border cuts it, and holds more than
// a few voxels: otherwise there is no cavity (NoResult). Where it meets the border it is closed flat
// there (warned: its volume is then a lower bound).
void check_cavity(const Volume<uint8_t>& labels, const ExtractParams& p, ExtractionResult& r) {
    const EnclosureFaces e = enclosure_faces(labels);
    size_t voxels = 0;
#pragma omp parallel for schedule(static) reduction(+ : voxels)
    for (int64_t i = 0; i < int64_t(labels.size()); ++i) voxels += labels[size_t(i)] == kEndocast;
    const double inside = e.bone + e.other > 0 ? double(e.bone) / double(e.bone + e.other) : 0.0;
    std::ostringstream at;
    at << "the chosen cavity (deepest point " << r.max_distance_mm << " mm from bone, " << voxels
       << " voxels)";
    if (voxels < p.min_cavity_voxels)
        throw NoResult(at.str() + " is smaller than " + std::to_string(p.min_cavity_voxels) +
                       " voxels: no braincase found (is the isovalue right, is there a skull?)" + isovalue_hint(r.params));
    if (inside < p.min_enclosure) {
        std::ostringstream msg;
        msg << at.str() << " is not enclosed by bone: only " << 100.0 * inside
            << "% of its boundary away from the volume border is bone, a braincase has >= "
            << 100.0 * p.min_enclosure
            << "%: no braincase found (check the isovalue, or give --seed-point)" << isovalue_hint(r.params);
        throw NoResult(msg.str());
    }
    r.border_contact_mm2 = e.border_area_mm2;
    if (e.border > 0) {
        std::ostringstream msg;
        msg << "the endocast meets the volume border over " << e.border_area_mm2
            << " mm^2 (the scan is cropped through the braincase): it is closed flat at the border, "
               "so its volume is a lower bound";
        r.warnings.push_back({"border_contact", msg.str(), {{"border_contact_mm2", e.border_area_mm2}}});
    }
}

// Every closing surface of the mesh (a patch not on bone, by the CT alone, of at least 10 voxel faces) goes into
// the openings list: the area of those at a cut opening (within its rim's radius and three voxels
// of its centre) is that opening's area; the others are listed as closing surfaces (cut = false).
// `neighbours`: the mesh's face_neighbours, or empty (computed here).
void list_closing_surfaces(ExtractionResult& r, const Geometry& g, const std::vector<std::array<uint32_t, 3>>& neighbours,
                           const std::vector<uint8_t>& face_on_bone) {
    const double small = g.smallest_spacing();
    const double step = g.largest_spacing();
    const std::vector<ClosingSurface> patches =
        neighbours.empty() ? closing_surfaces(r.mesh, face_on_bone, 10 * small * small)
                           : closing_surfaces(r.mesh, face_on_bone, 10 * small * small, neighbours);
    std::vector<uint8_t> matched(patches.size(), 0);
    for (Opening& op : r.openings.openings) {
        if (!op.cut) continue;
        for (size_t i = 0; i < patches.size(); ++i) {
            const Vec3& c = patches[i].centre;
            const double d = std::hypot(c[0] - op.centre_world[0], c[1] - op.centre_world[1], c[2] - op.centre_world[2]);
            if (d <= op.radius_mm + 3 * step) {
                op.area_mm2 += patches[i].area_mm2;
                matched[i] = 1;
            }
        }
    }
    for (size_t i = 0; i < patches.size(); ++i) {
        if (matched[i]) continue;
        Opening op;
        op.cut = false;
        op.centre_world = patches[i].centre;
        op.normal = patches[i].normal;
        op.area_mm2 = patches[i].area_mm2;
        op.radius_mm = std::sqrt(patches[i].area_mm2 / M_PI);
        r.openings.openings.push_back(op);
    }
}

}  // namespace

namespace {

// What one extraction carries from stage to stage; each volume is released as soon as the
// stages after it no longer need it (the peak memory is the openings stage's).
template <class T>
struct Extraction {
    Volume<T> owned;         // the input, when the caller gave it up: released once cropped
    const Volume<T>* input;  // the input CT (binarize)
    const Geometry grid;     // the input's grid (the mask and labels are put back on it)
    Volume<T> ct_box;        // the CT on the bone's box (ExtractionResult::work_box)
    const Volume<T>* work;   // the CT the stages after binarize read: the input or ct_box
    const ExtractParams& p;
    ExtractionResult r;
    // Restore the creases / flush the dips (both only when closing openings).
    const bool creases = p.close_openings && p.creases.enabled, dips = p.close_openings && p.dips.enabled;
    BinarizeResult bin;
    PackedMask bone_before_fill;  // bin.bone while the distance, seeds and watershed run
    VoidFillResult filled;
    Volume<float> dist;
    SeedResult seeds;
    WatershedResult ws;
    std::vector<size_t> plugs;  // the void fill's plugs next to the endocast (flush_dips)
    double air_threshold = 0;   // Otsu's threshold over all voxels (binarize's, with thin bone)
    Stopwatch total, sw;

    Extraction(const Volume<T>& c, const ExtractParams& params) : input(&c), grid(c.geometry()), work(&c), p(params) {}
    Extraction(Volume<T>&& c, const ExtractParams& params)
        : owned(std::move(c)), input(&owned), grid(owned.geometry()), work(&owned), p(params) {}
    Extraction(const Extraction&) = delete;

    void stage(const char* name) const {
        if (p.progress) p.progress(name);
    }

    // Bone at the isovalue (thin bone recovered), its voids filled, the distance to it.
    void bone_and_distance() {
        stage("binarize");
        r.params = resolve(*input, p);
        BinarizeParams bp = p.binarize;
        bp.isovalue = r.params.isovalue;
        bin = binarize(*input, bp);
        r.bone_fragments_removed_voxels = bin.removed_fragment_voxels;
        r.thin_bone_voxels = bin.thin_bone_voxels;
        air_threshold = bin.air_threshold;
        if (p.bone_box) {
            r.work_box = bone_work_box(bin.bone, r.params.void_radius_mm);
            if (r.work_box) {
                bin.bone = crop(bin.bone, *r.work_box);
                ct_box = crop(*input, *r.work_box);
                work = &ct_box;
                owned = Volume<T>();  // empty unless the caller gave the input up
                input = nullptr;
            }
        }
        r.timings_s.binarize = sw.lap();

        stage("void_fill");
        VoidFillParams vp;
        vp.radius_mm = r.params.void_radius_mm;  // resolved (and the voxels checked) by resolve()
        if (creases)  // the creases' closings' dilations, from the fill's transform (kept packed)
            for (double f : p.creases.keep_closed_fractions) vp.keep_dilations_mm.push_back(f * r.params.void_radius_mm);
        filled = fill_voids(bin.bone, vp);
        // Kept packed for the creases and dips (unpacked in the openings stage, once the distance is
        // released), else released.
        if (creases || dips) bone_before_fill = PackedMask(bin.bone);
        bin.bone = Volume<uint8_t>();
        r.void_filled_voxels = filled.filled_voxels;
        size_t bone_voxels = 0;
        const uint8_t* bone = filled.bone.data();
#pragma omp parallel for schedule(static) reduction(+ : bone_voxels)
        for (int64_t i = 0; i < int64_t(filled.bone.size()); ++i) bone_voxels += bone[i];
        r.bone_voxels = bone_voxels;
        r.timings_s.void_fill = sw.lap();

        stage("distance");
        dist = distance_transform(filled.bone);
        r.timings_s.distance = sw.lap();
    }

    // The seeds (the chosen cavity and the outside), the user's cut planes, the watershed.
    void segment() {
        stage("seeds");
        SeedParams sp = p.seeds;
        // The watershed resumes the candidate flood when it floods with the same parameters and
        // the seeds stay as chosen.
        const WatershedParams plain;
        sp.keep_flood = p.cut_planes.empty() && p.watershed.connectivity == plain.connectivity &&
                        p.watershed.quantum_mm == plain.quantum_mm;
        if (r.work_box) {  // the border seeds are the scan's, not the box's
            sp.box_lo = r.work_box->lo;
            sp.scan_dims = grid.dims;
        }
        seeds = place_seeds(filled.bone, dist, sp);
        r.border_seed_scale = seeds.border_scale;
        r.endocast_seeds_world = seeds.endocast_seeds_world;
        r.endocast_seed_radii_mm = seeds.endocast_seed_radii_mm;
        r.max_distance_mm = seeds.endocast_seed_distance_mm;
        r.candidates = seeds.candidates;
        r.warnings = seeds.warnings;
        if (!p.cut_planes.empty()) {
            r.cut_voxels = apply_cut_planes(seeds.labels, p.cut_planes);
            size_t left = 0;
            for (size_t i = 0; i < seeds.labels.size(); ++i) left += seeds.labels[i] == kEndocast;
            if (left == 0)
                throw InvalidParameter("the cut plane(s) remove the whole endocast seed: the normal "
                                       "must point away from the braincase");
        }
        r.timings_s.seeds = sw.lap();

        stage("watershed");
        if (seeds.flood) {
            seeds.labels = Volume<uint8_t>();
            ws = resume_watershed(std::move(seeds.flood->labels), seeds.flood->levels, dist, p.watershed);
            seeds.flood.reset();
            r.watershed_resumed = true;
        } else {
            ws = watershed(std::move(seeds.labels), dist, p.watershed);  // the seeds' memory holds the result
        }
        r.watershed_unreached_voxels = ws.unreached_voxels;
        extend_to_border(ws.labels);
        if (p.binarize.thin_bone_prominence > 0) r.air_excluded_voxels = exclude_air(ws.labels, *work, air_threshold);
        r.timings_s.watershed = sw.lap();
    }

    // The thin bone's voxels with the cavity on both sides and around them given back
    // (return_thin_bone_tips).
    void thin_bone_tips() {
        if (p.binarize.thin_bone_prominence > 0 && p.binarize.thin_bone_tips)
            r.thin_bone_tips_returned = return_thin_bone_tips(ws.labels, *work, r.params.isovalue, p.binarize.thin_bone_prominence,
                                                              bin.thin_bone_side_limit);
    }

    // The openings closed, the creases the void fill closed given back, the thin bone's tips given
    // back, the plugs found, the handles cut; then the cavity checked (NoResult when there is none).
    void close() {
        if (p.close_openings) {
            stage("openings");
            // Only the endocast's extent is needed of the distance from here on: released before
            // the openings stage's temporaries (its peak).
            const EndocastExtent extent = endocast_extent(ws.labels, dist, p.openings);
            dist = Volume<float>();
            bin.bone = bone_before_fill.unpack();  // empty without creases and dips
            bone_before_fill = PackedMask();
            r.openings = close_openings(ws.labels, filled.bone, extent, p.openings);
            if (creases) {
                // After the openings (a crease beside a cut opening touches its "other" side and
                // stays closed), before the handles (a crease bridging a bony spur makes one, cut there).
                r.creases = restore_creases(ws.labels, bin.bone, filled.bone, r.params.void_radius_mm, p.creases,
                                            filled.dilations);
                filled.dilations.clear();
            }
            // Before the handles: the false plate past a lip's tip can bridge to bone across the
            // cavity, a handle the handles stage would cut through the cavity (the tilted dry
            // phantom's sella, 2.74 mm inside).
            thin_bone_tips();
            if (dips) plugs = plug_contacts(ws.labels, bin.bone, filled.bone, r.params.void_radius_mm);
            bin.bone = Volume<uint8_t>();
            if (p.close_handles && extent.depth > 0)
                r.handles = close_handles(ws.labels, extent.deepest, extent.sub_distance, extent.sub_first);
            r.timings_s.openings = sw.lap();
        }
        filled.bone = Volume<uint8_t>();
        if (!p.close_openings) thin_bone_tips();
        check_cavity(ws.labels, p, r);
    }

    // Marching cubes on the CT where the labels allow. A handle on the surface next to a cut
    // opening: the wall flares into a funnel around the hole and the endocast left beyond the
    // plane rings the canal. That collar is cut too, and the result kept only where the handle
    // went away (elsewhere a collar is cavity).
    void polygonize_cavity() {
        stage("polygonize");
        PolygonizeParams pp;
        pp.isovalue = r.params.isovalue;
        pp.surface = r.params.surface;
        PolygonizeResult poly = polygonize(*work, ws.labels, pp);
        for (Opening& op : r.openings.openings) {
            if (!op.plane_fitted || !(p.openings.collar_width_voxels > 0)) continue;
            const double step = grid.largest_spacing();
            const double ball = op.radius_mm + (p.openings.collar_width_voxels + 3) * step;
            const meshpost::Point centre{op.centre_world[0], op.centre_world[1], op.centre_world[2]};
            const long before = meshpost::genus_within_ball(poly.mesh, centre, ball);
            if (before <= 0) continue;
            const std::vector<size_t> collar = cut_collar(ws.labels, op, p.openings);
            if (collar.empty()) continue;
            PolygonizeResult again = polygonize(*work, ws.labels, pp);
            if (meshpost::genus_within_ball(again.mesh, centre, ball) < before) {
                poly = std::move(again);
                op.collar_voxels = collar.size();
                op.voxels_removed += collar.size();
            } else {
                for (size_t i : collar) ws.labels[i] = kEndocast;
            }
        }
        r.enclosure = enclosure_by_bone(ws.labels);
        if (r.enclosure < p.min_enclosure) {
            std::ostringstream msg;
            msg << "the endocast region (deepest point " << r.max_distance_mm
                << " mm from bone) is not enclosed by bone: only " << 100.0 * r.enclosure
                << "% of its boundary is bone, a braincase has >= " << 100.0 * p.min_enclosure
                << "%; it may be the wrong cavity (check the seed point, or give --seed-point)";
            r.warnings.push_back({"not_enclosed", msg.str(), {{"enclosure", r.enclosure}, {"min_enclosure", p.min_enclosure}}});
        }
        r.mesh = std::move(poly.mesh);
        // On the input's grid: outside the bone's box is the air around the skull.
        if (p.keep_mask) r.mask = r.work_box ? uncrop(poly.mask, grid, *r.work_box, 0) : std::move(poly.mask);
        if (p.keep_labels) r.labels = r.work_box ? uncrop(ws.labels, grid, *r.work_box, kOther) : ws.labels;
        r.other_value = poly.other_value;
        r.half_max = poly.half_max;
        r.mask_volume_ml = double(poly.mask_voxels) * grid.voxel_volume_mm3() / 1000.0;
        r.ecv_ml = meshpost::signed_volume_mm3(r.mesh) / 1000.0;
        r.surface_area_mm2 = meshpost::surface_area_mm2(r.mesh);
        r.timings_s.polygonize = sw.lap();
    }

    // The share of the surface on bone, the closing surfaces that dip into holes made flush,
    // the closing surfaces listed, the share of the surface facing other space (leaks).
    void bone_contact_and_dips() {
        // The probe: past a voxel's partial volume, within the wall (bone_contact.h).
        BoneContactParams bcp = p.bone_contact;
        if (!(bcp.offset_mm > 0)) bcp.offset_mm = std::max(grid.smallest_spacing(), r.max_distance_mm / 50.0);
        r.bone_contact_offset_mm = bcp.offset_mm;
        // The CT alone decides the closing surfaces (the dips, the list): a plug of the void fill
        // across a hole is not bone there.
        BoneContact contact = bone_contact(r.mesh, *work, r.params.isovalue, bcp);
        std::vector<std::array<uint32_t, 3>> neighbours;  // the faces' edge neighbours, found beside the dips' loop
        std::vector<uint8_t> face_on_other = faces_on_other_space(r.mesh, ws.labels);
        mark_cut_caps(face_on_other, r.mesh, r.openings.openings, grid.largest_spacing());
        if (dips) {
            r.timings_s.bone_contact = sw.lap();
            // The faces do not change from here on: their analysis and their edge neighbours (for
            // the closing surfaces) are computed beside the dips' loop, on one thread (an error
            // there leaves them empty: the topology for the caller's own analysis to report, the
            // neighbours for the closing surfaces to compute again).
            std::optional<meshpost::TopologyReport> topology;
            const std::function<void()> analyze_faces = [&] {
                omp_set_num_threads(1);  // this thread's own parallel regions
                try {
                    topology = meshpost::analyze_connectivity(r.mesh);
                    neighbours = meshpost::face_neighbours(r.mesh);
                } catch (const meshpost::InvalidMesh&) {
                }
            };
            r.dips = flush_dips(r.mesh, contact.face_on_bone, work->geometry(), plugs, r.params.void_radius_mm, p.dips,
                               p.dips.sunk_wall_share > 0 ? face_on_other : std::vector<uint8_t>(), analyze_faces);
            if (topology) {  // and the positions, now final
                topology->degenerate_faces += meshpost::count_collinear_faces(r.mesh);
                r.topology = topology;
            }
            plugs = std::vector<size_t>();
            r.timings_s.dips = sw.lap();
            if (r.dips.flushed > 0) {
                r.ecv_ml = meshpost::signed_volume_mm3(r.mesh) / 1000.0;
                r.surface_area_mm2 = meshpost::surface_area_mm2(r.mesh);
                contact = bone_contact(r.mesh, *work, r.params.isovalue, bcp, contact.face_on_bone,
                                       r.dips.moved_vertices);
            }
        }
        // The share on the skull as segmented (its thin bone and filled voids are bone) for the
        // report and the picture.
        const Volume<uint8_t>& labels = ws.labels;
        BoneContact skull = bone_contact(r.mesh, *work, r.params.isovalue, bcp,
                                         PackedMask::where(labels.geometry(), [&](size_t i) { return labels[i] == kBone; }));
        r.bone_contact = skull.share;
        r.face_on_bone = std::move(skull.face_on_bone);
        r.face_on_bone_ct = contact.face_on_bone;
        {
            double leak = 0, all = 0;
            r.face_leaks.assign(r.mesh.faces.size(), 0);
            for (size_t f = 0; f < r.mesh.faces.size(); ++f) {
                const auto& t = r.mesh.faces[f];
                const auto& A = r.mesh.vertices[t[0]];
                const auto& B = r.mesh.vertices[t[1]];
                const auto& C = r.mesh.vertices[t[2]];
                const double u[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]}, v[3] = {C[0] - A[0], C[1] - A[1], C[2] - A[2]};
                const double area = 0.5 * std::sqrt(std::pow(u[1] * v[2] - u[2] * v[1], 2) + std::pow(u[2] * v[0] - u[0] * v[2], 2) +
                                                    std::pow(u[0] * v[1] - u[1] * v[0], 2));
                all += area;
                if (face_on_other[f] == 1 && !r.face_on_bone[f]) {
                    r.face_leaks[f] = 1;
                    leak += area;
                }
            }
            r.leak_share = all > 0 ? leak / all : 0.0;
        }
        if (r.bone_contact < p.min_bone_contact) {
            std::ostringstream msg;
            msg << "bone contact " << r.bone_contact << ": only " << 100.0 * r.bone_contact
                << "% of the surface lies on bone (the CT " << bcp.offset_mm
                << " mm outside it >= the isovalue, or the skull's thin bone or filled voids there), expected >= "
                << 100.0 * p.min_bone_contact
                << "%; parts of the surface are not on bone: an opening may be closed through the "
                   "cavity, or the surface leaks out of the braincase (look at the QC picture, where "
                   "they are orange)";
            msg << isovalue_hint(r.params);
            r.warnings.push_back({"bone_contact_low", msg.str(),
                                  {{"bone_contact", r.bone_contact}, {"min_bone_contact", p.min_bone_contact},
                                   {"probe_mm", bcp.offset_mm}}});
        }
        if (r.leak_share > p.max_leak_share) {
            std::ostringstream msg;
            msg << "possible leak: " << 100.0 * r.leak_share
                << "% of the surface faces other empty space (not bone, not the cap of a closed opening), "
                   "expected <= "
                << 100.0 * p.max_leak_share
                << "%: the surface may leave the braincase through thin or missing bone (into the nasal "
                   "cavity, an orbit, a canal); look at the QC picture (red), or try a lower --iso";
            r.warnings.push_back({"possible_leak", msg.str(),
                                  {{"leak_share", r.leak_share}, {"max_leak_share", p.max_leak_share}}});
        }
        list_closing_surfaces(r, grid, neighbours, contact.face_on_bone);
        r.timings_s.bone_contact += sw.lap();
    }
};

template <class T>
ExtractionResult run_extraction(Extraction<T>& e) {
    e.bone_and_distance();
    e.segment();
    e.close();
    e.polygonize_cavity();
    e.bone_contact_and_dips();
    e.r.timings_s.total = e.total.lap();
    return std::move(e.r);
}

}  // namespace

std::vector<DerivedLength> derived_lengths(const ExtractParams& p, const ExtractionResult& r) {
    const double v = r.params.smallest_spacing_mm, d = r.max_distance_mm, rv = r.params.void_radius_mm;
    auto num = [](double x) {
        std::ostringstream s;
        s << x;
        return s.str();
    };
    std::vector<DerivedLength> out = {
        {"voxel", v, "the grid's smallest spacing"},
        {"depth", d, "the cavity's largest inscribed ball (distance to bone at its deepest point)"},
        {"void_radius", rv,
         p.void_fill.radius_mm ? "given (--void-radius-mm)" : num(p.void_fill.radius_voxels) + " x voxel"},
        {"thin_bone_reach", 2 * v, "2 x voxel (a ridge's sides)"},
        {"opening_radius", r.openings.radius_mm,
         p.openings.radius_mm > 0 ? "given (--opening-radius-mm)" : num(p.openings.radius_fraction) + " x depth"},
        {"wide_opening_radius", r.openings.wide_radius_mm,
         r.openings.wide_radius_mm > 0 ? num(p.openings.wide_radius_fraction) + " x depth" : "off"},
        {"opening_far_distance", p.openings.far_voxels * v, num(p.openings.far_voxels) + " x voxel"},
        {"canal_reach", p.openings.canal_reach_fraction * r.openings.radius_mm,
         num(p.openings.canal_reach_fraction) + " x opening_radius"},
        {"air_exclusion_radius", 2 * v, "2 x voxel"},
        {"crease_max_mean_depth", p.creases.max_mean_depth_fraction * rv,
         num(p.creases.max_mean_depth_fraction) + " x void_radius"},
        {"dip_min_mean_depth", p.dips.min_mean_depth_voxels * v, num(p.dips.min_mean_depth_voxels) + " x voxel"},
        {"dip_max_move", rv, "void_radius"},
        {"dip_wall_length", p.dips.wall_length_voxels * v, num(p.dips.wall_length_voxels) + " x voxel"},
        {"fair_max_move", p.dips.fair_max_move_voxels * v, num(p.dips.fair_max_move_voxels) + " x voxel"},
        {"bone_contact_offset", r.bone_contact_offset_mm,
         p.bone_contact.offset_mm > 0 ? "given" : "max(voxel, depth / 50)"},
    };
    for (size_t i = 0; i < p.creases.keep_closed_fractions.size(); ++i)
        out.push_back({"crease_closed_radius_" + std::to_string(i + 1), p.creases.keep_closed_fractions[i] * rv,
                       num(p.creases.keep_closed_fractions[i]) + " x void_radius"});
    return out;
}

std::optional<CropBox> bone_work_box(const Volume<uint8_t>& bone, double void_radius_mm) {
    const LabelBox b = box_of(bone, [](uint8_t v) { return v != 0; });
    if (b.empty()) return std::nullopt;
    const Geometry& g = bone.geometry();
    CropBox box;
    bool whole = true;
    for (size_t a = 0; a < 3; ++a) {
        const int64_t margin = int64_t(std::ceil(2 * void_radius_mm / g.spacing[a])) + 2;
        box.lo[a] = std::max<int64_t>(0, b.lo[a] - margin);
        box.hi[a] = std::min<int64_t>(g.dims[a], b.hi[a] + margin + 1);
        whole = whole && box.lo[a] == 0 && box.hi[a] == g.dims[a];
    }
    if (whole) return std::nullopt;
    return box;
}


template <class T>
ExtractionResult extract_endocast(const Volume<T>& ct, const ExtractParams& p) {
    static_assert(is_ct_type<T>, "extract_endocast: the CT is float or int16 (volume.h)");
    Extraction<T> e(ct, p);
    return run_extraction(e);
}

template <class T>
ExtractionResult extract_endocast(Volume<T>&& ct, const ExtractParams& p) {
    static_assert(is_ct_type<T>, "extract_endocast: the CT is float or int16 (volume.h)");
    Extraction<T> e(std::move(ct), p);
    return run_extraction(e);
}

template ExtractionResult extract_endocast<float>(const Volume<float>&, const ExtractParams&);
template ExtractionResult extract_endocast<int16_t>(const Volume<int16_t>&, const ExtractParams&);
template ExtractionResult extract_endocast<float>(Volume<float>&&, const ExtractParams&);
template ExtractionResult extract_endocast<int16_t>(Volume<int16_t>&&, const ExtractParams&);

}  // namespace endocast
