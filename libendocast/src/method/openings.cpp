// The openings of the braincase closed at their rims: far tubes of the cavity cut by planes fitted to them (openings.h).
#include "endocast/stages/openings.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>
#include <vector>

#include "endocast/stages/components.h"
#include "endocast/stages/distance.h"
#include "endocast/stages/morphology.h"
#include "endocast/stages/resample.h"
#include "method/label_box.h"

namespace endocast {
namespace {

constexpr double kPi = 3.14159265358979323846;
// The second look: a far part deeper than this times its mouth's depth is a chamber, not a canal.
constexpr double kChamberWidening = 1.15;

// The smallest float >= t: a clamp for squared_distance_transform_clamped that keeps every test
// "value > t" and "value <= t" (t in double) exactly as on the unclamped transform.
float clamp_at_least(double t) {
    float c = static_cast<float>(t);
    if (double(c) < t) c = std::nextafter(c, std::numeric_limits<float>::infinity());
    return c;
}

// The box lo..hi (voxel indices in g) grown by ceil(margin_mm / spacing) + extra voxels on every
// side and clipped to g's grid: the sub-grid's geometry; `first` gets its first voxel's index in g.
Geometry grown_box(const Geometry& g, const std::array<int64_t, 3>& lo, const std::array<int64_t, 3>& hi,
                   double margin_mm, int64_t extra, std::array<int64_t, 3>& first) {
    Geometry s = g;
    for (int a = 0; a < 3; ++a) {
        const int64_t m = int64_t(std::ceil(margin_mm / g.spacing[a])) + extra;
        first[a] = std::max<int64_t>(0, lo[a] - m);
        s.dims[a] = std::min<int64_t>(g.dims[a] - 1, hi[a] + m) - first[a] + 1;
    }
    s.origin = g.index_to_world(double(first[0]), double(first[1]), double(first[2]));
    return s;
}

// Along the normal n and distance from the axis through c (mm) of voxel (x, y, z) of g: where a
// voxel lies relative to an opening's cut (plane through c, cylinder around the axis).
std::pair<double, double> along_and_radial(const Geometry& g, const Eigen::Vector3d& c, const Eigen::Vector3d& n,
                                           int64_t x, int64_t y, int64_t z) {
    const Vec3 w = g.index_to_world(double(x), double(y), double(z));
    const Eigen::Vector3d d = Eigen::Vector3d(w[0], w[1], w[2]) - c;
    const double along = d.dot(n);
    return {along, (d - along * n).norm()};
}

// Index box (inclusive, clipped to g's grid) holding every voxel within radius_mm of centre. With
// an orthonormal direction an offset of r mm is at most r / spacing voxels along each index axis
// (slack for rounding); otherwise, or for a non-finite radius, the whole grid.
void ball_index_box(const Geometry& g, const Vec3& centre, double radius_mm, std::array<int64_t, 3>& lo,
                    std::array<int64_t, 3>& hi) {
    bool orthonormal = std::isfinite(radius_mm);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            double dot = 0;
            for (int c = 0; c < 3; ++c) dot += g.direction[size_t(3 * c + a)] * g.direction[size_t(3 * c + b)];
            if (std::abs(dot - (a == b ? 1.0 : 0.0)) > 1e-6) orthonormal = false;
        }
    const Vec3 ci = g.world_to_index(centre);
    for (int a = 0; a < 3; ++a) {
        lo[a] = 0;
        hi[a] = g.dims[a] - 1;
        if (!orthonormal) continue;
        const double r = radius_mm / g.spacing[a] * (1.0 + 1e-6) + 2;
        lo[a] = std::max<int64_t>(0, int64_t(std::floor(ci[a] - r)));
        hi[a] = std::min<int64_t>(g.dims[a] - 1, int64_t(std::ceil(ci[a] + r)));
    }
}

// The ball radius R of the closing (mm) and close_openings' sub-volume: the endocast's box plus 2R
// (the reach of the balls deciding the closing) on every side; o receives its first voxel.
double closing_radius(const OpeningParams& p, float depth) {
    return p.radius_mm > 0 ? p.radius_mm : p.radius_fraction * depth;
}
// The second look's radius R2 (0: off: disabled, or an explicit R, or not larger than R).
double wide_radius(const OpeningParams& p, float depth) {
    if (p.radius_mm > 0 || !(p.wide_radius_fraction > p.radius_fraction)) return 0;
    return p.wide_radius_fraction * depth;
}
Geometry openings_box(const Geometry& g, const EndocastExtent& e, double R, std::array<int64_t, 3>& o) {
    return grown_box(g, e.lo, e.hi, 2 * R, 2, o);
}

}  // namespace

EndocastExtent endocast_extent(const Volume<uint8_t>& labels, const Volume<float>& distance,
                               const OpeningParams& p) {
    EndocastExtent e = endocast_extent(labels, distance);
    if (e.depth <= 0) return e;
    // The dilation of the bone by R holds the voxels whose squared distance is <= the closed
    // ball's squared radius (dilate_ball's rule): the centres are beyond its square root.
    auto centres = [&](double R) {
        std::array<int64_t, 3> o{};
        const Geometry sg = openings_box(labels.geometry(), e, R, o);
        const double beyond = std::sqrt(ball_squared_radius(R));
        Volume<uint8_t> c(sg);
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < sg.dims[2]; ++z)
            for (int64_t y = 0; y < sg.dims[1]; ++y) {
                const float* d = distance.data() + distance.index(o[0], y + o[1], z + o[2]);
                uint8_t* out = c.data() + c.index(0, y, z);
                for (int64_t x = 0; x < sg.dims[0]; ++x) out[x] = double(d[x]) > beyond ? 1 : 0;
            }
        return c;
    };
    e.ball_centres = centres(closing_radius(p, e.depth));
    if (const double R2 = wide_radius(p, e.depth); R2 > 0) e.wide_ball_centres = centres(R2);
    // The distance on the endocast's box only (a third of the openings box's voxels on the 512
    // phantom): see EndocastExtent::sub_distance.
    e.sub_distance = crop(distance, CropBox{e.lo, {e.hi[0] + 1, e.hi[1] + 1, e.hi[2] + 1}});
    e.sub_first = e.lo;
    return e;
}

EndocastExtent endocast_extent(const Volume<uint8_t>& labels, const Volume<float>& distance) {
    const Geometry& g = labels.geometry();
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    // Depth of the cavity (the first deepest voxel in scan order) and bounding box of E: per slice
    // in parallel, merged in slice order.
    struct SliceScan {
        float depth = -1;
        size_t deepest = 0;
        int64_t lo[2] = {0, 0}, hi[2] = {-1, -1};  // x and y range; hi < lo: no E voxel
    };
    std::vector<SliceScan> slices(static_cast<size_t>(nz));
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < nz; ++z) {
        SliceScan s;
        s.lo[0] = nx;
        s.lo[1] = ny;
        for (int64_t y = 0; y < ny; ++y) {
            const size_t row = labels.index(0, y, z);
            const uint8_t* l = labels.data() + row;
            const float* d = distance.data() + row;
            for (int64_t x = 0; x < nx; ++x) {
                if (l[x] != kEndocast) continue;
                if (d[x] > s.depth) {
                    s.depth = d[x];
                    s.deepest = row + size_t(x);
                }
                s.lo[0] = std::min(s.lo[0], x);
                s.hi[0] = std::max(s.hi[0], x);
                s.lo[1] = std::min(s.lo[1], y);
                s.hi[1] = std::max(s.hi[1], y);
            }
        }
        slices[size_t(z)] = s;
    }
    EndocastExtent e;
    float& depth = e.depth;
    size_t& deepest = e.deepest;
    std::array<int64_t, 3>& lo = e.lo;
    std::array<int64_t, 3>& hi = e.hi;
    lo = {nx, ny, nz};
    for (int64_t z = 0; z < nz; ++z) {
        const SliceScan& s = slices[size_t(z)];
        if (s.hi[0] < 0) continue;
        if (s.depth > depth) {
            depth = s.depth;
            deepest = s.deepest;
        }
        lo = {std::min(lo[0], s.lo[0]), std::min(lo[1], s.lo[1]), std::min(lo[2], z)};
        hi = {std::max(hi[0], s.hi[0]), std::max(hi[1], s.hi[1]), std::max(hi[2], z)};
    }
    if (hi[0] < 0) lo = {0, 0, 0};
    return e;
}

OpeningsResult close_openings(Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                              const Volume<float>& distance, const OpeningParams& p) {
    return close_openings(labels, bone, endocast_extent(labels, distance, p), p);
}

namespace {

// The openings stage's sub-volume (the endocast's box plus 2R, the reach of the balls deciding
// the closing) within the labels' grid.
struct SubBox {
    const Geometry& g;  // the labels' grid
    Geometry sg;        // the sub-volume's
    std::array<int64_t, 3> o{};  // its first voxel in g
    int64_t snx = 0, sny = 0, snz = 0;
    const Volume<uint8_t>& labels;
    // Full-volume index of the sub-volume's voxel (0, y, z).
    size_t full_row(int64_t y, int64_t z) const { return labels.index(o[0], y + o[1], z + o[2]); }
};

// Per far part (a component of the endocast farther than tau from the core): does it reach the
// outside or beyond the canal reach, does it meet the outside with a voxel at least deep_mm from
// bone (deep_mm > 0), its deepest distance to bone, its squared reach from the core, its box
// (sub-volume indices, inclusive) and the world sum of its voxels.
struct FarParts {
    Components rc;  // labelled on the far voxels' box (rc_lo, rc_dims: sub-volume indices)
    std::array<int64_t, 3> rc_lo{0, 0, 0};
    Dims rc_dims{0, 0, 0};
    // The far part (1..K) of the sub-volume's voxel (x, y, z); 0 where none.
    uint32_t label(int64_t x, int64_t y, int64_t z) const {
        x -= rc_lo[0], y -= rc_lo[1], z -= rc_lo[2];
        if (x < 0 || y < 0 || z < 0 || x >= rc_dims[0] || y >= rc_dims[1] || z >= rc_dims[2]) return 0;
        return rc.labels[size_t(x + rc_dims[0] * (y + rc_dims[1] * z))];
    }
    std::vector<uint8_t> opening, canal, deep;
    std::vector<float> max_depth, reach2;
    std::vector<float> mouth_depth;  // deepest distance to bone of its voxels within a voxel of tau from the core
    std::vector<std::array<int64_t, 6>> box;
    std::vector<Vec3> member_sum;
    size_t e_total = 0;  // endocast voxels in the sub-volume
    bool have_depth = false;  // max_depth is known (the extent carries the distance on the sub-volume)
};

// The core: the endocast not filled by the closing of the bone by the ball of radius R, the
// component of the deepest point. Each temporary is released as soon as possible (the peak of this
// stage is here and in the transform of the core). With the ball centres known (the voxels farther
// than R from bone), the voxels outside the closing are those within R of a centre: one transform.
// Otherwise dilate the bone, then erode.
Volume<uint8_t> cavity_core(const SubBox& sb, const Volume<uint8_t>& bone, const EndocastExtent& extent,
                            const Volume<uint8_t>& centres, double R, size_t& core_voxels) {
    const Volume<uint8_t>& labels = sb.labels;
    const int64_t snx = sb.snx, sny = sb.sny, snz = sb.snz;
    const int64_t nx = sb.g.dims[0], ny = sb.g.dims[1];
    const auto& o = sb.o;
    auto full_row = [&](int64_t y, int64_t z) { return sb.full_row(y, z); };
    const Geometry& sg = sb.sg;
    const Dims sd = sg.dims;
    const size_t deepest = extent.deepest;
    Volume<uint8_t> core;
    const bool from_centres = centres.dims() == sd;
    if (from_centres) {
        core = dilate_ball(centres, R);  // outside the closing
    } else {
        Volume<uint8_t> dilated;
        {
            Volume<uint8_t> sub_bone(sg);
#pragma omp parallel for schedule(static)
            for (int64_t z = 0; z < snz; ++z)
                for (int64_t y = 0; y < sny; ++y) {
                    const uint8_t* b = bone.data() + full_row(y, z);
                    uint8_t* s = sub_bone.data() + sub_bone.index(0, y, z);
                    for (int64_t x = 0; x < snx; ++x) s[x] = b[x] ? 1 : 0;
                }
            dilated = dilate_ball(sub_bone, R);
        }
        core = erode_ball(dilated, R);  // the closing (close_ball)
    }
    // Core: E not filled by the closing, the component of the deepest point.
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < snz; ++z)
        for (int64_t y = 0; y < sny; ++y) {
            const uint8_t* l = labels.data() + full_row(y, z);
            uint8_t* c = core.data() + core.index(0, y, z);
            for (int64_t x = 0; x < snx; ++x) c[x] = l[x] == kEndocast && (from_centres ? c[x] != 0 : !c[x]);
        }
    {
        const int64_t dx = int64_t(deepest % size_t(nx)) - o[0];
        const int64_t dy = int64_t((deepest / size_t(nx)) % size_t(ny)) - o[1];
        const int64_t dz = int64_t(deepest / size_t(nx * ny)) - o[2];
        core_voxels = keep_component_at(core, core.index(dx, dy, dz), Connectivity::Face6);
    }
    return core;
}

// The far parts of the endocast (more than tau from the core: the thin layer along a bumpy wall is
// nearer) and what the closure needs of each.
FarParts far_parts(const SubBox& sb, const Volume<uint8_t>& core, const EndocastExtent& extent, double tau,
                   double canal_reach, double deep_mm, double mouth) {
    const Volume<uint8_t>& labels = sb.labels;
    const int64_t snz = sb.snz;
    const auto& o = sb.o;
    const Geometry& g = sb.g;
    const Geometry& sg = sb.sg;
    const Dims sd = sg.dims;
    auto full_row = [&](int64_t y, int64_t z) { return sb.full_row(y, z); };
    FarParts fp;
    size_t e_total = 0;
    // Only "> tau^2" and "> (canal_reach_fraction R)^2" are asked of it: clamped at the larger,
    // the far lines are skipped (values beyond the clamp are +infinity, so both tests stay exact).
    // Both answers are kept as flags in `rest` (kFar: beyond tau, kBeyondCanal: also beyond the
    // canal reach), the far voxels' values per slice in scan order (for each part's reach), and the
    // transform is released before the components are labelled (its float volume and their labels
    // were the stage's peak together).
    // The transform runs on the endocast's box (extent.lo..hi, within the sub-volume): the core
    // (the features) and every endocast voxel (the only voxels asked) lie in it, so it gives them
    // the values of the sub-volume's transform, on 60 % of its voxels on the 512 phantom.
    constexpr uint8_t kFar = 1, kBeyondCanal = 2;
    Volume<uint8_t> rest(sg);
    std::vector<std::vector<float>> far_d2(static_cast<size_t>(snz));
    {
        std::array<int64_t, 3> elo{}, ehi{};
        for (int a = 0; a < 3; ++a) elo[a] = extent.lo[a] - o[a], ehi[a] = extent.hi[a] - o[a] + 1;
        const Volume<float> core_d2 = squared_distance_transform_clamped(
            crop(core, CropBox{elo, ehi}), false, clamp_at_least(std::max(tau * tau, canal_reach * canal_reach)));
#pragma omp parallel for schedule(static) reduction(+ : e_total)
        for (int64_t z = elo[2]; z < ehi[2]; ++z)
            for (int64_t y = elo[1]; y < ehi[1]; ++y) {
                const uint8_t* l = labels.data() + full_row(y, z) + elo[0];
                uint8_t* r = rest.data() + rest.index(elo[0], y, z);
                const float* d2 = core_d2.data() + core_d2.index(0, y - elo[1], z - elo[2]);
                for (int64_t x = 0; x < ehi[0] - elo[0]; ++x) {
                    const bool e = l[x] == kEndocast;
                    e_total += e;
                    const bool far = e && d2[x] > tau * tau;
                    r[x] = far ? uint8_t(kFar | (double(d2[x]) > canal_reach * canal_reach ? kBeyondCanal : 0)) : 0;
                    if (far) far_d2[size_t(z)].push_back(d2[x]);
                }
            }
    }
    // The far parts are labelled on the box of the far voxels only (their uint32 labels over the
    // whole sub-volume were this stage's peak): the same parts, numbered in the same scan order.
    Volume<uint8_t> far_box;
    {
        LabelBox fb = box_of(rest, [](uint8_t v) { return v != 0; });
        if (fb.empty()) fb.lo = {0, 0, 0}, fb.hi = {0, 0, 0};  // no far voxel: a one-voxel box of nothing
        fp.rc_lo = fb.lo;
        far_box = crop(rest, CropBox{fb.lo, {fb.hi[0] + 1, fb.hi[1] + 1, fb.hi[2] + 1}});
        fp.rc_dims = far_box.dims();
        rest = Volume<uint8_t>();
    }
    fp.rc = connected_components(far_box, Connectivity::Face6);
    const Components& rc = fp.rc;
    const std::array<int64_t, 3> flo = fp.rc_lo;
    const Dims fd = fp.rc_dims;
    const size_t K = rc.sizes.size();
    // Per far part: does it reach the outside (a face neighbour "other" or unlabelled; not the
    // volume border: where a scan is cropped through the braincase, a middle fossa the border cuts
    // is closed flat there, not cut as an opening), does it reach beyond the canal reach, and its
    // box: per slice in parallel (all order-free: or, max, min), then its members' world sum in
    // scan order (one thread, so the sum does not depend on the thread count).
    fp.opening.assign(K, 0), fp.canal.assign(K, 0), fp.deep.assign(K, 0);
    fp.max_depth.assign(K, 0.f), fp.reach2.assign(K, 0.f), fp.mouth_depth.assign(K, 0.f);
    auto& opening = fp.opening;
    auto& canal = fp.canal;
    auto& max_depth = fp.max_depth;
    auto& reach2 = fp.reach2;
    const bool have_d = fp.have_depth = !extent.sub_distance.empty();
    const Volume<float>& ed = extent.sub_distance;  // on the endocast's box (far parts are endocast)
    const std::array<int64_t, 3>& ef = extent.sub_first;
    fp.box.assign(K, {sd[0], sd[1], sd[2], -1, -1, -1});
    auto& box = fp.box;
    const int off6[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
#pragma omp parallel
    {
        std::vector<uint8_t> op_t(K, 0), canal_t(K, 0), deep_t(K, 0);
        std::vector<float> maxd_t(K, 0.f), reach_t(K, 0.f), mouth_t(K, 0.f);
        std::vector<std::array<int64_t, 6>> box_t(K, {sd[0], sd[1], sd[2], -1, -1, -1});
#pragma omp for schedule(static)
        for (int64_t z = flo[2]; z < flo[2] + fd[2]; ++z) {
            const float* slice_d2 = far_d2[size_t(z)].data();  // the slice's far voxels, in scan order
            size_t far_at = 0;
            for (int64_t y = flo[1]; y < flo[1] + fd[1]; ++y) {
                // Rows of the far box (its voxel i is the sub-volume's x = flo[0] + i).
                const size_t s = far_box.index(0, y - flo[1], z - flo[2]);
                const uint32_t* lab = rc.labels.data() + s;
                const uint8_t* r = far_box.data() + s;
                // The endocast box's index of this row's voxel x is ed_row + x (used for far voxels
                // only, which lie in the box).
                const int64_t ey = y + o[1] - ef[1], ez = z + o[2] - ef[2];
                const bool row_in_box = have_d && ey >= 0 && ez >= 0 && ey < ed.ny() && ez < ed.nz();
                const int64_t ed_row = row_in_box ? int64_t(ed.index(0, ey, ez)) + o[0] - ef[0] : 0;
                for (int64_t x = flo[0]; x < flo[0] + fd[0]; ++x) {
                    const uint32_t k1 = lab[x - flo[0]];
                    if (!k1) continue;
                    const size_t k = k1 - 1;
                    if (r[x - flo[0]] & kBeyondCanal) canal_t[k] = 1;
                    auto& b = box_t[k];
                    b = {std::min(b[0], x), std::min(b[1], y), std::min(b[2], z),
                         std::max(b[3], x), std::max(b[4], y), std::max(b[5], z)};
                    const float d2 = slice_d2[far_at++];  // labelled: a far voxel
                    if (row_in_box) {
                        maxd_t[k] = std::max(maxd_t[k], ed.data()[ed_row + x]);
                        if (double(d2) <= mouth * mouth) mouth_t[k] = std::max(mouth_t[k], ed.data()[ed_row + x]);
                    }
                    reach_t[k] = std::max(reach_t[k], d2);
                    // A deep voxel (at least deep_mm from bone) touching the outside: a section of a
                    // canal that wide, not a thin gap through the wall.
                    const bool deep = deep_mm > 0 && row_in_box && double(ed.data()[ed_row + x]) >= deep_mm;
                    if (op_t[k] && (deep_t[k] || !deep)) continue;
                    const int64_t gx = x + o[0], gy = y + o[1], gz = z + o[2];
                    for (const auto& q : off6) {
                        const int64_t qx = gx + q[0], qy = gy + q[1], qz = gz + q[2];
                        if (!labels.contains(qx, qy, qz)) continue;
                        const uint8_t l = labels(qx, qy, qz);
                        if (l == kOther || l == kUnlabelled) {
                            op_t[k] = 1;
                            deep_t[k] |= uint8_t(deep);
                        }
                    }
                }
            }
        }
#pragma omp critical(openings_merge)
        for (size_t k = 0; k < K; ++k) {
            opening[k] |= op_t[k];
            canal[k] |= canal_t[k];
            fp.deep[k] |= deep_t[k];
            max_depth[k] = std::max(max_depth[k], maxd_t[k]);
            fp.mouth_depth[k] = std::max(fp.mouth_depth[k], mouth_t[k]);
            reach2[k] = std::max(reach2[k], reach_t[k]);
            auto& b = box[k];
            const auto& t = box_t[k];
            b = {std::min(b[0], t[0]), std::min(b[1], t[1]), std::min(b[2], t[2]),
                 std::max(b[3], t[3]), std::max(b[4], t[4]), std::max(b[5], t[5])};
        }
    }
    far_box = Volume<uint8_t>();
    std::vector<std::vector<float>>().swap(far_d2);
    fp.member_sum.assign(K, Vec3{0, 0, 0});
    auto& member_sum = fp.member_sum;
    for (int64_t z = flo[2]; z < flo[2] + fd[2]; ++z)
        for (int64_t y = flo[1]; y < flo[1] + fd[1]; ++y) {
            const uint32_t* lab = rc.labels.data() + size_t(fd[0]) * size_t((y - flo[1]) + fd[1] * (z - flo[2]));
            for (int64_t x = flo[0]; x < flo[0] + fd[0]; ++x) {
                const uint32_t k1 = lab[x - flo[0]];
                if (!k1) continue;
                const Vec3 w = g.index_to_world(double(x + o[0]), double(y + o[1]), double(z + o[2]));
                for (int a = 0; a < 3; ++a) member_sum[k1 - 1][a] += w[a];
            }
        }
    fp.e_total = e_total;
    return fp;
}

// Which far parts touching the outside are openings: a canal (reaching deeper than a corner can)
// always; otherwise only a tube. In the second look (wide_of > 0: the first look's R) only canals:
// those reaching beyond the canal reach, and tubes touching the outside at least as wide as the
// first look's balls: through a section that wide (a voxel touching the outside wide_of or more
// from bone), or with their deepest voxel that wide and longer than wide (their reach from the
// core at least twice that depth; a stubby pocket is not a canal).
void classify_openings(FarParts& fp, const Geometry& g, const OpeningParams& p, double wide_of) {
    const size_t K = fp.rc.sizes.size();
    auto& opening = fp.opening;
    auto& canal = fp.canal;
    const auto& max_depth = fp.max_depth;
    const auto& reach2 = fp.reach2;
    const Components& rc = fp.rc;
    if (wide_of > 0)
        for (size_t k = 0; k < K; ++k)
            opening[k] = fp.deep[k] || (opening[k] && fp.have_depth && double(max_depth[k]) >= wide_of &&
                                        double(reach2[k]) >= 4.0 * double(max_depth[k]) * double(max_depth[k]));
    // A canal does not widen beyond its mouth: a far part deeper than where it meets the core (a
    // chamber behind a narrower mouth: a rodent's olfactory bulbs behind their junction with the
    // cerebrum) is a pocket of the cavity, not an opening, in the second look.
    if (wide_of > 0 && fp.have_depth)
        for (size_t k = 0; k < K; ++k)
            if (double(max_depth[k]) > kChamberWidening * double(fp.mouth_depth[k])) {
                opening[k] = 0;
                canal[k] = 0;
            }
    // A far part reaching deeper than a corner can, sealed by tissue above the isovalue (a spinal
    // canal closed by ligaments at a low isovalue), is a canal too.
    if (p.canal_reach_fraction > 0)
        for (size_t k = 0; k < K; ++k)
            if (canal[k]) opening[k] = 1;
    // A far part touching the outside is an opening only if it is a tube: a canal or a hole's
    // channel, at most as wide as its deepest voxel and as long as its reach from the core. A far
    // part holding much more (a sheet or a pocket of the skull base: a middle cranial fossa below
    // the core's balls, opening to the outside through its foramina) stays whole: the watershed
    // already ends it at its holes. Canals beyond the reach clamp stay openings.
    if (fp.have_depth && p.max_tubeness > 0)
        for (size_t k = 0; k < K; ++k) {
            if (!opening[k] || !std::isfinite(reach2[k])) continue;
            const double tube = kPi * double(max_depth[k]) * double(max_depth[k]) * std::sqrt(double(reach2[k]));
            if (!(double(rc.sizes[k]) * g.voxel_volume_mm3() <= p.max_tubeness * tube)) opening[k] = 0;
        }
}

// Core voxels on the inner skull surface (26-adjacent to bone): candidates for rims, per slice in
// parallel and concatenated in slice order (scan order of the sub-volume).
std::vector<size_t> wall_voxels(const SubBox& sb, const Volume<uint8_t>& core) {
    const Volume<uint8_t>& labels = sb.labels;
    const int64_t snx = sb.snx, sny = sb.sny, snz = sb.snz;
    const int64_t nx = sb.g.dims[0], ny = sb.g.dims[1], nz = sb.g.dims[2];
    const auto& o = sb.o;
    std::vector<size_t> wall;
    {
        std::vector<std::vector<size_t>> wall_z(static_cast<size_t>(snz));
        // Per row of the core: the bone among the 3 x 3 rows around it, or-ed into one row (near[i]:
        // bone at x = o[0] - 1 + i in one of them), then a core voxel is on the wall when near
        // holds bone at x - 1, x or x + 1 (the 26-neighbourhood, clipped at the volume's border).
#pragma omp parallel
        {
            std::vector<uint8_t> near(size_t(snx + 2));
#pragma omp for schedule(dynamic, 4)
            for (int64_t z = 0; z < snz; ++z)
                for (int64_t y = 0; y < sny; ++y) {
                    const uint8_t* c = core.data() + core.index(0, y, z);
                    if (std::all_of(c, c + snx, [](uint8_t v) { return v == 0; })) continue;
                    const int64_t gy = y + o[1], gz = z + o[2];
                    std::fill(near.begin(), near.end(), uint8_t(0));
                    const int64_t i0 = std::max<int64_t>(0, 1 - o[0]), i1 = std::min<int64_t>(snx + 2, nx - o[0] + 1);
                    for (int cz = -1; cz <= 1; ++cz)
                        for (int b = -1; b <= 1; ++b) {
                            const int64_t qy = gy + b, qz = gz + cz;
                            if (qy < 0 || qz < 0 || qy >= ny || qz >= nz) continue;
                            const uint8_t* row = labels.data() + labels.index(0, qy, qz);
                            for (int64_t i = i0; i < i1; ++i) near[size_t(i)] |= uint8_t(row[o[0] - 1 + i] == kBone);
                        }
                    for (int64_t x = 0; x < snx; ++x)
                        if (c[x] && (near[size_t(x)] | near[size_t(x) + 1] | near[size_t(x) + 2]))
                            wall_z[size_t(z)].push_back(core.index(x, y, z));
                }
        }
        size_t n = 0;
        for (const auto& w : wall_z) n += w.size();
        wall.reserve(n);
        for (auto& w : wall_z) {
            wall.insert(wall.end(), w.begin(), w.end());
            std::vector<size_t>().swap(w);
        }
    }
    return wall;
}

// Rim of each opening: the wall voxels within reach of it (world mm). The distance to opening k is
// taken on k's box grown by more than the reach (every wall voxel within reach lies in it), clamped
// at reach^2 (only "<= reach^2" is asked).
std::vector<std::vector<Vec3>> opening_rims(const SubBox& sb, const FarParts& fp, const std::vector<size_t>& wall,
                                            double rim_reach, const OpeningParams& p) {
    const Geometry& g = sb.g;
    const Geometry& sg = sb.sg;
    const Dims sd = sg.dims;
    const int64_t snx = sb.snx, sny = sb.sny;
    const auto& o = sb.o;
    const size_t K = fp.rc.sizes.size();
    const auto& opening = fp.opening;
    const auto& box = fp.box;
    const Components& rc = fp.rc;
    std::vector<std::vector<Vec3>> rims(K);
    for (size_t k = 0; k < K; ++k) {
        if (!opening[k] || rc.sizes[k] < p.min_opening_voxels) continue;
        std::array<int64_t, 3> ko{};
        const Geometry kg = grown_box(sg, {box[k][0], box[k][1], box[k][2]}, {box[k][3], box[k][4], box[k][5]},
                                      rim_reach, 1, ko);
        const Dims kd = kg.dims;
        Volume<uint8_t> ok(kg);
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < kd[2]; ++z)
            for (int64_t y = 0; y < kd[1]; ++y)
                for (int64_t x = 0; x < kd[0]; ++x)
                    ok(x, y, z) = fp.label(x + ko[0], y + ko[1], z + ko[2]) == k + 1;
        const Volume<float> od2 = squared_distance_transform_clamped(ok, false, clamp_at_least(rim_reach * rim_reach));
        // `wall` is in scan order: only its slices of the box can lie in it.
        const size_t plane = size_t(snx) * size_t(sny);
        const auto first = std::lower_bound(wall.begin(), wall.end(), size_t(ko[2]) * plane);
        const auto last = std::lower_bound(first, wall.end(), size_t(ko[2] + kd[2]) * plane);
        for (auto it = first; it != last; ++it) {
            const size_t i = *it;
            const int64_t x = int64_t(i % size_t(sd[0])), y = int64_t((i / size_t(sd[0])) % size_t(sd[1])),
                          z = int64_t(i / size_t(sd[0] * sd[1]));
            const int64_t kx = x - ko[0], ky = y - ko[1], kz = z - ko[2];
            if (kx < 0 || ky < 0 || kz < 0 || kx >= kd[0] || ky >= kd[1] || kz >= kd[2]) continue;
            if (od2(kx, ky, kz) <= rim_reach * rim_reach)
                rims[k].push_back(g.index_to_world(double(x + o[0]), double(y + o[1]), double(z + o[2])));
        }
    }

    return rims;
}

// Opening k closed: a plane fitted to its rim (normal toward the opening), and the opening beyond
// the plane (or all of it without a plane) and any other endocast voxel beyond the plane within
// the rim's cylinder (the core's dip into the hole and the band between core and opening)
// relabelled outside. Relabelling visits only a box of the sub-volume that holds every voxel it
// may change: opening k's box, and with a plane the box of the ball around the rim's centre
// holding the cut's cylinder (ball_index_box).
Opening cut_opening(const SubBox& sb, Volume<uint8_t>& labels, const FarParts& fp, size_t k, const std::vector<Vec3>& rim,
                    double R, double step, const OpeningParams& p) {
    const Geometry& g = sb.g;
    const Dims sd = sb.sg.dims;
    const auto& o = sb.o;
    const Components& rc = fp.rc;
    const auto& member_sum = fp.member_sum;
    auto full_row = [&](int64_t y, int64_t z) { return sb.full_row(y, z); };
    std::array<int64_t, 6> rb = fp.box[k];  // sub-volume indices, inclusive
    Opening op;
    Eigen::Vector3d c(0, 0, 0), n(0, 0, 0);
    if (rim.size() >= p.min_rim_voxels) {
        for (const auto& w : rim) c += Eigen::Vector3d(w[0], w[1], w[2]);
        c /= double(rim.size());
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        for (const auto& w : rim) {
            const Eigen::Vector3d d = Eigen::Vector3d(w[0], w[1], w[2]) - c;
            cov += d * d.transpose();
        }
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
        n = es.eigenvectors().col(0);  // smallest eigenvalue
        const Eigen::Vector3d mean = Eigen::Vector3d(member_sum[k][0], member_sum[k][1],
                                                     member_sum[k][2]) / double(rc.sizes[k]);
        if ((mean - c).dot(n) < 0) n = -n;
        // A rim that is not a ring around the opening (too flat a cloud along the normal
        // direction is fine; a degenerate line is not): require two comparable extents.
        op.plane_fitted = es.eigenvalues()(1) > 1e-6 && es.eigenvalues()(2) < 1e6 * es.eigenvalues()(1);
        for (const auto& w : rim) {
            const Eigen::Vector3d d = Eigen::Vector3d(w[0], w[1], w[2]) - c;
            op.radius_mm = std::max(op.radius_mm, (d - d.dot(n) * n).norm());
        }
    }
    op.centre_world = {c[0], c[1], c[2]};
    op.normal = {n[0], n[1], n[2]};
    const double reach = op.radius_mm + step;
    if (op.plane_fitted) {
        // along in (0, R] and radial <= reach: within sqrt(R^2 + reach^2) of c.
        std::array<int64_t, 3> blo{}, bhi{};
        ball_index_box(g, op.centre_world, std::sqrt(R * R + reach * reach), blo, bhi);
        for (int a = 0; a < 3; ++a) {
            const int64_t l = std::max<int64_t>(0, blo[a] - o[a]);
            const int64_t h = std::min<int64_t>(sd[a] - 1, bhi[a] - o[a]);
            if (l <= h) {
                rb[a] = std::min(rb[a], l);
                rb[a + 3] = std::max(rb[a + 3], h);
            }
        }
    }
    // Relabel: the opening beyond the plane (or all of it without a plane), and any other
    // endocast voxel beyond the plane within the rim's cylinder (the core's dip into the hole
    // and the band between core and opening).
    size_t removed = 0;
#pragma omp parallel for schedule(static) reduction(+ : removed)
    for (int64_t z = rb[2]; z <= rb[5]; ++z)
        for (int64_t y = rb[1]; y <= rb[4]; ++y) {
            uint8_t* row = labels.data() + full_row(y, z);
            for (int64_t x = rb[0]; x <= rb[3]; ++x) {
                uint8_t& l = row[x];
                if (l != kEndocast) continue;
                const bool in_opening = fp.label(x, y, z) == k + 1;
                bool beyond = in_opening;
                if (op.plane_fitted) {
                    const auto [along, radial] = along_and_radial(g, c, n, x + o[0], y + o[1], z + o[2]);
                    beyond = along > 0 && (in_opening || (radial <= reach && along <= R));
                }
                if (beyond) {
                    l = kOther;
                    ++removed;
                }
            }
        }
    op.voxels_removed = removed;
    return op;
}

}  // namespace

namespace {

// One look: the core by balls of radius R (their centres given), its far parts, those that are
// openings cut at their rims (appended to res.openings). The second look (wide_of > 0, the first
// look's R) cuts only canals. Returns the core's voxels and the far parts' (corner) voxels.
std::pair<size_t, size_t> look(Volume<uint8_t>& labels, const Volume<uint8_t>& bone, const EndocastExtent& extent,
                               const Volume<uint8_t>& centres, double R, const OpeningParams& p, double wide_of,
                               OpeningsResult& res) {
    const Geometry& g = labels.geometry();
    SubBox sb{g, Geometry{}, {}, 0, 0, 0, labels};
    sb.sg = openings_box(g, extent, R, sb.o);
    sb.snx = sb.sg.dims[0], sb.sny = sb.sg.dims[1], sb.snz = sb.sg.dims[2];
    size_t core_voxels = 0;
    Volume<uint8_t> core = cavity_core(sb, bone, extent, centres, R, core_voxels);
    const double step = g.largest_spacing();
    const double tau = p.far_voxels * g.smallest_spacing();
    const double canal_reach = p.canal_reach_fraction > 0 ? p.canal_reach_fraction * R : 0.0;
    FarParts fp = far_parts(sb, core, extent, tau, canal_reach, wide_of, tau + g.largest_spacing());
    classify_openings(fp, g, p, wide_of);
    const size_t corner_voxels = fp.e_total - core_voxels;
    const std::vector<size_t> wall = wall_voxels(sb, core);
    core = Volume<uint8_t>();
    const std::vector<std::vector<Vec3>> rims = opening_rims(sb, fp, wall, tau + 2 * step, p);
    const size_t K = fp.rc.sizes.size();
    for (size_t k = 0; k < K; ++k) {
        if (!fp.opening[k]) continue;
        if (fp.rc.sizes[k] < p.min_opening_voxels) {  // a speck touching the outside: drop it
            const std::array<int64_t, 6>& rb = fp.box[k];
            for (int64_t z = rb[2]; z <= rb[5]; ++z)
                for (int64_t y = rb[1]; y <= rb[4]; ++y)
                    for (int64_t x = rb[0]; x <= rb[3]; ++x)
                        if (fp.label(x, y, z) == k + 1)
                            labels[sb.full_row(y, z) + size_t(x)] = kOther;
            res.small_openings_voxels += fp.rc.sizes[k];
            continue;
        }
        res.openings.push_back(cut_opening(sb, labels, fp, k, rims[k], R, step, p));
        res.openings.back().wide = wide_of > 0;
    }
    return {core_voxels, corner_voxels};
}

}  // namespace

OpeningsResult close_openings(Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                              const EndocastExtent& extent, const OpeningParams& p) {
    OpeningsResult res;
    const float depth = extent.depth;
    if (depth <= 0) return res;
    const double R = closing_radius(p, depth);
    res.radius_mm = R;
    std::tie(res.core_voxels, res.corner_voxels) = look(labels, bone, extent, extent.ball_centres, R, p, 0.0, res);
    const double R2 = wide_radius(p, depth);
    if (R2 > 0 && !extent.wide_ball_centres.empty()) {
        res.wide_radius_mm = R2;
        look(labels, bone, extent, extent.wide_ball_centres, R2, p, R, res);
    }
    return res;
}

std::vector<size_t> cut_collar(Volume<uint8_t>& labels, const Opening& op, const OpeningParams& p) {
    std::vector<size_t> changed;
    if (!op.plane_fitted || !(p.collar_width_voxels > 0)) return changed;
    const Geometry& g = labels.geometry();
    const double step = g.largest_spacing();
    const double width = p.collar_width_voxels * step;
    const double reach = op.radius_mm + step;  // the cut's cylinder (close_openings)
    const Eigen::Vector3d c(op.centre_world[0], op.centre_world[1], op.centre_world[2]);
    const Eigen::Vector3d n(op.normal[0], op.normal[1], op.normal[2]);
    auto place = [&](int64_t x, int64_t y, int64_t z) { return along_and_radial(g, c, n, x, y, z); };
    // The seeds (along <= width, radial <= reach) lie within reach + width of c.
    std::array<int64_t, 3> lo{}, hi{};
    ball_index_box(g, op.centre_world, reach + width, lo, hi);
    std::vector<size_t> stack;
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y)
            for (int64_t x = lo[0]; x <= hi[0]; ++x) {
                if (labels(x, y, z) != kOther) continue;
                const auto [along, radial] = place(x, y, z);
                if (along > 0 && along <= width && radial <= reach) stack.push_back(labels.index(x, y, z));
            }
    const int64_t nx = g.dims[0], ny = g.dims[1];
    const int off6[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    while (!stack.empty()) {
        const size_t i = stack.back();
        stack.pop_back();
        const int64_t x = int64_t(i % size_t(nx)), y = int64_t((i / size_t(nx)) % size_t(ny)),
                      z = int64_t(i / size_t(nx * ny));
        for (const auto& q : off6) {
            const int64_t qx = x + q[0], qy = y + q[1], qz = z + q[2];
            if (!labels.contains(qx, qy, qz)) continue;
            uint8_t& l = labels(qx, qy, qz);
            if (l != kEndocast) continue;
            const auto [along, radial] = place(qx, qy, qz);
            if (!(along > 0 && along <= width && radial <= reach + width)) continue;
            l = kOther;
            changed.push_back(labels.index(qx, qy, qz));
            stack.push_back(changed.back());
        }
    }
    return changed;
}

}  // namespace endocast
