// Closing surfaces that dip into a hole, made flush with its rim (dips.h).
#include "endocast/stages/dips.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>
#include <queue>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "endocast/stages/components.h"
#include "meshpost/fair.h"
#include "meshpost/measure.h"
#include "meshpost/patches.h"
#include "method/label_box.h"

namespace endocast {
namespace {

using meshpost::Face;
using meshpost::Point;
using meshpost::TriangleMesh;

// Fills a patch's holes: from each face next to it, a walk over the faces not in it that ends
// before it has seen as many faces as the patch has is a piece it encloses (it joins the patch,
// and so do the other patches inside it).
struct Enclosure {
    std::vector<int64_t> seen;  // the walk that last reached each face
    int64_t walk = 0;
    explicit Enclosure(size_t faces) : seen(faces, -1) {}

    void fill(std::vector<std::vector<uint32_t>>& patches, size_t id, std::vector<int64_t>& owner,
              const std::vector<std::array<uint32_t, 3>>& nb) {
        std::vector<uint32_t>& faces = patches[id];
        const int64_t first = walk, self = int64_t(id);
        const size_t limit = faces.size(), own = faces.size();
        for (size_t i = 0; i < own; ++i)
            for (uint32_t start : nb[faces[i]]) {
                if (start == meshpost::kNoFace || owner[start] == self || seen[start] >= first) continue;
                std::vector<uint32_t> piece{start};
                seen[start] = walk;
                bool enclosed = true;
                for (size_t j = 0; j < piece.size() && enclosed; ++j)
                    for (uint32_t g : nb[piece[j]]) {
                        if (g == meshpost::kNoFace || owner[g] == self || seen[g] == walk) continue;
                        seen[g] = walk;
                        piece.push_back(g);
                        if (piece.size() >= limit) {
                            enclosed = false;
                            break;
                        }
                    }
                ++walk;
                if (!enclosed) continue;
                for (uint32_t g : piece) {
                    if (owner[g] >= 0) patches[size_t(owner[g])].clear();
                    owner[g] = self;
                    faces.push_back(g);
                }
            }
    }
};

// The edge-connected patches of faces not on bone, each with what it encloses (the pieces of the
// rest that it alone bounds and that are smaller than it: a few faces whose sample 1 mm out hit
// the hole's wall, and what lies inside them), in the order of their first face.
std::vector<std::vector<uint32_t>> off_bone_patches(const TriangleMesh& m, const std::vector<uint8_t>& on_bone,
                                                    const std::vector<std::array<uint32_t, 3>>& nb,
                                                    std::vector<int64_t>& patch_of, Enclosure& e) {
    std::vector<uint8_t> off(m.faces.size(), 0);
    for (size_t f = 0; f < off.size(); ++f) off[f] = !on_bone[f];
    std::vector<std::vector<uint32_t>> patches = meshpost::face_patches(nb, off);
    for (size_t id = 0; id < patches.size(); ++id)
        for (uint32_t f : patches[id]) patch_of[f] = int64_t(id);
    for (size_t id = 0; id < patches.size(); ++id) e.fill(patches, id, patch_of, nb);
    return patches;  // those enclosed by another are empty
}

// A face's centroid and normal (the cross product of its edges and that vector's length; len 0 for
// a degenerate face), for the voxels beyond it.
struct FaceRay {
    Vec3 centre;
    Point cross;
    double len;
    FaceRay(const TriangleMesh& mesh, uint32_t f) {
        const Face& tri = mesh.faces[f];
        cross = meshpost::face_cross(mesh, tri);
        len = std::sqrt(cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]);
        for (size_t k = 0; k < 3; ++k)
            centre[k] = (mesh.vertices[tri[0]][k] + mesh.vertices[tri[1]][k] + mesh.vertices[tri[2]][k]) / 3.0;
    }
    // The index of the voxel nearest to the point t mm out along the unit normal, or -1 for a
    // degenerate face or a point beyond the grid. Rounded as std::lround (half away from zero),
    // inline: in range, v > -0.5 and v < n - 0.5; then the truncation and its exact remainder.
    int64_t voxel_beyond(const Geometry& grid, double t) const {
        if (!(len > 0)) return -1;
        Vec3 w;
        for (size_t k = 0; k < 3; ++k) w[k] = centre[k] + t * cross[k] / len;
        const Vec3 ijk = grid.world_to_index(w);
        int64_t at[3];
        for (size_t a = 0; a < 3; ++a) {
            const double v = ijk[a];
            if (!(v > -0.5 && v < double(grid.dims[a]) - 0.5)) return -1;
            at[a] = int64_t(v);
            at[a] += v - double(at[a]) >= 0.5;
        }
        return at[0] + grid.dims[0] * (at[1] + grid.dims[1] * at[2]);
    }
};

// The patch grown by `rings` rings of faces across its edges (faces in no other patch): the faces
// on bone along a hole's rounded rim, whose sample 1 mm out hit the hole's wall.
void grow_patch(std::vector<uint32_t>& faces, const std::vector<std::array<uint32_t, 3>>& nb,
                std::vector<int64_t>& owner, int64_t id, int rings) {
    size_t begin = 0;
    for (int r = 0; r < rings; ++r) {
        const size_t end = faces.size();
        for (size_t i = begin; i < end; ++i)
            for (uint32_t g : nb[faces[i]])
                if (g != meshpost::kNoFace && owner[g] < 0) {
                    owner[g] = id;
                    faces.push_back(g);
                }
        begin = end;
    }
}

// The patch grown across the hole's wall: ring by ring, the faces (in no other patch) next to the
// last ring that are steep to the patch's mean normal N (|n . N| < max_cosine: a channel's wall, not
// the inner table around its mouth), at most `rings` rings. A dip into an oblique hole runs down
// one side of its wall, whose faces sample bone 1 mm out; its membrane must span the rim above it.
// With max_length_mm > 0 the walk is measured, not counted: every such face within that length of
// the patch along the shortest path over face centroids (rings unused).
void grow_along_wall(std::vector<uint32_t>& faces, const TriangleMesh& mesh, const std::vector<std::array<uint32_t, 3>>& nb,
                     std::vector<int64_t>& owner, int64_t id, int rings, double max_cosine, double climb_tolerance, double footprint,
                     double footprint_mm, double max_length_mm) {
    Point normal{0, 0, 0};
    for (uint32_t f : faces) {
        const Point c = meshpost::face_cross(mesh, mesh.faces[f]);
        for (size_t a = 0; a < 3; ++a) normal[a] += c[a];
    }
    const double nn = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    if (!(nn > 0)) return;
    // How far out along N a face's centroid lies (mm).
    auto height = [&](uint32_t f) {
        double h = 0;
        for (uint32_t v : mesh.faces[f])
            for (size_t a = 0; a < 3; ++a) h += mesh.vertices[v][a] * normal[a];
        return h / (3 * nn);
    };
    // The patch's footprint seen along N: its centre and the largest distance of a face centroid
    // from it across N. A wall face outside it is another hollow's (a crease beside the hole).
    auto centroid = [&](uint32_t f) {
        Point c{0, 0, 0};
        for (uint32_t v : mesh.faces[f])
            for (size_t a = 0; a < 3; ++a) c[a] += mesh.vertices[v][a] / 3;
        return c;
    };
    Point centre{0, 0, 0};
    for (uint32_t f : faces) {
        const Point c = centroid(f);
        for (size_t a = 0; a < 3; ++a) centre[a] += c[a] / double(faces.size());
    }
    auto across = [&](uint32_t f) {
        const Point c = centroid(f);
        Point d{c[0] - centre[0], c[1] - centre[1], c[2] - centre[2]};
        const double h = (d[0] * normal[0] + d[1] * normal[1] + d[2] * normal[2]) / nn;
        for (size_t a = 0; a < 3; ++a) d[a] -= h * normal[a] / nn;
        return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    };
    double reach = 0;
    for (uint32_t f : faces) reach = std::max(reach, across(f));
    reach = reach * footprint + footprint_mm;
    // Within the footprint and steep to N (a wall's face).
    auto steep = [&](uint32_t g) {
        if (across(g) > reach) return false;
        const Point c = meshpost::face_cross(mesh, mesh.faces[g]);
        const double len = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        return len > 0 && std::fabs(c[0] * normal[0] + c[1] * normal[1] + c[2] * normal[2]) < max_cosine * len * nn;
    };
    if (max_length_mm > 0) {
        // Nearest first, by the path over face centroids: a fixed length up the wall, however
        // the marching cubes cut it (slivers along an overhang make rings short).
        using Entry = std::pair<double, uint32_t>;  // (length, face), shortest on top
        std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
        std::unordered_map<uint32_t, double> best;  // the shortest path found to each face reached
        auto shortest = [&](uint32_t f) {
            const auto it = best.find(f);
            return it == best.end() ? std::numeric_limits<double>::infinity() : it->second;
        };
        for (uint32_t f : faces) {
            best[f] = 0;
            heap.emplace(0.0, f);
        }
        while (!heap.empty()) {
            const auto [d, f] = heap.top();
            heap.pop();
            if (d > shortest(f)) continue;
            if (owner[f] < 0) {
                owner[f] = id;
                faces.push_back(f);
            }
            const Point cf = centroid(f);
            for (uint32_t g : nb[f]) {
                if (g == meshpost::kNoFace || owner[g] >= 0 || !steep(g) || height(g) > height(f) + climb_tolerance) continue;
                const Point cg = centroid(g);
                const double dg = d + std::hypot(cg[0] - cf[0], cg[1] - cf[1], cg[2] - cf[2]);
                if (dg > max_length_mm || dg >= shortest(g)) continue;
                best[g] = dg;
                heap.emplace(dg, g);
            }
        }
        return;
    }
    size_t begin = 0;
    for (int r = 0; r < rings; ++r) {
        const size_t end = faces.size();
        for (size_t i = begin; i < end; ++i)
            for (uint32_t g : nb[faces[i]]) {
                if (g == meshpost::kNoFace || owner[g] >= 0 || !steep(g)) continue;
                if (height(g) > height(faces[i]) + climb_tolerance) continue;  // climbs toward the cavity only
                owner[g] = id;
                faces.push_back(g);
            }
        if (faces.size() == end) break;
        begin = end;
    }
}

// orient3d in doubles: > 0 when d lies above the plane of abc.
double orient(const Point& a, const Point& b, const Point& c, const Point& d) {
    const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
    const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
    return (uy * vz - uz * vy) * (d[0] - a[0]) + (uz * vx - ux * vz) * (d[1] - a[1]) + (ux * vy - uy * vx) * (d[2] - a[2]);
}

// Segment pq crosses or touches triangle abc (coplanar: no).
bool segment_meets(const Point& p, const Point& q, const Point& a, const Point& b, const Point& c) {
    const double o1 = orient(a, b, c, p), o2 = orient(a, b, c, q);
    if ((o1 > 0 && o2 > 0) || (o1 < 0 && o2 < 0) || (o1 == 0 && o2 == 0)) return false;
    const double s1 = orient(p, q, a, b), s2 = orient(p, q, b, c), s3 = orient(p, q, c, a);
    return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

// Two faces sharing at most one vertex meet other than at it (edge neighbours: no).
bool faces_cross(const TriangleMesh& m, const Face& f, const Face& g) {
    int shared = 0, i0 = 0, j0 = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (f[i] == g[j]) ++shared, i0 = i, j0 = j;
    if (shared >= 2) return false;
    auto P = [&](const Face& h, int k) -> const Point& { return m.vertices[h[size_t(k % 3)]]; };
    if (shared == 1)
        return segment_meets(P(f, i0 + 1), P(f, i0 + 2), P(g, 0), P(g, 1), P(g, 2)) ||
               segment_meets(P(g, j0 + 1), P(g, j0 + 2), P(f, 0), P(f, 1), P(f, 2));
    for (int k = 0; k < 3; ++k)
        if (segment_meets(P(f, k), P(f, k + 1), P(g, 0), P(g, 1), P(g, 2)) ||
            segment_meets(P(g, k), P(g, k + 1), P(f, 0), P(f, 1), P(f, 2)))
            return true;
    return false;
}

struct Box {
    Point lo, hi;
};
Box face_box(const TriangleMesh& m, const Face& f) {
    Box b{m.vertices[f[0]], m.vertices[f[0]]};
    for (int k = 1; k < 3; ++k)
        for (size_t a = 0; a < 3; ++a) {
            b.lo[a] = std::min(b.lo[a], m.vertices[f[size_t(k)]][a]);
            b.hi[a] = std::max(b.hi[a], m.vertices[f[size_t(k)]][a]);
        }
    return b;
}

// The mesh's faces bucketed by the cell of their box's centre (a uniform grid over the vertices'
// box, about one cell per kFacesPerCell faces, in one array sorted by cell): the faces whose box
// can meet a given box are those whose centre lies within it grown by the largest half-extent of a
// face box. A centre outside the grid is bucketed in the nearest cell, and queries are clamped the
// same way. A face that moves (a flushed patch's) leaves the grid for a short list scanned by
// every query, and the half-extent grows with it.
class FaceIndex {
public:
    static constexpr double kFacesPerCell = 16;
    // The boxes, half-extents and cells on all threads (minima and maxima: the same for any
    // thread count), the faces sorted by cell on one.
    explicit FaceIndex(const TriangleMesh& m) : m_(m), moved_flag_(m.faces.size(), 0) {
        const Point first = m.vertices.empty() ? Point{0, 0, 0} : m.vertices[0];
        double lo0 = first[0], lo1 = first[1], lo2 = first[2], hi0 = first[0], hi1 = first[1], hi2 = first[2];
        const int64_t nv = int64_t(m.vertices.size()), nf = int64_t(m.faces.size());
#pragma omp parallel for schedule(static) reduction(min : lo0, lo1, lo2) reduction(max : hi0, hi1, hi2)
        for (int64_t i = 0; i < nv; ++i) {
            const Point& v = m.vertices[size_t(i)];
            lo0 = std::min(lo0, v[0]), lo1 = std::min(lo1, v[1]), lo2 = std::min(lo2, v[2]);
            hi0 = std::max(hi0, v[0]), hi1 = std::max(hi1, v[1]), hi2 = std::max(hi2, v[2]);
        }
        const Box all{{lo0, lo1, lo2}, {hi0, hi1, hi2}};
        double h0 = 0, h1 = 0, h2 = 0;
#pragma omp parallel for schedule(static) reduction(max : h0, h1, h2)
        for (int64_t f = 0; f < nf; ++f) {
            const Box b = face_box(m, m.faces[size_t(f)]);
            h0 = std::max(h0, 0.5 * (b.hi[0] - b.lo[0]));
            h1 = std::max(h1, 0.5 * (b.hi[1] - b.lo[1]));
            h2 = std::max(h2, 0.5 * (b.hi[2] - b.lo[2]));
        }
        half_ = {h0, h1, h2};
        lo_ = all.lo;
        // Cubic cells, as many as a cell per kFacesPerCell faces (a face at most a cell wide).
        const double volume = std::max(1e-27, (all.hi[0] - all.lo[0]) * (all.hi[1] - all.lo[1]) * (all.hi[2] - all.lo[2]));
        const double side = std::cbrt(volume / std::max(1.0, double(m.faces.size()) / kFacesPerCell));
        for (size_t a = 0; a < 3; ++a) {
            cell_[a] = std::max({side, 2.0 * half_[a], 1e-9});
            n_[a] = std::max<int64_t>(1, std::min<int64_t>(1024, int64_t((all.hi[a] - all.lo[a]) / cell_[a]) + 1));
        }
        std::vector<uint32_t> cell_of(m.faces.size());
#pragma omp parallel for schedule(static)
        for (int64_t f = 0; f < nf; ++f) cell_of[size_t(f)] = cell_at(centre(face_box(m, m.faces[size_t(f)])));
        start_.assign(size_t(n_[0] * n_[1] * n_[2]) + 1, 0);
        for (size_t f = 0; f < m.faces.size(); ++f) ++start_[cell_of[f] + 1];
        for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
        faces_.resize(m.faces.size());
        std::vector<uint32_t> at(start_.begin(), start_.end() - 1);
        for (size_t f = 0; f < m.faces.size(); ++f) faces_[at[cell_of[f]]++] = uint32_t(f);
    }
    // The faces `moved` changed shape: out of the grid, into the moved list; the half-extent grown.
    void update(const std::vector<uint32_t>& moved) {
        for (uint32_t f : moved) {
            grow_half(face_box(m_, m_.faces[f]));
            if (!moved_flag_[f]) moved_flag_[f] = 1, moved_.push_back(f);
        }
    }
    // fn(face) for every face whose box may meet b (and some more); stops when fn returns true.
    template <class Fn>
    bool any_near(const Box& b, Fn fn) const {
        int64_t r[3][2];
        for (size_t a = 0; a < 3; ++a) {
            r[a][0] = index(b.lo[a] - half_[a], a);
            r[a][1] = index(b.hi[a] + half_[a], a);
        }
        for (int64_t z = r[2][0]; z <= r[2][1]; ++z)
            for (int64_t y = r[1][0]; y <= r[1][1]; ++y)
                for (int64_t x = r[0][0]; x <= r[0][1]; ++x) {
                    const size_t c = size_t(x + n_[0] * (y + n_[1] * z));
                    for (uint32_t k = start_[c]; k < start_[c + 1]; ++k)
                        if (!moved_flag_[faces_[k]] && fn(faces_[k])) return true;
                }
        for (uint32_t f : moved_)
            if (fn(f)) return true;
        return false;
    }

private:
    static Point centre(const Box& b) {
        return {0.5 * (b.lo[0] + b.hi[0]), 0.5 * (b.lo[1] + b.hi[1]), 0.5 * (b.lo[2] + b.hi[2])};
    }
    void grow_half(const Box& b) {
        for (size_t a = 0; a < 3; ++a) half_[a] = std::max(half_[a], 0.5 * (b.hi[a] - b.lo[a]));
    }
    int64_t index(double v, size_t a) const {
        const double c = std::floor((v - lo_[a]) / cell_[a]);
        return c < 0 ? 0 : c >= double(n_[a] - 1) ? n_[a] - 1 : int64_t(c);
    }
    uint32_t cell_at(const Point& p) const {
        return uint32_t(index(p[0], 0) + n_[0] * (index(p[1], 1) + n_[1] * index(p[2], 2)));
    }
    const TriangleMesh& m_;
    Point lo_{0, 0, 0}, half_{0, 0, 0};
    double cell_[3] = {1, 1, 1};
    int64_t n_[3] = {1, 1, 1};
    std::vector<uint32_t> start_, faces_;  // the faces of cell c: faces_[start_[c] .. start_[c + 1])
    std::vector<uint8_t> moved_flag_;
    std::vector<uint32_t> moved_;
};

// A face of the patch (moved) crosses another face of the mesh: every face whose box meets the
// patch's box (the patch's own faces, moved, and the others near it by `index`, which holds them
// where they are: only the patch's faces moved) is tested against the patch's faces whose boxes it
// meets.
bool crosses_the_mesh(const TriangleMesh& m, const std::vector<uint32_t>& patch, const FaceIndex& index,
                      std::vector<uint8_t>& in_this_patch) {
    auto box = [&](const Face& f) { return face_box(m, f); };
    auto apart = [](const Box& a, const Box& b) {
        return a.lo[0] > b.hi[0] || b.lo[0] > a.hi[0] || a.lo[1] > b.hi[1] || b.lo[1] > a.hi[1] || a.lo[2] > b.hi[2] ||
               b.lo[2] > a.hi[2];
    };
    std::vector<Box> boxes;
    boxes.reserve(patch.size());
    Box all = box(m.faces[patch[0]]);
    double extent = 0;  // the largest side of a patch face's box
    for (uint32_t f : patch) {
        boxes.push_back(box(m.faces[f]));
        for (size_t a = 0; a < 3; ++a) {
            all.lo[a] = std::min(all.lo[a], boxes.back().lo[a]);
            all.hi[a] = std::max(all.hi[a], boxes.back().hi[a]);
            extent = std::max(extent, boxes.back().hi[a] - boxes.back().lo[a]);
        }
    }
    // The patch's faces in a grid of cells over its box (each face in the cells its box meets; at
    // most 64 cells a side), so that a face of the mesh is tested against the patch faces near it
    // only (was every patch face: quadratic in the patch's size).
    int64_t n[3];
    double cell[3];
    for (size_t a = 0; a < 3; ++a) {
        const double side = all.hi[a] - all.lo[a];
        cell[a] = std::max({extent, side / 64.0, 1e-12});
        n[a] = std::max<int64_t>(1, std::min<int64_t>(64, int64_t(side / cell[a]) + 1));
    }
    auto cell_range = [&](const Box& b, size_t a, int64_t& c0, int64_t& c1) {
        c0 = std::clamp<int64_t>(int64_t(std::floor((b.lo[a] - all.lo[a]) / cell[a])), 0, n[a] - 1);
        c1 = std::clamp<int64_t>(int64_t(std::floor((b.hi[a] - all.lo[a]) / cell[a])), 0, n[a] - 1);
    };
    std::vector<std::vector<uint32_t>> cells(size_t(n[0] * n[1] * n[2]));
    for (size_t k = 0; k < boxes.size(); ++k) {
        int64_t r[3][2];
        for (size_t a = 0; a < 3; ++a) cell_range(boxes[k], a, r[a][0], r[a][1]);
        for (int64_t z = r[2][0]; z <= r[2][1]; ++z)
            for (int64_t y = r[1][0]; y <= r[1][1]; ++y)
                for (int64_t x = r[0][0]; x <= r[0][1]; ++x) cells[size_t(x + n[0] * (y + n[1] * z))].push_back(uint32_t(k));
    }
    auto crosses = [&](uint32_t g) {
        const Box bg = box(m.faces[g]);
        if (apart(bg, all)) return false;
        int64_t r[3][2];
        for (size_t a = 0; a < 3; ++a) cell_range(bg, a, r[a][0], r[a][1]);
        for (int64_t z = r[2][0]; z <= r[2][1]; ++z)
            for (int64_t y = r[1][0]; y <= r[1][1]; ++y)
                for (int64_t x = r[0][0]; x <= r[0][1]; ++x)
                    for (uint32_t k : cells[size_t(x + n[0] * (y + n[1] * z))])
                        if (patch[k] != g && !apart(bg, boxes[k]) && faces_cross(m, m.faces[patch[k]], m.faces[g]))
                            return true;
        return false;
    };
    for (uint32_t f : patch) in_this_patch[f] = 1;
    bool hit = false;
    for (uint32_t f : patch)
        if ((hit = crosses(f))) break;
    if (!hit) hit = index.any_near(all, [&](uint32_t g) { return !in_this_patch[g] && crosses(g); });
    for (uint32_t f : patch) in_this_patch[f] = 0;
    return hit;
}

// Runs `loop`, and flush_dips' `beside` beside it: as the two threads of one OpenMP team (the
// pool's second thread, idle through the sequential loop, takes `beside`: no thread of its own to
// start and to share a core with the pool's thread while that one waits spinning); with one thread,
// one after the other. Parallel regions inside either run on its thread alone (results do not
// depend on the thread count). Both run to their end; then the loop's error is thrown, or beside's.
void side_by_side(const std::function<void()>& loop, const std::function<void()>& beside) {
    std::exception_ptr error[2];
    if (beside && omp_get_max_threads() > 1) {
#pragma omp parallel num_threads(2)
        {
            const int t = omp_get_thread_num(), team = omp_get_num_threads();
            try {
                if (t == 0) loop();
                if (t == team - 1) beside();  // the team may have one thread only
            } catch (...) {
                error[t] = std::current_exception();
            }
        }
    } else {
        loop();
        if (beside) beside();
    }
    for (const std::exception_ptr& e : error)
        if (e) std::rethrow_exception(e);
}

// One patch (a disk: V - E + F = 1) moved onto the membrane spanning its rim when it is a dip:
// it holds volume beyond the membrane (at least min_depth_mm over its area) and no vertex
// moves farther than the void fill's ball can dip. `valence` counts each vertex's faces,
// `in_patch` is zero on entry and on return.
enum class Flush { NotADisk, Kept, Flushed, Crossing };
// `index` holds the mesh's faces (updated here when the patch moves), `in_this_patch` is zero on
// entry and on return (crosses_the_mesh's flags).
Flush flush_patch(TriangleMesh& mesh, const std::vector<uint32_t>& patch, const std::vector<uint32_t>& valence,
                 std::vector<uint32_t>& in_patch, double void_radius_mm, double min_depth_mm, const DipParams& p,
                 DipResult& r, FaceIndex& index, std::vector<uint8_t>& in_this_patch,
                 const meshpost::VertexFaces* thin_plate_ring = nullptr) {
    // A disk (V - E + F = 1); its inner vertices have every face around them in it.
    double area = 0;
    Point normal{0, 0, 0};
    std::vector<uint32_t> verts;
    std::vector<uint64_t> edges;
    for (uint32_t f : patch) {
        const Point c = meshpost::face_cross(mesh, mesh.faces[f]);
        area += 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        for (int a = 0; a < 3; ++a) {
            normal[size_t(a)] += c[size_t(a)];
            const uint64_t u = mesh.faces[f][a], w = mesh.faces[f][(a + 1) % 3];
            verts.push_back(uint32_t(u));
            edges.push_back(std::min(u, w) << 32 | std::max(u, w));
            ++in_patch[u];
        }
    }
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    std::vector<uint32_t> inner;
    for (uint32_t v : verts) {
        if (in_patch[v] == valence[v]) inner.push_back(v);
        in_patch[v] = 0;
    }
    const double nn = std::sqrt(normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]);
    if (int64_t(verts.size()) - int64_t(edges.size()) + int64_t(patch.size()) != 1 || inner.empty() || !(nn > 0))
        return Flush::NotADisk;
    for (double& c : normal) c /= nn;

    // The membrane over the patch alone: every neighbour of an inner vertex is in it.
    TriangleMesh sub;
    sub.vertices.reserve(verts.size());
    for (uint32_t v : verts) sub.vertices.push_back(mesh.vertices[v]);
    auto local = [&](uint32_t v) {
        return uint32_t(std::lower_bound(verts.begin(), verts.end(), v) - verts.begin());
    };
    for (uint32_t f : patch)
        sub.faces.push_back({local(mesh.faces[f][0]), local(mesh.faces[f][1]), local(mesh.faces[f][2])});
    std::vector<uint8_t> free_vertex(verts.size(), 0);
    for (uint32_t v : inner) free_vertex[local(v)] = 1;
    std::vector<Point> moved = thin_plate_ring ? sub.vertices : meshpost::membrane_positions(sub, free_vertex);
    if (thin_plate_ring) {
        // The thin plate: the patch and every face touching one of its vertices, those fixed.
        const meshpost::VertexFaces& faces_of = *thin_plate_ring;
        std::vector<uint32_t> ring_faces;
        for (uint32_t v : verts)
            ring_faces.insert(ring_faces.end(), faces_of.faces.begin() + faces_of.start[v],
                              faces_of.faces.begin() + faces_of.start[v + 1]);
        std::sort(ring_faces.begin(), ring_faces.end());
        ring_faces.erase(std::unique(ring_faces.begin(), ring_faces.end()), ring_faces.end());
        std::vector<uint32_t> all;
        for (uint32_t f : ring_faces) all.insert(all.end(), mesh.faces[f].begin(), mesh.faces[f].end());
        std::sort(all.begin(), all.end());
        all.erase(std::unique(all.begin(), all.end()), all.end());
        auto at = [&](uint32_t v) { return uint32_t(std::lower_bound(all.begin(), all.end(), v) - all.begin()); };
        TriangleMesh ring;
        ring.vertices.reserve(all.size());
        for (uint32_t v : all) ring.vertices.push_back(mesh.vertices[v]);
        for (uint32_t f : ring_faces) ring.faces.push_back({at(mesh.faces[f][0]), at(mesh.faces[f][1]), at(mesh.faces[f][2])});
        std::vector<uint8_t> free_ring(all.size(), 0);
        for (uint32_t v : inner) free_ring[at(v)] = 1;
        const std::vector<Point> plate = meshpost::thin_plate_positions(ring, free_ring);
        for (uint32_t v : inner) moved[local(v)] = plate[at(v)];
    }
    double farthest = 0;
    for (uint32_t v : inner) {
        const Point& a = mesh.vertices[v];
        const Point& b = moved[local(v)];
        farthest = std::max(farthest, std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]));
    }
    // The volume between the patch and its membrane: the patch's signed tetrahedra from one
    // fixed apex, before minus after (the rest of the mesh does not move). A dip holds volume
    // beyond its membrane; a crease or a fossa's floor lies on the cavity's side of it.
    const Point o = sub.vertices[0];
    auto patch_volume = [&](const std::vector<Point>& x) {
        double v6 = 0;
        for (const Face& f : sub.faces) {
            const Point &a = x[f[0]], &b = x[f[1]], &c = x[f[2]];
            const double ax = a[0] - o[0], ay = a[1] - o[1], az = a[2] - o[2];
            const double bx = b[0] - o[0], by = b[1] - o[1], bz = b[2] - o[2];
            const double cx = c[0] - o[0], cy = c[1] - o[1], cz = c[2] - o[2];
            v6 += ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx);
        }
        return v6 / 6.0;
    };
    const double removed = patch_volume(sub.vertices) - patch_volume(moved);
    // A faired closure may take volume or give it; a dip must take it.
    if ((!thin_plate_ring && removed < min_depth_mm * area) || farthest > void_radius_mm) return Flush::Kept;
    std::vector<Point> before(inner.size());
    for (size_t k = 0; k < inner.size(); ++k) {
        before[k] = mesh.vertices[inner[k]];
        mesh.vertices[inner[k]] = moved[local(inner[k])];
    }
    if (crosses_the_mesh(mesh, patch, index, in_this_patch)) {  // the membrane would pass through the wall it rests on
        for (size_t k = 0; k < inner.size(); ++k) mesh.vertices[inner[k]] = before[k];
        return Flush::Crossing;
    }
    index.update(patch);  // an inner vertex's faces are all in the patch
    r.volume_removed_mm3 += removed;
    ++r.flushed;
    r.vertices_moved += inner.size();
    r.moved_vertices.insert(r.moved_vertices.end(), inner.begin(), inner.end());
    r.max_depth_mm = std::max(r.max_depth_mm, farthest);
    return Flush::Flushed;
}

}  // namespace

std::vector<size_t> plug_contacts(const Volume<uint8_t>& labels, const Volume<uint8_t>& bone,
                                  const Volume<uint8_t>& filled, double void_radius_mm) {
    if (labels.dims() != bone.dims() || labels.dims() != filled.dims())
        throw InvalidParameter("plug_contacts: the label, bone and filled volumes differ in size");
    std::vector<size_t> out;
    const LabelBox e = label_box(labels, kEndocast);
    if (e.empty() || !(void_radius_mm > 0)) return out;
    // The endocast's box grown by twice the void fill's radius: a piece reaching its edge goes on
    // beyond it (out of the cavity).
    const Geometry& g = labels.geometry();
    const Dims& d = labels.dims();
    std::array<int64_t, 3> lo{}, n{};
    for (size_t a = 0; a < 3; ++a) {
        const int64_t m = int64_t(std::ceil(2.0 * void_radius_mm / g.spacing[a])) + 2;
        lo[a] = std::max<int64_t>(0, e.lo[a] - m);
        n[a] = std::min<int64_t>(d[a] - 1, e.hi[a] + m) - lo[a] + 1;
    }
    Geometry sg = g;
    sg.dims = {n[0], n[1], n[2]};
    Volume<uint8_t> added(sg, 0);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < n[2]; ++z)
        for (int64_t y = 0; y < n[1]; ++y)
            for (int64_t x = 0; x < n[0]; ++x) {
                const size_t i = labels.index(x + lo[0], y + lo[1], z + lo[2]);
                added(x, y, z) = filled[i] && !bone[i] && labels[i] == kBone;
            }
    const Components cc = connected_components(added, Connectivity::Face6);
    // Per piece: touches the endocast (bit 1), other empty space or the box's edge (bit 2).
    // Slices on all threads, each thread with its own flags, or-ed together (the same for any
    // order); a row without a piece is passed over.
    std::vector<uint8_t> touch(cc.sizes.size(), 0);
    constexpr int64_t kFace[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    auto row_has_piece = [&](int64_t y, int64_t z) {
        const uint32_t* r = cc.labels.data() + added.index(0, y, z);
        uint32_t any = 0;
        for (int64_t x = 0; x < n[0]; ++x) any |= r[x];
        return any != 0;
    };
#pragma omp parallel
    {
        std::vector<uint8_t> mine(touch.size(), 0);
#pragma omp for schedule(dynamic, 4)
        for (int64_t z = 0; z < n[2]; ++z)
            for (int64_t y = 0; y < n[1]; ++y) {
                if (!row_has_piece(y, z)) continue;
                for (int64_t x = 0; x < n[0]; ++x) {
                    const uint32_t k = cc.labels[added.index(x, y, z)];
                    if (k == 0) continue;
                    for (const auto& o : kFace) {
                        const int64_t sx = x + o[0], sy = y + o[1], sz = z + o[2];
                        if (sx < 0 || sy < 0 || sz < 0 || sx >= n[0] || sy >= n[1] || sz >= n[2]) {
                            mine[k - 1] |= 2;
                            continue;
                        }
                        const uint8_t l = labels(sx + lo[0], sy + lo[1], sz + lo[2]);
                        if (l == kEndocast) mine[k - 1] |= 1;
                        else if (l == kOther || l == kUnlabelled) mine[k - 1] |= 2;
                    }
                }
            }
#pragma omp critical(plug_contacts_touch)
        for (size_t k = 0; k < touch.size(); ++k) touch[k] |= mine[k];
    }
    // The plugs' voxels next to the endocast (26-neighbours), in scan order (sorted): per slice on
    // all threads, the slices' lists joined in order.
    std::vector<std::vector<size_t>> slice_out(static_cast<size_t>(n[2]));
#pragma omp parallel for schedule(dynamic, 4)
    for (int64_t z = 0; z < n[2]; ++z)
        for (int64_t y = 0; y < n[1]; ++y) {
            if (!row_has_piece(y, z)) continue;
            for (int64_t x = 0; x < n[0]; ++x) {
                const uint32_t k = cc.labels[added.index(x, y, z)];
                if (k == 0 || touch[k - 1] != 3) continue;
                bool next = false;
                for (int64_t dz = -1; dz <= 1 && !next; ++dz)
                    for (int64_t dy = -1; dy <= 1 && !next; ++dy)
                        for (int64_t dx = -1; dx <= 1 && !next; ++dx) {
                            const int64_t sx = x + lo[0] + dx, sy = y + lo[1] + dy, sz = z + lo[2] + dz;
                            if (sx < 0 || sy < 0 || sz < 0 || sx >= d[0] || sy >= d[1] || sz >= d[2]) continue;
                            next = labels(sx, sy, sz) == kEndocast;
                        }
                if (next) slice_out[size_t(z)].push_back(labels.index(x + lo[0], y + lo[1], z + lo[2]));
            }
        }
    for (const std::vector<size_t>& piece : slice_out) out.insert(out.end(), piece.begin(), piece.end());
    return out;
}

std::vector<uint8_t> faces_on_other_space(const TriangleMesh& mesh, const Volume<uint8_t>& labels) {
    const Geometry& grid = labels.geometry();
    const double step = grid.largest_spacing();
    std::vector<uint8_t> out(mesh.faces.size(), 0);
#pragma omp parallel for schedule(static)
    for (int64_t f = 0; f < int64_t(mesh.faces.size()); ++f) {
        const int64_t i = FaceRay(mesh, uint32_t(f)).voxel_beyond(grid, step);
        if (i < 0) continue;  // the volume's border (closed flat there) or a degenerate face
        const uint8_t l = labels[size_t(i)];
        out[size_t(f)] = l == kOther || l == kUnlabelled;
    }
    return out;
}

DipResult flush_dips(TriangleMesh& mesh, const std::vector<uint8_t>& face_on_bone, const Geometry& grid,
                     const std::vector<size_t>& plug, double void_radius_mm, const DipParams& p,
                     const std::vector<uint8_t>& face_on_other, const std::function<void()>& beside) {
    if (face_on_bone.size() != mesh.faces.size())
        throw InvalidParameter("flush_dips: " + std::to_string(face_on_bone.size()) + " face flags for " +
                               std::to_string(mesh.faces.size()) + " faces");
    if (!std::isfinite(p.min_mean_depth_voxels) || p.min_mean_depth_voxels < 0 || p.rim_rings < 0 || p.rim_rings_retry < 0 || p.wall_rings < 0 ||
        !(p.wall_max_cosine >= 0 && p.wall_max_cosine <= 1) || !(p.wall_climb_voxels >= 0) || !(p.wall_footprint > 0) ||
        !(p.wall_length_voxels >= 0 && std::isfinite(p.wall_length_voxels)) ||
        !(p.min_plug_share >= 0 && p.min_plug_share <= 1) || !(p.sunk_wall_share >= 0 && p.sunk_wall_share <= 1) ||
        !(p.sunk_other_share >= 0 && p.sunk_other_share <= 1) || p.sunk_wall_rings < 0 || !(p.sunk_footprint_voxels >= 0) ||
        !(p.fair_max_move_voxels >= 0 && std::isfinite(p.fair_max_move_voxels)) || p.fair_rim_rings < 0 ||
        !(p.fair_max_area_share > 0 && p.fair_max_area_share <= 1))
        throw InvalidParameter("flush_dips: min_mean_depth_voxels " + std::to_string(p.min_mean_depth_voxels) +
                               ", rim_rings " + std::to_string(p.rim_rings) + ", rim_rings_retry " +
                               std::to_string(p.rim_rings_retry) + ", wall_rings " + std::to_string(p.wall_rings) +
                               ", wall_max_cosine " + std::to_string(p.wall_max_cosine) + ", wall_climb_voxels " +
                               std::to_string(p.wall_climb_voxels) + ", wall_footprint " +
                               std::to_string(p.wall_footprint) + ", wall_length_voxels " +
                               std::to_string(p.wall_length_voxels) + ", min_plug_share " +
                               std::to_string(p.min_plug_share) + ", sunk_wall_share " + std::to_string(p.sunk_wall_share) +
                               ", sunk_other_share " + std::to_string(p.sunk_other_share) + ", sunk_wall_rings " +
                               std::to_string(p.sunk_wall_rings) + ", sunk_footprint_voxels " +
                               std::to_string(p.sunk_footprint_voxels) + ", fair_max_move_voxels " +
                               std::to_string(p.fair_max_move_voxels) + ", fair_rim_rings " + std::to_string(p.fair_rim_rings) +
                               ", fair_max_area_share " + std::to_string(p.fair_max_area_share) +
                               ": expected values >= 0, the shares <= 1 (fair_max_area_share > 0)");
    if (!face_on_other.empty() && face_on_other.size() != mesh.faces.size())
        throw InvalidParameter("flush_dips: " + std::to_string(face_on_other.size()) + " face_on_other flags for " +
                               std::to_string(mesh.faces.size()) + " faces");
    DipResult r;
    const double climb_tol = p.wall_climb_voxels * grid.smallest_spacing();
    const double min_depth_mm = p.min_mean_depth_voxels * grid.smallest_spacing();
    const double wall_length_mm = p.wall_length_voxels * grid.smallest_spacing();
    if (!p.enabled || !(void_radius_mm > 0) || mesh.faces.empty()) {
        if (beside) beside();
        return r;
    }
    for (const Face& f : mesh.faces)
        for (uint32_t v : f)
            if (v >= mesh.vertices.size()) throw InvalidParameter("flush_dips: a face references a vertex beyond the mesh");
    const std::vector<std::array<uint32_t, 3>> nb = meshpost::face_neighbours(mesh);
    std::vector<int64_t> owner(mesh.faces.size(), -1);
    Enclosure enclosure(mesh.faces.size());
    // A face lies on a plug when a voxel the void fill added is just outside it (half a voxel and
    // one voxel out along its normal, nearest voxel). The plugs' voxels are a bit per voxel of the
    // grid (a lookup per ray, not a search of the list); an index beyond the grid is no voxel a
    // ray can reach.
    const double step = grid.largest_spacing();
    const size_t voxels = grid.voxel_count();
    std::vector<uint64_t> plug_bits(plug.empty() ? 0 : (voxels + 63) / 64, 0);
    for (size_t i : plug)
        if (i < voxels) plug_bits[i >> 6] |= uint64_t(1) << (i & 63);
    auto on_plug = [&](uint32_t f) {
        if (plug.empty()) return false;
        const FaceRay ray(mesh, f);
        for (double t : {0.5 * step, step}) {
            const int64_t i = ray.voxel_beyond(grid, t);
            if (i >= 0 && ((plug_bits[size_t(i) >> 6] >> (size_t(i) & 63)) & 1u)) return true;
        }
        return false;
    };
    // The patches: faces off bone or on a plug (the dip's faces along the hole's rounded rim sample
    // its wall 1 mm out, but lie on the plug).
    std::vector<uint8_t> wall(mesh.faces.size(), 0), plug_face(mesh.faces.size(), 0);
#pragma omp parallel for schedule(static)
    for (int64_t f = 0; f < int64_t(mesh.faces.size()); ++f) {
        plug_face[size_t(f)] = on_plug(uint32_t(f));
        wall[size_t(f)] = face_on_bone[size_t(f)] && !plug_face[size_t(f)];
    }
    std::vector<std::vector<uint32_t>> patches = off_bone_patches(mesh, wall, nb, owner, enclosure);
    std::vector<uint32_t> valence(mesh.vertices.size(), 0);
    for (const Face& f : mesh.faces)
        for (uint32_t v : f) ++valence[v];
    auto face_area = [&](uint32_t f) {
        const Point c = meshpost::face_cross(mesh, mesh.faces[f]);
        return 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    };
    const double max_area = M_PI * 4 * void_radius_mm * void_radius_mm;
    double area_of_mesh = -1;  // when first needed (the faired closures' cap)
    auto mesh_area = [&]() {
        if (area_of_mesh < 0) area_of_mesh = meshpost::surface_area_mm2(mesh);  // the sum of face_area, in face order
        return area_of_mesh;
    };
    std::vector<uint32_t> in_patch(mesh.vertices.size(), 0);
    FaceIndex index(mesh);
    std::vector<uint8_t> in_this_patch(mesh.faces.size(), 0);
    const bool fair = p.fair_max_move_voxels > 0 && p.sunk_wall_share > 0 && face_on_other.size() == mesh.faces.size();
    meshpost::VertexFaces faces_of;  // each vertex's faces (the thin plate's ring), when first needed
    auto incidence = [&]() -> const meshpost::VertexFaces& {
        if (faces_of.start.empty()) faces_of = meshpost::vertex_faces(mesh, "flush_dips");
        return faces_of;
    };
    const std::function<void()> loop = [&] {
        for (size_t id = 0; id < patches.size(); ++id) {
            std::vector<uint32_t>& patch = patches[id];
            if (patch.empty()) continue;  // enclosed by another
            double patch_area = 0, plug_area = 0;
            for (uint32_t f : patch) {
                const double a = face_area(f);
                patch_area += a;
                if (plug_face[f]) plug_area += a;
            }
            const bool dip = patch_area <= max_area && plug_area >= p.min_plug_share * patch_area;
            // Else a closure sunk down its channel: at least a disk of the void fill's ball in area,
            // facing other empty space beyond (not a floor of thin bone: the sella's), with the
            // channel's wall round most of it (checked once grown up that wall).
            std::vector<uint32_t> around;  // the faces next to the patch and its rim's ring (on bone)
            bool cap = false;
            if (!dip) {
                if (!(p.sunk_wall_share > 0) || face_on_other.size() != mesh.faces.size() ||
                    patch_area < M_PI * void_radius_mm * void_radius_mm)
                    continue;
                double other_area = 0, cap_area = 0;
                for (uint32_t f : patch) {
                    if (face_on_other[f]) other_area += face_area(f);
                    if (face_on_other[f] == kCutCap) cap_area += face_area(f);
                }
                if (other_area < p.sunk_other_share * patch_area) continue;
                // Without its cut cap too little faces other space to be sunk: a cut opening's closure,
                // only faired.
                cap = other_area - cap_area < p.sunk_other_share * patch_area;
            }
            const double bound = dip ? void_radius_mm : std::sqrt(patch_area / M_PI);
            // Grown across the hole's wall, then by the rim rings; where the membrane of the patch grown
            // that far would cross the mesh, with up to rim_rings_retry more rim rings (a fold where
            // the rim turns sharply), then with half as many wall rings, then none. A sunk closure's
            // walk keeps within a voxel of its footprint (up the channel, not up the fossa beyond
            // its mouth) and must have reached sunk_wall_share of the faces around it.
            const size_t own = patch.size();
            int extra = 0;
            for (int wall = dip ? p.wall_rings : p.sunk_wall_rings;;) {
                if (!dip) {
                    // First the ring of faces along the rim, rounded by the blur, then the wall's.
                    grow_patch(patch, nb, owner, int64_t(id), 1);
                    around.clear();
                    for (uint32_t f : patch)
                        for (uint32_t g : nb[f])
                            if (g != meshpost::kNoFace && owner[g] < 0) around.push_back(g);
                    std::sort(around.begin(), around.end());
                    around.erase(std::unique(around.begin(), around.end()), around.end());
                }
                if (wall > 0) {
                    if (dip) grow_along_wall(patch, mesh, nb, owner, int64_t(id), wall, p.wall_max_cosine, climb_tol, p.wall_footprint,
                                             0, wall_length_mm * wall / p.wall_rings);
                    else grow_along_wall(patch, mesh, nb, owner, int64_t(id), wall, p.wall_max_cosine, climb_tol, 1.0,
                                         p.sunk_footprint_voxels * grid.smallest_spacing(), 0);
                }
                if (!dip) {
                    size_t walled = 0;
                    for (uint32_t g : around) walled += owner[g] == int64_t(id);
                    if (cap || wall == 0 || double(walled) < p.sunk_wall_share * double(around.size())) {
                        for (size_t k = own; k < patch.size(); ++k) owner[patch[k]] = -1;
                        patch.resize(own);
                        if (fair) {
                            // Not sunk: the watershed's closure across a wide opening (a voxel staircase
                            // on a tilted grid) or a cut cap, onto the thin plate continuing the table
                            // around it.
                            grow_patch(patch, nb, owner, int64_t(id), p.fair_rim_rings);
                            enclosure.fill(patches, id, owner, nb);
                            double faired_area = 0;
                            for (uint32_t f : patch) faired_area += face_area(f);
                            if (faired_area <= p.fair_max_area_share * mesh_area() &&
                                flush_patch(mesh, patch, valence, in_patch, p.fair_max_move_voxels * grid.smallest_spacing(),
                                            min_depth_mm, p, r, index, in_this_patch, &incidence()) == Flush::Flushed)
                                ++r.faired;
                        }
                        break;
                    }
                }
                grow_patch(patch, nb, owner, int64_t(id), p.rim_rings + extra);
                enclosure.fill(patches, id, owner, nb);
                const Flush f = flush_patch(mesh, patch, valence, in_patch, bound, min_depth_mm, p, r, index, in_this_patch);
                if (f == Flush::Flushed && !dip) ++r.sunk;
                if (f != Flush::NotADisk && (f != Flush::Crossing || wall == 0)) ++r.patches;
                if (f != Flush::Crossing) break;
                if (wall == 0) {
                    ++r.crossing;
                    break;
                }
                for (size_t k = own; k < patch.size(); ++k) owner[patch[k]] = -1;
                patch.resize(own);
                if (extra < p.rim_rings_retry) {
                    ++extra;
                    continue;
                }
                extra = 0;
                wall /= 2;
            }
        }
    };
    side_by_side(loop, beside);
    return r;
}

}  // namespace endocast
