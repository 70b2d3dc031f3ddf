// Creases of the cavity closed by the void fill, given back to the endocast (creases.h).
#include "endocast/stages/creases.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "endocast/stages/components.h"
#include "endocast/stages/distance.h"
#include "endocast/stages/morphology.h"
#include "endocast/stages/resample.h"
#include "method/label_box.h"
#include "method/plug_queue.h"

namespace endocast {
namespace {

// A plug whose bounding box holds at least this many voxels is split on its own (restore_pass).
constexpr double kLargePlugVoxels = 1 << 16;

struct PocketRule {
    double mouth_fraction = 0, ball_fraction = 0;
};

struct Box {
    std::array<int64_t, 3> lo{0, 0, 0}, dims{0, 0, 0};
    bool empty() const { return dims[0] <= 0; }
    bool endocast_on_border = false;  ///< an endocast voxel lies on a face of the volume
};

// Bounding box of the endocast voxels, grown by `margin` voxels per axis and clipped to the volume.
Box endocast_box(const Volume<uint8_t>& labels, const std::array<int64_t, 3>& margin) {
    const Dims& d = labels.dims();
    const LabelBox e = label_box(labels, kEndocast);
    Box b;
    if (e.empty()) return b;
    for (size_t a = 0; a < 3; ++a) {
        b.lo[a] = std::max<int64_t>(0, e.lo[a] - margin[a]);
        b.dims[a] = std::min<int64_t>(d[a] - 1, e.hi[a] + margin[a]) - b.lo[a] + 1;
        b.endocast_on_border |= e.lo[a] == 0 || e.hi[a] == d[a] - 1;
    }
    return b;
}

// The bone dilated by a ball of `radius_mm` on the box b: given (`dilation`, on the labels' grid),
// or computed on the box grown by the ball's reach (the same voxels: the bone beyond the box is
// dilated into it too).
Volume<uint8_t> box_dilation(const Volume<uint8_t>& bone, const Box& b, double radius_mm, const PackedMask* dilation) {
    const Geometry& lg = bone.geometry();
    Geometry g = lg;
    g.dims = {b.dims[0], b.dims[1], b.dims[2]};
    Volume<uint8_t> out(g, 0);
    if (dilation) {
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < b.dims[2]; ++z)
            for (int64_t y = 0; y < b.dims[1]; ++y) {
                const size_t row = bone.index(b.lo[0], y + b.lo[1], z + b.lo[2]);
                uint8_t* o = out.data() + out.index(0, y, z);
                for (int64_t x = 0; x < b.dims[0]; ++x) o[x] = dilation->test(row + size_t(x));
            }
        return out;
    }
    CropBox grown;
    for (size_t a = 0; a < 3; ++a) {
        const int64_t m = int64_t(std::ceil(radius_mm / lg.spacing[a])) + 1;
        grown.lo[a] = std::max<int64_t>(0, b.lo[a] - m);
        grown.hi[a] = std::min<int64_t>(lg.dims[a], b.lo[a] + b.dims[a] + m);
    }
    const Volume<uint8_t> dil = dilate_ball(crop(bone, grown), radius_mm);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < b.dims[2]; ++z)
        for (int64_t y = 0; y < b.dims[1]; ++y)
            for (int64_t x = 0; x < b.dims[0]; ++x)
                out(x, y, z) = dil(x + b.lo[0] - grown.lo[0], y + b.lo[1] - grown.lo[1], z + b.lo[2] - grown.lo[2]);
    return out;
}

// The void fill's voxels in the box that a ball of `radius_mm` does not close in the bone too:
// the closing is the bone's dilation (box_dilation) eroded on the box.
Volume<uint8_t> crease_candidates(const Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                                  const Volume<uint8_t>& filled, const Box& b, double radius_mm,
                                  const PackedMask* dilation) {
    Volume<uint8_t> sub = box_dilation(bone, b, radius_mm, dilation);
    // Where the volume's border cuts the cavity (a scan cropped through the base) it is a wall
    // (across_face): the ball closes the gaps between it and the bone, as it would at the bone
    // going on beyond it (the superior orbital fissure's slit where the border cuts it). As
    // close_ball with walled faces: the wall, bone beyond the face as deep as the ball, dilates
    // into the box the voxels within the ball's radius of it; the erosion sees no empty voxel
    // beyond it (nor beyond the box's other faces).
    if (b.endocast_on_border) {
        const Geometry& g = labels.geometry();
        const float r2 = static_cast<float>(ball_squared_radius(radius_mm));
        for (size_t a = 0; a < 3; ++a) {
            const bool lo = b.lo[a] == 0, hi = b.lo[a] + b.dims[a] == labels.dims()[a];
            if (!lo && !hi) continue;
            const double w = g.spacing[a];
            // Voxel k of the axis (0-based in the box) is within the ball of the wall below it, at
            // distance k + 1 voxels (the dilation's own squared distance, in float): the first
            // `reach` layers along the axis.
            int64_t reach = 0;
            while (reach < b.dims[a] && static_cast<float>(w * w * double(reach + 1) * double(reach + 1)) <= r2) ++reach;
            for (int64_t z = 0; z < b.dims[2]; ++z)
                for (int64_t y = 0; y < b.dims[1]; ++y)
                    for (int64_t x = 0; x < b.dims[0]; ++x) {
                        const int64_t c = a == 0 ? x : a == 1 ? y : z;
                        if ((lo && c < reach) || (hi && b.dims[a] - 1 - c < reach)) sub(x, y, z) = 1;
                    }
        }
    }
    const Volume<uint8_t> closed = erode_ball(sub, radius_mm);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < b.dims[2]; ++z)
        for (int64_t y = 0; y < b.dims[1]; ++y)
            for (int64_t x = 0; x < b.dims[0]; ++x) {
                const size_t i = labels.index(x + b.lo[0], y + b.lo[1], z + b.lo[2]);
                sub(x, y, z) = filled[i] && !bone[i] && !closed(x, y, z) && labels[i] == kBone;
            }
    return sub;
}

// What lies across a face of a voxel of a piece, the voxel beyond it at (x, y, z) local to the box
// b (maybe outside it): the endocast, other empty space or the way out (the box's edge, beyond
// which the piece goes on; the volume's border unless it cuts the cavity itself, as in a scan
// cropped through the base, where it is a wall: it cuts pockets there too, the sella, and the mesh
// is closed flat at the border), or nothing (bone, the void fill).
enum class Across : uint8_t { Nothing = 0, Endocast = 1, Outside = 2 };
Across across_face(const Volume<uint8_t>& labels, const Box& b, int64_t x, int64_t y, int64_t z) {
    const Dims& d = labels.dims();
    const int64_t gx = x + b.lo[0], gy = y + b.lo[1], gz = z + b.lo[2];
    if (gx < 0 || gy < 0 || gz < 0 || gx >= d[0] || gy >= d[1] || gz >= d[2])
        return b.endocast_on_border ? Across::Nothing : Across::Outside;
    if (x < 0 || y < 0 || z < 0 || x >= b.dims[0] || y >= b.dims[1] || z >= b.dims[2]) return Across::Outside;
    const uint8_t l = labels(gx, gy, gz);
    return l == kEndocast ? Across::Endocast : (l == kOther || l == kUnlabelled) ? Across::Outside : Across::Nothing;
}

// A piece's bounding box `bx` (local to the box b) grown by margin_mm and clipped to b: its corner
// (local to b) and the grid of its size.
struct PieceBox {
    std::array<int64_t, 3> lo{}, dims{};
    Geometry grid;
};
PieceBox piece_box(const Geometry& g, const Box& b, const std::array<int64_t, 6>& bx, double margin_mm) {
    PieceBox p;
    for (size_t a = 0; a < 3; ++a) {
        const int64_t m = int64_t(std::ceil(margin_mm / g.spacing[a])) + 1;
        p.lo[a] = std::max<int64_t>(0, bx[a] - m);
        p.dims[a] = std::min<int64_t>(b.dims[a] - 1, bx[a + 3] + m) - p.lo[a] + 1;
    }
    p.grid = g;
    p.grid.dims = {p.dims[0], p.dims[1], p.dims[2]};
    return p;
}

// The radius (mm) of the largest ball inside piece k of `cc` (labels over `cand`, box `b`): the
// largest distance of its voxels to a voxel that is neither the piece nor endocast, computed over
// its bounding box `bx` (local to b) grown by `margin_mm`.
double inscribed_radius(const Volume<uint8_t>& labels, const Components& cc, const Volume<uint8_t>& cand,
                        const Box& b, const std::array<int64_t, 6>& bx, uint32_t k, double margin_mm) {
    const PieceBox pb = piece_box(labels.geometry(), b, bx, margin_mm);
    const std::array<int64_t, 3>& lo = pb.lo;
    const std::array<int64_t, 3>& dims = pb.dims;
    Volume<uint8_t> wall(pb.grid, 0);
    for (int64_t z = 0; z < dims[2]; ++z)
        for (int64_t y = 0; y < dims[1]; ++y)
            for (int64_t x = 0; x < dims[0]; ++x) {
                const int64_t cx = x + lo[0], cy = y + lo[1], cz = z + lo[2];
                wall(x, y, z) = cc.labels[cand.index(cx, cy, cz)] != k &&
                                labels(cx + b.lo[0], cy + b.lo[1], cz + b.lo[2]) != kEndocast;
            }
    const Volume<float> d2 = squared_distance_transform(wall);
    float best = 0;
    for (int64_t z = 0; z < dims[2]; ++z)
        for (int64_t y = 0; y < dims[1]; ++y)
            for (int64_t x = 0; x < dims[0]; ++x)
                if (cc.labels[cand.index(x + lo[0], y + lo[1], z + lo[2])] == k) best = std::max(best, d2(x, y, z));
    return std::sqrt(double(best));
}

constexpr uint8_t kOut = uint8_t(Across::Outside), kIn = uint8_t(Across::Endocast);  // the flood's two sides
static_assert(kOut == plug_queue::kOut && kIn == plug_queue::kIn);
constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();  // no neighbour

// The flood of split_plug from its seeds (`queued`: a member's seed side, 0 none) over the members'
// neighbours: each member's side (0: not reached). A member is queued at most once per side
// (`queued`, a bit per side): a second entry equal to one still queued would pop after it with
// nothing to do. The same members are taken, in the same order, as with every push.
template <class Queue>
std::vector<uint8_t> flood_sides(Queue& q, std::vector<uint8_t>& queued,
                                 const std::vector<std::array<uint32_t, 6>>& nbr) {
    for (uint32_t c = 0; c < uint32_t(queued.size()); ++c)
        if (queued[c]) q.add(c, queued[c]);
    q.heapify();
    std::vector<uint8_t> side(queued.size(), 0);
    while (!q.empty()) {
        const auto [c, s] = q.pop();
        if (side[c]) continue;
        side[c] = s;
        for (const uint32_t j : nbr[c]) {
            if (j == kNone || side[j] || (queued[j] & s)) continue;
            queued[j] |= s;
            q.push(j, s);
        }
    }
    return side;
}

// A piece that touches both the endocast and other empty space: a hole's plug, with the creases
// of the cavity beside the hole's mouth that the ball joined to it (the wedge between the petrous
// ridge and the internal acoustic meatus). It is flooded from both sides down the distance to the
// bone without the void fill, as the watershed floods the cavity: a voxel is taken, highest
// distance first, by the side that reaches it, other space with a lead of `lead_mm` (its entries
// rank that much higher). Along a canal of even width the grid's distances vary by up to half a
// voxel's diagonal, so the lead keeps the canal other space's up to where it widens into the cavity; the endocast
// takes the voxels at least that much wider than the narrowest cross-section between them and the
// outside, and the creases below them, with what the balls inside them cover. Returns the
// endocast's voxels (indices into `cand`) when they are a crease (their volume over their mouth
// toward the endocast at most max_depth_mm: not a chamber behind the hole), else none.
std::vector<size_t> split_plug(const Volume<uint8_t>& labels, const Volume<uint8_t>& bone, const Components& cc,
                               const Volume<uint8_t>& cand, const Box& b, const std::array<int64_t, 6>& bx, uint32_t k,
                               double margin_mm, double lead_mm, double max_depth_mm) {
    const Geometry& g = labels.geometry();
    const PieceBox pb = piece_box(g, b, bx, margin_mm);
    const std::array<int64_t, 3>& lo = pb.lo;
    const std::array<int64_t, 3>& n = pb.dims;
    const Geometry& sg = pb.grid;
    // The bone on the box, and the piece's voxels listed in the box's scan order (`members`; a
    // member's place in the list is its id below), with where each row of the box starts in it.
    Volume<uint8_t> wall(sg, 0);
    std::vector<size_t> members;
    std::vector<uint32_t> row_start(size_t(n[1] * n[2] + 1));
    for (int64_t z = 0; z < n[2]; ++z)
        for (int64_t y = 0; y < n[1]; ++y) {
            row_start[size_t(y + n[1] * z)] = uint32_t(members.size());
            const uint8_t* from = bone.data() + bone.index(lo[0] + b.lo[0], y + lo[1] + b.lo[1], z + lo[2] + b.lo[2]);
            std::memcpy(wall.data() + wall.index(0, y, z), from, size_t(n[0]));
            const uint32_t* label = cc.labels.data() + cand.index(lo[0], y + lo[1], z + lo[2]);
            for (int64_t x = 0; x < n[0]; ++x)
                if (label[x] == k) members.push_back(wall.index(x, y, z));
        }
    // The flood's arrays are per member, not per voxel of the box (a piece is a small part of its
    // box, and the flood would read all over it), its ids 32-bit.
    if (members.size() >= size_t(kNone))
        throw InvalidParameter("restore_creases: a plug of " + std::to_string(members.size()) +
                               " voxels, expected fewer than 4294967295 (the plug flood's 32-bit ids)");
    const size_t m = members.size();
    row_start.back() = uint32_t(m);
    // The members' face neighbours that are members too (kNone: none): along x the next id when
    // the next voxel; along y and z the rows beside merged (both sorted by x).
    std::vector<std::array<uint32_t, 6>> nbr(m);
    for (auto& a : nbr) a.fill(kNone);
    for (size_t c = 0; c + 1 < m; ++c)
        if (members[c + 1] == members[c] + 1 && int64_t(members[c] % size_t(n[0])) + 1 < n[0]) {
            nbr[c][1] = uint32_t(c + 1);
            nbr[c + 1][0] = uint32_t(c);
        }
    auto link = [&](size_t r0, size_t r1, int64_t step, int f) {  // rows r0 and r1 = r0's beside, +step
        uint32_t a = row_start[r0], c = row_start[r1];
        const uint32_t a_end = row_start[r0 + 1], c_end = row_start[r1 + 1];
        while (a < a_end && c < c_end) {
            const size_t want = members[a] + size_t(step);
            if (members[c] < want) {
                ++c;
            } else {
                if (members[c] == want) {
                    nbr[a][size_t(f + 1)] = c;
                    nbr[c][size_t(f)] = a;
                }
                ++a;
            }
        }
    };
    for (int64_t z = 0; z < n[2]; ++z)
        for (int64_t y = 0; y < n[1]; ++y) {
            const size_t r = size_t(y + n[1] * z);
            if (y + 1 < n[1]) link(r, r + 1, n[0], 2);
            if (z + 1 < n[2]) link(r, r + size_t(n[1]), n[0] * n[1], 4);
        }
    const Volume<float> dist_box = distance_transform(wall);
    std::vector<float> dist(m);
    for (size_t c = 0; c < m; ++c) dist[c] = dist_box[members[c]];
    const int64_t off[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    const double face_area[3] = {g.spacing[1] * g.spacing[2], g.spacing[0] * g.spacing[2], g.spacing[0] * g.spacing[1]};
    auto across = [&](int64_t x, int64_t y, int64_t z, int f) {
        return uint8_t(across_face(labels, b, x + lo[0] + off[f][0], y + lo[1] + off[f][1], z + lo[2] + off[f][2]));
    };
    // The seeds: the members beside other space (its side) or else beside the endocast.
    std::vector<uint8_t> queued(m, 0);
    for (int64_t z = 0; z < n[2]; ++z)
        for (int64_t y = 0; y < n[1]; ++y) {
            const size_t r = size_t(y + n[1] * z);
            for (uint32_t c = row_start[r]; c < row_start[r + 1]; ++c) {
                const int64_t x = int64_t(members[c]) - wall.index(0, y, z);
                uint8_t s = 0;
                for (int f = 0; f < 6; ++f) s |= across(x, y, z, f);
                if (s) queued[c] = (s & kOut) ? kOut : kIn;
            }
        }
    std::vector<uint8_t> side;
    if (plug_queue::SideHeaps::fits(dist, lead_mm)) {
        plug_queue::SideHeaps q(dist, lead_mm);
        side = flood_sides(q, queued, nbr);
    } else {
        plug_queue::RankHeap q(dist, lead_mm);
        side = flood_sides(q, queued, nbr);
    }
    const bool any = std::find(side.begin(), side.end(), kIn) != side.end();
    // The endocast's side is what the balls inside its voxels (each as wide as the distance to the
    // bone) cover: the flood leaves other space a shell along the walls of a flare, as narrow as
    // the canal; the balls fill it but do not fit down the canal.
    if (!any) return {};
    std::vector<float> cover(wall.size(), std::numeric_limits<float>::infinity());
    for (size_t c = 0; c < m; ++c)
        if (side[c] == kIn) cover[members[c]] = -dist[c] * dist[c];
    generalized_squared_distance(cover, sg);
    std::vector<size_t> out;
    double volume = 0, mouth = 0;
    for (size_t c = 0; c < m; ++c) {
        const size_t i = members[c];
        if (!side[c] || !(side[c] == kIn || cover[i] < 0)) continue;
        const int64_t x = int64_t(i) % n[0], y = (int64_t(i) / n[0]) % n[1], z = int64_t(i) / (n[0] * n[1]);
        out.push_back(cand.index(x + lo[0], y + lo[1], z + lo[2]));
        volume += g.voxel_volume_mm3();
        for (int f = 0; f < 6; ++f)
            if (across(x, y, z, f) == kIn) mouth += face_area[f / 2];
    }
    if (volume > max_depth_mm * mouth) return {};
    std::sort(out.begin(), out.end());
    return out;
}

// One pass: the pieces of the void fill's voxels that a ball of `keep_closed_mm` does not close
// in the bone too, given back when they are creases (restore_creases). Adds to `r`.
void restore_pass(Volume<uint8_t>& labels, const Volume<uint8_t>& bone, Volume<uint8_t>& filled,
                  const Box& b, double keep_closed_mm, double max_depth_mm, const PocketRule& pocket,
                  double pocket_margin, double plug_lead_mm, const PackedMask* dilation, CreaseResult& r) {
    const Volume<uint8_t> cand = crease_candidates(labels, bone, filled, b, keep_closed_mm, dilation);
    const Components cc = connected_components(cand, Connectivity::Face6);

    // Per piece: touches the endocast (bit 1), other empty space or the box's edge (bit 2); its
    // mouth (the area of its faces toward the endocast, mm^2).
    std::vector<uint8_t> touch(cc.sizes.size(), 0);
    std::vector<double> mouth(cc.sizes.size(), 0.0);
    std::vector<std::array<int64_t, 6>> box(cc.sizes.size(), {b.dims[0], b.dims[1], b.dims[2], -1, -1, -1});
    const Geometry& g = labels.geometry();
    const double face_area[3] = {g.spacing[1] * g.spacing[2], g.spacing[0] * g.spacing[2], g.spacing[0] * g.spacing[1]};
    const int64_t off[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    // The candidates are few (the void fill's voxels near the endocast): a row without one is
    // passed over by a byte search. In scan order, one thread (the mouths' sums in a fixed order).
    auto first_candidate = [&](int64_t y, int64_t z) {
        const uint8_t* row = cand.data() + cand.index(0, y, z);
        return std::find_if(row, row + b.dims[0], [](uint8_t v) { return v != 0; }) - row;
    };
    for (int64_t z = 0; z < b.dims[2]; ++z)
        for (int64_t y = 0; y < b.dims[1]; ++y)
            for (int64_t x = first_candidate(y, z); x < b.dims[0]; ++x) {
                const uint32_t k = cc.labels[cand.index(x, y, z)];
                if (k == 0) continue;
                uint8_t& t = touch[k - 1];
                auto& bx = box[k - 1];
                bx = {std::min(bx[0], x), std::min(bx[1], y), std::min(bx[2], z),
                      std::max(bx[3], x), std::max(bx[4], y), std::max(bx[5], z)};
                for (int f = 0; f < 6; ++f) {
                    const Across a = across_face(labels, b, x + off[f][0], y + off[f][1], z + off[f][2]);
                    t |= uint8_t(a);
                    if (a == Across::Endocast) mouth[k - 1] += face_area[f / 2];
                }
            }
    // A crease is open to the cavity: the mean depth of a piece below its mouth (volume / mouth
    // area) is at most max_depth_mm. A chamber behind a narrow gap in the wall (mastoid air cells,
    // the diploe behind a gap in the inner table) is deeper: it stays closed.
    // A deeper piece is still a pocket when its mouth is wide for its width and one ball holds most
    // of it (the sella turcica under the dorsum: 23 mm deep below a 56 mm^2 mouth, but the mouth
    // is half the pocket's cross-section); a chamber behind a gap has a mouth far narrower than
    // its inside (cthead's air cells: 1 mm^2 into a 936 mm^3 piece 4 mm in radius).
    const double voxel = g.voxel_volume_mm3();
    for (size_t k = 0; k < touch.size(); ++k) {
        if (touch[k] == 1 && double(cc.sizes[k]) * voxel > max_depth_mm * mouth[k]) {
            const double radius = pocket.mouth_fraction > 0
                                      ? inscribed_radius(labels, cc, cand, b, box[k], uint32_t(k + 1), pocket_margin)
                                      : 0.0;
            const double volume = double(cc.sizes[k]) * voxel;
            if (radius > 0 && mouth[k] >= pocket.mouth_fraction * M_PI * radius * radius &&
                4.0 / 3.0 * M_PI * radius * radius * radius >= pocket.ball_fraction * volume) {
                ++r.deep_pockets;
            } else {
                touch[k] = 5;
                ++r.pieces_too_deep;
            }
        }
        if (touch[k] == 1) ++r.pieces;
        if (touch[k] == 3) ++r.pieces_kept_closed;
    }
    // The plugs (touching the endocast and other space): the creases the ball joined to them and
    // the mouth's flare come back (split_plug).
    std::vector<uint32_t> plugs;
    if (plug_lead_mm > 0)
        for (size_t k = 0; k < touch.size(); ++k)
            if (touch[k] == 3) plugs.push_back(uint32_t(k + 1));
    // A large plug is split alone, its distance transforms on all threads; the small ones are split
    // several at once (a transform inside a parallel loop runs on one thread).
    std::vector<std::vector<size_t>> sides(plugs.size());
    auto split_one = [&](size_t q) {
        const uint32_t k = plugs[q];
        sides[q] = split_plug(labels, bone, cc, cand, b, box[k - 1], k, pocket_margin, plug_lead_mm, max_depth_mm);
    };
    std::vector<size_t> small;
    for (size_t q = 0; q < plugs.size(); ++q) {
        const auto& bx = box[plugs[q] - 1];
        const double span = double(bx[3] - bx[0] + 1) * double(bx[4] - bx[1] + 1) * double(bx[5] - bx[2] + 1);
        if (span < kLargePlugVoxels) small.push_back(q);
        else split_one(q);
    }
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t s = 0; s < int64_t(small.size()); ++s) split_one(small[size_t(s)]);
    std::vector<size_t> split;
    for (const std::vector<size_t>& s : sides) {
        if (s.empty()) continue;
        ++r.plugs_split;
        split.insert(split.end(), s.begin(), s.end());
    }
    for (size_t i : split) {
        const int64_t x = int64_t(i) % b.dims[0], y = (int64_t(i) / b.dims[0]) % b.dims[1], z = int64_t(i) / (b.dims[0] * b.dims[1]);
        const size_t j = labels.index(x + b.lo[0], y + b.lo[1], z + b.lo[2]);
        labels[j] = kEndocast;
        filled[j] = 0;
        ++r.voxels;
        ++r.plug_voxels;
    }
    for (int64_t z = 0; z < b.dims[2]; ++z)
        for (int64_t y = 0; y < b.dims[1]; ++y)
            for (int64_t x = first_candidate(y, z); x < b.dims[0]; ++x) {
                const uint32_t k = cc.labels[cand.index(x, y, z)];
                if (k == 0 || touch[k - 1] != 1) continue;
                const size_t i = labels.index(x + b.lo[0], y + b.lo[1], z + b.lo[2]);
                labels[i] = kEndocast;
                filled[i] = 0;
                ++r.voxels;
            }
}

// The void fill's voxels left as thin sheets inside the endocast once the creases are back: a
// voxel it added (filled, not bone) still kBone with kEndocast on both sides along an axis, within
// `reach` voxels each way through such voxels only (a lid remnant over a pocket given back: the
// smaller balls close the corner at the pocket's rim). Repeated until none is left; returns the
// voxels given back. A pass reads the labels and changes them after it: the planes are scanned in
// parallel, the same voxels for any thread count.
size_t give_back_sheets(Volume<uint8_t>& labels, const Volume<uint8_t>& bone, Volume<uint8_t>& filled, const Box& b,
                        int reach) {
    const Dims& d = labels.dims();
    auto fill_voxel = [&](size_t i) { return filled[i] && !bone[i] && labels[i] == kBone; };
    auto in_sheet = [&](int64_t x, int64_t y, int64_t z) {
        const int64_t c[3] = {x, y, z};
        for (int a = 0; a < 3; ++a) {
            int sides = 0;
            for (int dir : {-1, 1}) {
                int64_t q[3] = {c[0], c[1], c[2]};
                for (int k = 1; k <= reach; ++k) {
                    q[a] += dir;
                    if (q[a] < 0 || q[a] >= d[size_t(a)]) break;
                    const size_t j = labels.index(q[0], q[1], q[2]);
                    if (labels[j] == kEndocast) {
                        ++sides;
                        break;
                    }
                    if (!fill_voxel(j)) break;
                }
            }
            if (sides == 2) return true;
        }
        return false;
    };
    size_t total = 0;
    // Round 1 tests every voxel of the box; a later round only the voxels within `reach` along an
    // axis of a voxel the round before gave back (no other voxel's lines changed, so its answer is
    // the same). Each round decides on the labels as they were at its start, then gives back.
    std::vector<size_t> given;  // the last round's, ascending
    {
        std::vector<std::vector<size_t>> back(size_t(b.dims[2]));
#pragma omp parallel for schedule(dynamic, 4)
        for (int64_t z = b.lo[2]; z < b.lo[2] + b.dims[2]; ++z) {
            std::vector<size_t>& plane = back[size_t(z - b.lo[2])];
            for (int64_t y = b.lo[1]; y < b.lo[1] + b.dims[1]; ++y)
                for (int64_t x = b.lo[0]; x < b.lo[0] + b.dims[0]; ++x) {
                    const size_t i = labels.index(x, y, z);
                    if (fill_voxel(i) && in_sheet(x, y, z)) plane.push_back(i);
                }
        }
        for (const std::vector<size_t>& plane : back) given.insert(given.end(), plane.begin(), plane.end());
    }
    const int64_t nx = d[0], ny = d[1];
    while (!given.empty()) {
        for (size_t i : given) {
            labels[i] = kEndocast;
            filled[i] = 0;
        }
        total += given.size();
        std::vector<size_t> next;
        for (size_t i : given) {
            const int64_t c[3] = {int64_t(i % size_t(nx)), int64_t((i / size_t(nx)) % size_t(ny)), int64_t(i / size_t(nx * ny))};
            for (int a = 0; a < 3; ++a)
                for (int64_t k = -reach; k <= reach; ++k) {
                    int64_t q[3] = {c[0], c[1], c[2]};
                    q[a] += k;
                    bool inside = true;
                    for (int e = 0; e < 3; ++e) inside = inside && q[e] >= b.lo[e] && q[e] < b.lo[e] + b.dims[e];
                    if (inside) next.push_back(labels.index(q[0], q[1], q[2]));
                }
        }
        std::sort(next.begin(), next.end());
        next.erase(std::unique(next.begin(), next.end()), next.end());
        std::vector<uint8_t> back(next.size(), 0);
#pragma omp parallel for schedule(dynamic, 256)
        for (int64_t n = 0; n < int64_t(next.size()); ++n) {
            const size_t i = next[size_t(n)];
            back[size_t(n)] = fill_voxel(i) && in_sheet(int64_t(i % size_t(nx)), int64_t((i / size_t(nx)) % size_t(ny)),
                                                         int64_t(i / size_t(nx * ny)));
        }
        given.clear();
        for (size_t n = 0; n < next.size(); ++n)
            if (back[n]) given.push_back(next[n]);
    }
    return total;
}

}  // namespace

CreaseResult restore_creases(Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                             Volume<uint8_t>& filled, double void_radius_mm,
                             const CreaseParams& p) {
    return restore_creases(labels, bone, filled, void_radius_mm, p, {});
}

CreaseResult restore_creases(Volume<uint8_t>& labels, const Volume<uint8_t>& bone, Volume<uint8_t>& filled,
                             double void_radius_mm, const CreaseParams& p,
                             const std::vector<PackedMask>& bone_dilations) {
    if (labels.dims() != bone.dims() || labels.dims() != filled.dims())
        throw InvalidParameter("restore_creases: the label, bone and filled volumes differ in size");
    if (!bone_dilations.empty() && bone_dilations.size() != p.keep_closed_fractions.size())
        throw InvalidParameter("restore_creases: " + std::to_string(bone_dilations.size()) + " bone dilations for " +
                               std::to_string(p.keep_closed_fractions.size()) + " keep-closed fractions");
    for (const PackedMask& m : bone_dilations)
        if (m.geometry().dims != labels.dims())
            throw InvalidParameter("restore_creases: a bone dilation's grid differs from the labels'");
    for (double f : p.keep_closed_fractions)
        if (!std::isfinite(f) || f < 0 || f > 1)
            throw InvalidParameter("crease keep-closed fraction " + std::to_string(f) +
                                   " of the void-fill radius, expected within [0, 1]");
    for (double f : {p.pocket_mouth_fraction, p.pocket_ball_fraction})
        if (!std::isfinite(f) || f < 0)
            throw InvalidParameter("crease pocket fraction " + std::to_string(f) + ", expected a finite value >= 0");
    if (p.sheet_voxels < 0)
        throw InvalidParameter("crease sheet_voxels " + std::to_string(p.sheet_voxels) + ", expected >= 0 (0: off)");
    if (!std::isfinite(p.plug_lead_voxels) || p.plug_lead_voxels < 0)
        throw InvalidParameter("crease plug_lead_voxels " + std::to_string(p.plug_lead_voxels) +
                               ", expected a finite value >= 0 (0: off)");
    CreaseResult r;
    if (!p.enabled || !(void_radius_mm > 0)) return r;
    const Geometry& g = labels.geometry();
    std::array<int64_t, 3> margin{};
    // Twice the void fill's radius beyond the endocast: a piece reaching the box's edge stays closed.
    for (size_t a = 0; a < 3; ++a) margin[a] = int64_t(std::ceil(2.0 * void_radius_mm / g.spacing[a])) + 2;
    const Box b = endocast_box(labels, margin);
    if (b.empty()) return r;
    for (size_t k = 0; k < p.keep_closed_fractions.size(); ++k)
        restore_pass(labels, bone, filled, b, p.keep_closed_fractions[k] * void_radius_mm,
                     p.max_mean_depth_fraction * void_radius_mm, {p.pocket_mouth_fraction, p.pocket_ball_fraction},
                     void_radius_mm, p.plug_lead_voxels * g.largest_spacing(),
                     bone_dilations.empty() ? nullptr : &bone_dilations[k], r);
    if (p.sheet_voxels > 0) r.sheet_voxels = give_back_sheets(labels, bone, filled, b, p.sheet_voxels);
    return r;
}

}  // namespace endocast
