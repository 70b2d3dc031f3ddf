// Closing surfaces as patches of faces of the mesh (closing_patches.h).
#include "method/closing_patches.h"

#include <algorithm>
#include <cmath>

#include "meshpost/patches.h"

namespace endocast {

using meshpost::Face;
using meshpost::Point;
using meshpost::TriangleMesh;

namespace {

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

}  // namespace

void Enclosure::fill(std::vector<std::vector<uint32_t>>& patches, size_t id, std::vector<int64_t>& owner,
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

bool crosses_the_mesh(const TriangleMesh& m, const std::vector<uint32_t>& patch) {
    struct Box { Point lo, hi; };
    auto box = [&](const Face& f) {
        Box b{m.vertices[f[0]], m.vertices[f[0]]};
        for (int k = 1; k < 3; ++k)
            for (size_t a = 0; a < 3; ++a) {
                b.lo[a] = std::min(b.lo[a], m.vertices[f[size_t(k)]][a]);
                b.hi[a] = std::max(b.hi[a], m.vertices[f[size_t(k)]][a]);
            }
        return b;
    };
    auto apart = [](const Box& a, const Box& b) {
        return a.lo[0] > b.hi[0] || b.lo[0] > a.hi[0] || a.lo[1] > b.hi[1] || b.lo[1] > a.hi[1] || a.lo[2] > b.hi[2] ||
               b.lo[2] > a.hi[2];
    };
    std::vector<Box> boxes;
    boxes.reserve(patch.size());
    Box all = box(m.faces[patch[0]]);
    for (uint32_t f : patch) {
        boxes.push_back(box(m.faces[f]));
        for (size_t a = 0; a < 3; ++a) {
            all.lo[a] = std::min(all.lo[a], boxes.back().lo[a]);
            all.hi[a] = std::max(all.hi[a], boxes.back().hi[a]);
        }
    }
    for (size_t g = 0; g < m.faces.size(); ++g) {
        const Box bg = box(m.faces[g]);
        if (apart(bg, all)) continue;
        for (size_t k = 0; k < patch.size(); ++k)
            if (patch[k] != g && !apart(bg, boxes[k]) && faces_cross(m, m.faces[patch[k]], m.faces[g])) return true;
    }
    return false;
}

}  // namespace endocast
