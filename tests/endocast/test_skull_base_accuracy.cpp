// Issue 18's bars on the anatomical skull-base phantoms (phantom --skull-base): living, dry and
// macaque, tilted, with a cervical spine, cropped through the braincase. The truth is the cavity
// bounded by the inner table and closed flush across every hole (phantom_cavity_signed_distance).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "method/refine.h"
#include "endocast/stages/resample.h"
#include "meshpost/measure.h"
#include "meshpost/topology.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::expect_clean_genus0;
using endocast::testing::to_float;

namespace {


struct Deviation {
    double mean = 0;          ///< area-weighted mean |signed distance| (mm)
    double mean_signed = 0;   ///< area-weighted mean signed distance (mm; < 0: inside the truth)
    double inside = 0;        ///< deepest vertex inside the truth (mm, >= 0)
    double outside = 0;       ///< farthest vertex outside it (mm, >= 0)
    Vec3 inside_at{0, 0, 0}, outside_at{0, 0, 0};
};

// A section through the plane at c spanned by the unit vectors a and b, +-half_a and +-half_b mm
// at 0.1 mm a pixel, written as a PPM: the CT in grey (the endocast's voxels bluer), the truth's
// zero set green, the mesh red
// (diagnostics: SB_SLICE="cx cy cz ax ay az bx by bz half_a half_b file.ppm").
void write_section(const meshpost::TriangleMesh& m, const PhantomResult& ph, const Volume<uint8_t>* mask, const char* sl) {
    double c[3], a[3], b[3], ha, hb;
    char file[512];
    if (std::sscanf(sl, "%lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %lf %511s", &c[0], &c[1], &c[2], &a[0], &a[1], &a[2], &b[0],
                    &b[1], &b[2], &ha, &hb, file) == 12) {
        const double px = 0.1;
        const int W = int(2 * ha / px), H = int(2 * hb / px);
        std::vector<unsigned char> img(size_t(W) * H * 3);
        const auto& g = ph.ct.geometry();
        std::vector<double> truth(size_t(W) * H);
#pragma omp parallel for
        for (int j = 0; j < H; ++j)
            for (int i = 0; i < W; ++i) {
                const double u = -ha + (i + 0.5) * px, v = hb - (j + 0.5) * px;
                const Vec3 w{c[0] + u * a[0] + v * b[0], c[1] + u * a[1] + v * b[1], c[2] + u * a[2] + v * b[2]};
                const Vec3 ijk = g.world_to_index(w);
                const int64_t x = std::lround(ijk[0]), y = std::lround(ijk[1]), z = std::lround(ijk[2]);
                double ct = 0;
                const bool inside = x >= 0 && y >= 0 && z >= 0 && x < ph.ct.dims()[0] && y < ph.ct.dims()[1] && z < ph.ct.dims()[2];
                if (inside) ct = ph.ct(x, y, z);
                const double grey = std::clamp((ct + 200.0) / 1400.0, 0.0, 1.0);
                truth[size_t(j) * W + i] = phantom_cavity_signed_distance(ph, w);
                unsigned char* q = &img[(size_t(j) * W + i) * 3];
                q[0] = q[1] = q[2] = (unsigned char)(40 + 180 * grey);
                if (mask && inside && (*mask)(x, y, z)) q[2] = (unsigned char)std::min(255, q[2] + 60);  // the endocast's voxels: bluer
            }
        for (int j = 1; j < H; ++j)  // the truth's zero set: green
            for (int i = 1; i < W; ++i) {
                const double t = truth[size_t(j) * W + i];
                if ((t < 0) != (truth[size_t(j) * W + i - 1] < 0) || (t < 0) != (truth[size_t(j - 1) * W + i] < 0)) {
                    unsigned char* q = &img[(size_t(j) * W + i) * 3];
                    q[0] = 0, q[1] = 200, q[2] = 0;
                }
            }
        const double nrm[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
        for (const auto& f : m.faces) {  // the mesh's section: red
            double s3[3], uv[3][2];
            for (int k = 0; k < 3; ++k) {
                const auto& P = m.vertices[f[k]];
                const double d0 = P[0] - c[0], d1 = P[1] - c[1], d2 = P[2] - c[2];
                s3[k] = d0 * nrm[0] + d1 * nrm[1] + d2 * nrm[2];
                uv[k][0] = d0 * a[0] + d1 * a[1] + d2 * a[2];
                uv[k][1] = d0 * b[0] + d1 * b[1] + d2 * b[2];
            }
            std::vector<std::array<double, 2>> pts;
            for (int k = 0; k < 3; ++k) {
                const int l = (k + 1) % 3;
                if ((s3[k] < 0) != (s3[l] < 0)) {
                    const double t = s3[k] / (s3[k] - s3[l]);
                    pts.push_back({uv[k][0] + t * (uv[l][0] - uv[k][0]), uv[k][1] + t * (uv[l][1] - uv[k][1])});
                }
            }
            if (pts.size() != 2) continue;
            for (int st = 0; st <= 20; ++st) {
                const double u = pts[0][0] + (pts[1][0] - pts[0][0]) * st / 20.0, v = pts[0][1] + (pts[1][1] - pts[0][1]) * st / 20.0;
                const int i = int((u + ha) / px), j = int((hb - v) / px);
                if (i < 0 || j < 0 || i >= W || j >= H) continue;
                unsigned char* q = &img[(size_t(j) * W + i) * 3];
                q[0] = 255, q[1] = 0, q[2] = 0;
            }
        }
        if (FILE* fo = std::fopen(file, "wb")) {
            std::fprintf(fo, "P6 %d %d 255\n", W, H);
            std::fwrite(img.data(), 1, img.size(), fo);
            std::fclose(fo);
        }
    }
}

// Distances of the mesh's vertices to the true surface, area-weighted (a third of each face's area
// to each corner), leaving out the vertices within `skip_below_mm` above the volume's lower face.
Deviation deviation(const meshpost::TriangleMesh& m, const PhantomResult& ph, double skip_below_mm = -1e9,
                    const Volume<uint8_t>* mask = nullptr) {
    const std::vector<double> w = endocast::testing::vertex_areas(m);
    std::vector<double> sd(m.vertices.size(), 0.0);
#pragma omp parallel for schedule(dynamic, 4096)
    for (int64_t v = 0; v < int64_t(m.vertices.size()); ++v) {
        const auto& p = m.vertices[size_t(v)];
        sd[size_t(v)] = phantom_cavity_signed_distance(ph, {p[0], p[1], p[2]});
    }
    Deviation d;
    double sum = 0, sum_signed = 0, wsum = 0;
    for (size_t v = 0; v < m.vertices.size(); ++v) {
        const auto& p = m.vertices[v];
        if (ph.cropped && p[2] < ph.crop_plane_z_mm + skip_below_mm) continue;
        sum += w[v] * std::fabs(sd[v]);
        sum_signed += w[v] * sd[v];
        wsum += w[v];
        if (-sd[v] > d.inside) {
            d.inside = -sd[v];
            d.inside_at = {p[0], p[1], p[2]};
        }
        if (sd[v] > d.outside) {
            d.outside = sd[v];
            d.outside_at = {p[0], p[1], p[2]};
        }
    }
    if (std::getenv("SB_BANDS")) {  // mean signed distance by height band (diagnostics)
        for (double z0 = -80; z0 < 80; z0 += 20) {
            double a = 0, ws = 0;
            for (size_t v = 0; v < m.vertices.size(); ++v) {
                const double zr = m.vertices[v][2] - ph.cavity_centre_world[2];
                if (zr < z0 || zr >= z0 + 20) continue;
                a += w[v] * sd[v];
                ws += w[v];
            }
            if (ws > 0) std::printf("  z %+4.0f..%+4.0f: area %7.0f mm^2, mean signed %+.3f mm\n", z0, z0 + 20, ws, a / ws);
        }
    }
    if (std::getenv("SB_FAR")) {  // vertices more than 1.5 mm off, by the nearest opening (diagnostics)
        std::map<std::string, std::array<double, 4>> by;  // count, max outside, max inside, distance to opening
        for (size_t v = 0; v < m.vertices.size(); ++v) {
            if (std::fabs(sd[v]) < 1.5) continue;
            const auto& p = m.vertices[v];
            std::string best = "-";
            double bd = 1e9;
            for (const PhantomOpening& o : ph.openings) {
                const double dd = std::hypot(p[0] - o.centre_world[0], p[1] - o.centre_world[1], p[2] - o.centre_world[2]);
                if (dd < bd) bd = dd, best = o.name;
            }
            auto& e = by[best];
            e[0] += 1;
            e[1] = std::max(e[1], sd[v]);
            e[2] = std::max(e[2], -sd[v]);
            e[3] = e[0] == 1 ? bd : std::min(e[3], bd);
        }
        for (const auto& [k, e] : by)
            std::printf("  %-32s %5.0f vertices, outside %.2f, inside %.2f mm, nearest %.1f mm from its centre\n", k.c_str(),
                        e[0], e[1], e[2], e[3]);
    }
    if (const char* spec = std::getenv("SB_SLICE")) write_section(m, ph, mask, spec);
    d.mean = wsum > 0 ? sum / wsum : 0;
    d.mean_signed = wsum > 0 ? sum_signed / wsum : 0;
    return d;
}

// Issue 18's bars are ECV within 0.5 %, mean distance <= 0.1 mm, nothing more than 2 mm inside
// (a pocket cut) or outside (a leak past a foramen) the truth, genus 0. Each case asserts what the
// closure reaches today (measured, docs/accuracy.md, with a small margin) so that a regression
// fails; where that is short of the bar the gap is written next to it (below, with the
// cases). Without --thin-bone the cavity leaks into the orbits through their 0.5-1 mm roofs and
// the olfactory groove is cut (the two cases with thin_bone 0).
struct Case {
    const char* name;
    PhantomPreset preset;
    double tilt = 0;
    bool spine = false;
    double thin_bone = 0.5;  // --thin-bone (0.5: the default)
    double ecv_pct = 0.5, mean_mm = 0.1, inside_mm = 2.0, outside_mm = 2.0;  // bars asserted
    double crop_base_mm = 0;  // > 0: cropped through the braincase (vertices within a voxel of the border left out)
    SurfaceMode surface = SurfaceMode::Iso;
};
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

}  // namespace

class SkullBaseAccuracy : public ::testing::TestWithParam<Case> {};

TEST_P(SkullBaseAccuracy, EcvSurfaceAndTopologyWithinTheBars) {
    const Case& c = GetParam();
    PhantomParams pp;
    pp.preset = c.preset;
    pp.skull_base = true;
    pp.tilt_deg = c.tilt;
    pp.spine = c.spine;
    pp.crop_base_mm = c.crop_base_mm;
    const PhantomResult ph = generate_phantom(pp);
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    p.binarize.thin_bone_prominence = c.thin_bone;
    p.surface = c.surface;
    const ExtractionResult r = extract_endocast(to_float(ph.ct), p);
    const Deviation d = deviation(r.mesh, ph, ph.ct.geometry().spacing[2], &r.mask);
    std::printf("%s: ECV %.2f mL vs %.2f (%+.3f %%), mean distance %.3f mm (signed %+.3f), deepest inside %.2f mm "
                "at (%.1f, %.1f, %.1f), farthest outside %.2f mm at (%.1f, %.1f, %.1f), bone contact %.3f, genus %ld\n",
                c.name, r.ecv_ml, ph.true_ecv_ml, 100 * (r.ecv_ml / ph.true_ecv_ml - 1), d.mean, d.mean_signed,
                d.inside, d.inside_at[0], d.inside_at[1], d.inside_at[2], d.outside, d.outside_at[0],
                d.outside_at[1], d.outside_at[2], r.bone_contact, meshpost::analyze_topology(r.mesh).genus);
    EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, c.ecv_pct / 100);
    EXPECT_LE(d.mean, c.mean_mm);
    EXPECT_LE(d.inside, c.inside_mm);    // a pocket cut
    EXPECT_LE(d.outside, c.outside_mm);  // a leak past a foramen
    if (c.crop_base_mm == 0) EXPECT_GE(r.bone_contact, 0.9);
    expect_clean_genus0(r.mesh);
}

// Measured (1 mm voxels, 0.5 mm macaque; docs/accuracy.md): ECV %, mean, inside, outside (mm).
// With the creases the void fill closed given back (creases.h), thin bone recovered (the default
// --thin-bone 0.5) and the closing surfaces that dip into the holes the void fill plugged made
// flush with their rims (dips.h), every ECV is within the 0.5 % and every mean distance
// within its 0.1 mm; the sella under the dorsum, far deeper than its mouth, comes back as a pocket
// (its mouth is half its cross-section: creases.h), and so do the void fill's sheets left inside
// the endocast (the macaque's lid over its sella), and the side toward the endocast of a plug the
// ball joined a crease to (the wedge beside the right internal acoustic meatus, joined to its
// plug and the jugular foramen's: CreaseParams::plug_lead_voxels). Where the border crops the
// cavity it is a wall for the creases' ball too (the cropped phantom's fossa corner). The spine
// phantom's foramen magnum, cut by a plane above its lateral rims, goes onto its thin plate too. The tilted grid's foramen magnum, closed by a voxel
// staircase (2.75 mm inside; its truth a bowl sagging 1-2 mm below the chord of its rim), goes
// onto the thin plate continuing the table (DipParams::fair_max_move_voxels). The tilted phantoms' oblique
// foramina lacera (3.4 mm outside before the flush grew each patch across the hole's wall,
// DipParams::wall_rings; 2.28 living, 2.29 dry with eight rings, which climbed 1.5 mm of the
// overhanging wall's slivers) are within the bar since the walk is measured by its length
// (DipParams::wall_length_voxels: 1.82 living, 1.99 dry). The macaque's
// foramen magnum, closed 2.5 mm down its canal (2.66 mm outside), is raised to the canal's mouth
// (a closure sunk down its channel, DipParams::sunk_wall_share).
INSTANTIATE_TEST_SUITE_P(
    Presets, SkullBaseAccuracy,
    ::testing::Values(
        // -0.162 %, 0.060, 1.95 (the left internal acoustic meatus: 1.76 before the wall walk was
        // measured by length, 2.00 at 3.5 voxels; 1.87 before the thin bone's tips went back, return_thin_bone_tips;
        // 2.98 before the plugs were split: the wedge by the right internal acoustic meatus), 1.92 (the left hypoglossal canal: 2.02 before the walls of the dips
        // reached past their footprint, DipParams::wall_footprint; the jugular foramina were 3.46
        // before their dips were flushed): every bar of the issue met
        Case{"living", PhantomPreset::Human, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0},
        // -0.140 %, 0.055, 1.73 (2.09 before the thin bone's tips went back: the ridge past the
        // lip at the sella's rim, read as a 0.5 mm plate with the cavity on both sides; 2.98 before
        // the plugs were split), 1.59 (2.02 before the wall footprint; the sella restored as a
        // pocket: it was 5.28 inside): every bar of the issue met
        Case{"dry", PhantomPreset::Dry, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0},
        // -0.232 %, 0.035, 1.17 (1.45 before the plugs were split; 2.40 and -0.102 % before the
        // void fill's sheets came back: the lid's remnant over the sella), 0.95 (2.66 and +0.037 %
        // before closures sunk down their channel were raised, DipParams::sunk_wall_share: the
        // foramen magnum, 12 mm wide, closed 2.5 mm down its canal): every bar of the issue met
        Case{"macaque", PhantomPreset::Macaque, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0},
        // -0.124 %, 0.058, 1.65 (the foramen magnum's closure, a voxel staircase up to 2.75 mm
        // inside before closures across wide openings went onto their thin plate,
        // DipParams::fair_max_move_voxels), 1.80 (the right foramen lacerum: 3.46 before the wall
        // growth, 2.28 before the walk by length; the superior orbital fissure was 3.64): every
        // bar of the issue met
        Case{"living_tilt25", PhantomPreset::Human, 25, false, 0.5, 0.5, 0.1, 2.0, 2.0},
        // -0.121 %, 0.053, 1.65 (1.99, the foramen magnum's rim, before its closure went onto its
        // thin plate; 2.74 before the thin bone's tips went
        // back ahead of the handles: the false plate past the sella's lip bridged the cavity to
        // bone, and the handle's cut left a sheet of air as bone there), 2.29 (the right foramen
        // lacerum: 3.44 before the wall growth, 3.20 before the rim was retried wider where the
        // membrane crossed the mesh, DipParams::rim_rings_retry, then 2.09 before the wall
        // footprint 1.5, 2.29 before the walk up the wall was measured by length; now 1.80):
        // every bar of the issue met
        Case{"dry_tilt25", PhantomPreset::Dry, 25, false, 0.5, 0.5, 0.1, 2.0, 2.0},
        // -0.168 %, 0.060, 1.69 (2.59 before cut caps went onto their thin plate: the foramen
        // magnum's cut plane, fitted to a rim lower at its sides, lay 3.5 mm above the lateral
        // rims), 1.62 (2.04 before the wall footprint 1.5; the cervical canal is cut at the
        // foramen magnum; the jugular foramen was 4.35, then 2.44 before the wall growth): every
        // bar of the issue met
        Case{"living_spine", PhantomPreset::Human, 0, true, 0.5, 0.5, 0.1, 2.0, 2.0},
        // --thin-bone 0: -0.321 %, 0.175, 6.50 (olfactory groove), 11.72 (right orbit, through its roof)
        Case{"living_no_thin_bone", PhantomPreset::Human, 0, false, 0, 0.5, 0.21, 7.0, 13.0},
        // --thin-bone 0: +0.301 %, 0.395, 7.48, 15.80 (the orbit)
        Case{"living_spine_no_thin_bone", PhantomPreset::Human, 0, true, 0, 0.5, 0.45, 8.3, 17.0},
        // cropped 30 mm above the cavity's lowest point (issue 18: nothing more than 2 mm inside
        // except within a voxel of the border): -0.131 %, 0.053, 1.05, 1.86 (2.21 inside, the
        // right middle fossa's tip 4.5 mm above the border, before the crease candidates' ball
        // closed against the border as a wall: the superior orbital fissure's slit, cut open by
        // the border, joined the void fill's sliver along the fossa's wall to the orbit; 2.34, the
        // sella's rim, before the thin bone's tips went back); the middle fossae and the sella the border cuts are lobes and pockets of the
        // cavity, closed flat at the border (the fossae were cut ~8 mm above it: -2.6 %, 11 mm
        // inside; the sella, kept closed while the border counted as an opening for the creases:
        // 6.33 mm inside): every bar of the issue met
        Case{"dry_cropped30", PhantomPreset::Dry, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0, 30.0},
        // cropped 45 mm above the lowest point, over the anterior fossa: -0.139 %, 0.043, 0.87, 0.76.
        // Before the seeds were chosen again when the border cuts a section of the cavity
        // (SeedParams::border_retry_section_share) its border balls ate most of it and left a
        // 116 mL part, refused as not enclosed (exit 5; cropped 42 mm: 379 of 1127 mL, exit 0)
        Case{"dry_cropped45", PhantomPreset::Dry, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0, 45.0},
        // the macaque cropped 5 mm above its lowest point: -0.229 %, 0.037, 1.85, 2.74 (at the
        // border: a canal the border cuts closed flat there, left to a later change). Before, the
        // balls of the border flooded the posterior fossa the border cuts from below and the
        // openings stage cut it by a plane: -8.8 %, 9.24 mm inside
        Case{"macaque_cropped5", PhantomPreset::Macaque, 0, false, 0.5, 0.5, 0.1, 2.0, 3.0, 5.0},
        // --surface half-max (the half-maximum height, each boundary voxel's threshold half-way
        // between the cavity and the local bone peak): +0.000 %, 0.054, 1.76, 1.94 (the issue's
        // bars met; outside 1.61 before the thin bone's tips went back: the cavity's median, which
        // sets every threshold, moved, and the left optic canal's rim with it; 2.98 inside before the plugs were split); before its
        // channels were seeded at the work box's edge too it grew 3 voxels down the foramina
        // lacera (their plugs meet the outside 25 mm below, beyond the box): 6.60 outside
        Case{"living_half_max", PhantomPreset::Human, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0, 0, SurfaceMode::HalfMax},
        // -0.035 %, 0.045, 1.67, 2.03 (the right foramen lacerum: 2.33 before the walk by
        // length; iso: 1.65, 1.80)
        Case{"dry_tilt25_half_max", PhantomPreset::Dry, 25, false, 0.5, 0.5, 0.1, 2.0, 2.1, 0, SurfaceMode::HalfMax},
        // -0.064 %, 0.049, 1.69, 1.60: every bar of the issue met (iso: 1.72 / 1.68)
        Case{"dry_half_max", PhantomPreset::Dry, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0, 0, SurfaceMode::HalfMax},
        // -0.028 %, 0.030, 1.19, 1.05: every bar of the issue met (2.66 outside and +0.242 % before
        // the sunk foramen magnum was raised)
        Case{"macaque_half_max", PhantomPreset::Macaque, 0, false, 0.5, 0.5, 0.1, 2.0, 2.0, 0, SurfaceMode::HalfMax}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

// The coarse-to-fine path (refine.h): the method on the phantom block-averaged by 2 (its grid the
// one the method is measured on above: 1 mm, the macaque 0.5 mm), its region's band decided again
// on the phantom's own grid (0.5 mm, 0.25 mm), a few planes at a time. The bars of issue 18 on the
// fine grid, and the surface nearer the truth than the coarse run's (the walls at the fine
// isosurface; the closures stay the coarse run's). Before the closures clipped the band to the
// coarse mesh, the canals the flush raised the closure out of came back (2.2-3.4 mm outside,
// genus 1-5).
struct RefineCase {
    const char* name;
    PhantomPreset preset;
    double spacing_mm;
    int factor;
    double ecv_pct, mean_mm, inside_mm, outside_mm;
};
void PrintTo(const RefineCase& c, std::ostream* os) { *os << c.name; }

class SkullBaseRefine : public ::testing::TestWithParam<RefineCase> {};

TEST_P(SkullBaseRefine, CoarseToFineMeetsTheBarsOnTheFineGrid) {
    const RefineCase& c = GetParam();
    PhantomParams pp;
    pp.preset = c.preset;
    pp.skull_base = true;
    pp.spacing = {c.spacing_mm, c.spacing_mm, c.spacing_mm};
    const PhantomResult ph = generate_phantom(pp);
    const Volume<float> fine = to_float(ph.ct);
    const int factor = c.factor;
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    p.keep_labels = true;
    const Volume<float> small = downsample(fine, factor);
    const ExtractionResult coarse = extract_endocast(small, p);
    RefineParams rp;
    rp.isovalue = coarse.params.isovalue;
    rp.other_value = coarse.other_value;
    rp.slab_planes = 16;  // many slabs
    const Volume<uint8_t> classes =
        refine_classes(coarse.mask, coarse.labels, small, rp.isovalue, coarse.mesh, coarse.face_on_bone_ct);
    rp.clip_mesh = &coarse.mesh;
    const Geometry& g = fine.geometry();
    size_t reads = 0;
    const PlaneReader read = [&](int64_t z, float* dst) {
        ++reads;
        std::copy(&fine(0, 0, z), &fine(0, 0, z) + g.dims[0] * g.dims[1], dst);
    };
    const RefineResult r = refine_full_resolution(g, read, classes, factor, rp);
    const double ecv = meshpost::signed_volume_mm3(r.mesh) / 1000.0;
    const Deviation dc = deviation(coarse.mesh, ph);
    const Deviation d = deviation(r.mesh, ph);
    std::printf("%s coarse: mean %.3f, inside %.2f at (%.1f, %.1f, %.1f), outside %.2f at (%.1f, %.1f, %.1f)\n", c.name,
                dc.mean, dc.inside, dc.inside_at[0], dc.inside_at[1], dc.inside_at[2], dc.outside, dc.outside_at[0],
                dc.outside_at[1], dc.outside_at[2]);
    std::printf("%s refined from x%d: ECV %.2f mL vs %.2f (%+.3f %%; coarse %+.3f %%), mean %.3f mm, inside %.2f at "
                "(%.1f, %.1f, %.1f), outside %.2f at (%.1f, %.1f, %.1f); band %zu voxels, %zu changed, %zu slabs, "
                "%zu clipped, %zu pieces dropped, genus %ld\n",
                c.name, factor, ecv, ph.true_ecv_ml, 100 * (ecv / ph.true_ecv_ml - 1),
                100 * (coarse.ecv_ml / ph.true_ecv_ml - 1), d.mean, d.inside, d.inside_at[0], d.inside_at[1],
                d.inside_at[2], d.outside, d.outside_at[0], d.outside_at[1], d.outside_at[2], r.band_voxels,
                r.changed_voxels, r.slabs, r.clipped_voxels, r.pieces_removed, meshpost::analyze_topology(r.mesh).genus);
    EXPECT_GT(r.slabs, 4u);
    EXPECT_EQ(reads, size_t(r.box.size()[2]));  // each plane of the box read once
    EXPECT_GT(r.changed_voxels, 0u);
    EXPECT_NEAR(ecv / ph.true_ecv_ml, 1.0, c.ecv_pct / 100);
    EXPECT_NEAR(r.region_volume_ml / ecv, 1.0, 0.02);
    EXPECT_LE(d.mean, c.mean_mm);
    EXPECT_LT(d.mean, 0.8 * dc.mean);
    EXPECT_LE(d.inside, c.inside_mm);
    EXPECT_LE(d.outside, c.outside_mm);
    expect_clean_genus0(r.mesh);
}

INSTANTIATE_TEST_SUITE_P(Presets, SkullBaseRefine,
                         ::testing::Values(
                             // -0.180 % (coarse -0.219), mean 0.023 (0.038), inside 1.48, outside 0.90
                             RefineCase{"macaque", PhantomPreset::Macaque, 0.25, 2, 0.5, 0.05, 2.0, 2.0},
                             // -0.116 % (coarse -0.111), mean 0.034 (0.061), inside 1.81, outside 1.35
                             RefineCase{"dry", PhantomPreset::Dry, 0.5, 2, 0.5, 0.05, 2.0, 2.0}),
                         [](const ::testing::TestParamInfo<RefineCase>& i) { return std::string(i.param.name); });
