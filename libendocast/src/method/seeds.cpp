// Seeds for the watershed: the border, the cavity candidates and the chosen braincase (seeds.h).
#include "endocast/stages/seeds.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <sstream>

#include "endocast/stages/components.h"
#include "endocast/stages/distance.h"
#include "endocast/stages/watershed.h"

namespace endocast {
namespace {

std::string fmt(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

// Per face of the volume (2 * axis + side), per column below it ((u, v) the other two axes in
// increasing order, u + nu * v): the depth of its first kBone voxel from the face, -1 for none.
// One pass in memory order, the planes in parallel: the x faces per row, the y faces per column of
// the thread's own planes, the z faces per thread over its run of planes (then merged in order).
// The per-voxel updates are selects on contiguous arrays, which the compiler vectorizes.
std::array<std::vector<int32_t>, 6> first_bone_depths(const Volume<uint8_t>& labels) {
    const int64_t nx = labels.nx(), ny = labels.ny(), nz = labels.nz();
    std::array<std::vector<int32_t>, 6> first;
    first[0].assign(size_t(ny * nz), -1), first[1].assign(size_t(ny * nz), -1);  // x faces: (y, z)
    first[2].assign(size_t(nx * nz), -1), first[3].assign(size_t(nx * nz), -1);  // y faces: (x, z)
    first[4].assign(size_t(nx * ny), -1), first[5].assign(size_t(nx * ny), -1);  // z faces: (x, y)
    // Per thread: the first and last plane with bone per (x, y) column, -1 for none.
    std::vector<std::vector<int32_t>> zfirst, zlast;
#pragma omp parallel
    {
        const int threads = omp_get_num_threads(), t = omp_get_thread_num();
#pragma omp single
        zfirst.resize(size_t(threads)), zlast.resize(size_t(threads));
        std::vector<int32_t>& zf = zfirst[size_t(t)];
        std::vector<int32_t>& zl = zlast[size_t(t)];
        zf.assign(size_t(nx * ny), -1), zl.assign(size_t(nx * ny), -1);
        const int64_t z0 = nz * t / threads, z1 = nz * (t + 1) / threads;
        for (int64_t z = z0; z < z1; ++z) {
            int32_t* __restrict fy = first[2].data() + nx * z;
            int32_t* __restrict ly = first[3].data() + nx * z;
            const int32_t zz = int32_t(z);
            for (int64_t y = 0; y < ny; ++y) {
                const uint8_t* __restrict row = labels.data() + labels.index(0, y, z);
                const uint8_t* const lo = std::find(row, row + nx, kBone);
                if (lo == row + nx) continue;
                const int64_t hi = nx - 1 - (std::find(std::make_reverse_iterator(row + nx), std::make_reverse_iterator(row), kBone) -
                                             std::make_reverse_iterator(row + nx));
                first[0][size_t(y + ny * z)] = int32_t(lo - row), first[1][size_t(y + ny * z)] = int32_t(nx - 1 - hi);
                const int32_t yy = int32_t(y), yr = int32_t(ny - 1 - y);
                int32_t* __restrict f = zf.data() + nx * y;
                int32_t* __restrict l = zl.data() + nx * y;
                for (int64_t x = 0; x < nx; ++x) {
                    const bool b = row[x] == kBone;
                    fy[x] = b && fy[x] < 0 ? yy : fy[x];
                    ly[x] = b ? yr : ly[x];
                    f[x] = b && f[x] < 0 ? zz : f[x];
                    l[x] = b ? zz : l[x];
                }
            }
        }
    }
    // The z faces: the first thread (in plane order) with bone in a column gives its first plane,
    // the last one its last.
    for (size_t t = 0; t < zfirst.size(); ++t)
        for (size_t c = 0; c < size_t(nx * ny); ++c) {
            if (zfirst[t][c] < 0) continue;
            if (first[4][c] < 0) first[4][c] = zfirst[t][c];
            first[5][c] = int32_t(nz - 1) - zlast[t][c];
        }
    return first;
}

// Marks as kOther every empty voxel within scale*d(b) of an empty face voxel b of the scan (the
// volume, or the scan p.scan_dims that holds it as a box: SeedParams::box_lo), and every empty
// voxel of a face of such a box inside the scan.
//
// A voxel x is in the union of balls when min_b (|x - b|^2 - r_b^2) <= 0. The balls of one face
// are centred on its plane, so for them this splits into a 2-D part in the plane and the squared
// depth below it: g(u, v) = min_b (|(u, v) - b|^2 - r_b^2), a 2-D generalized transform of the
// face, and the voxel at depth t is covered when g(u, v) + (t w)^2 <= 0. Each face's columns are
// covered to a depth computed once (the six faces in parallel); the volume is then labelled in one
// parallel pass: O(face area + volume) instead of a 3-D transform of the whole volume. (The sums
// are rounded in another order than a 3-D transform would; only a voxel within rounding of a ball's
// surface could differ.)
size_t border_seeds(Volume<uint8_t>& labels, const Volume<float>& distance, double scale,
                    const SeedParams& p) {
    const Geometry& g = labels.geometry();
    const Dims& dm = g.dims;
    constexpr float kInfF = std::numeric_limits<float>::infinity();
    // deepest[2 * a + side][u + nu * v]: the last covered layer below face (a, side), -1 if none;
    // (u, v) are the other two axes in increasing order.
    std::array<std::vector<int32_t>, 6> deepest;
    const std::array<std::vector<int32_t>, 6> first_bone =
        p.scan_dims[0] > 0 ? first_bone_depths(labels) : std::array<std::vector<int32_t>, 6>{};
    // The six faces in parallel; each face's small transform then runs on one thread.
#pragma omp parallel for schedule(dynamic, 1)
    for (int face = 0; face < 6; ++face) {
        const int a = face / 2, side = face % 2;
        const int ua = a == 0 ? 1 : 0, va = a == 2 ? 1 : 2;
        const int64_t nu = dm[ua], nv = dm[va], na = dm[a];
        const double w2 = g.spacing[a] * g.spacing[a];
        // The scan's face: `off` layers beyond the volume's (0: the volume's face is the scan's),
        // spanning NU x NV voxels, the volume's (u, v) = (0, 0) at (lu, lv) on it.
        const bool in_scan = p.scan_dims[0] > 0;
        const int64_t NA = in_scan ? p.scan_dims[size_t(a)] : na;
        const int64_t off = !in_scan ? 0 : side ? NA - p.box_lo[size_t(a)] - na : p.box_lo[size_t(a)];
        const int64_t NU = off ? p.scan_dims[size_t(ua)] : nu, NV = off ? p.scan_dims[size_t(va)] : nv;
        const int64_t lu = off ? p.box_lo[size_t(ua)] : 0, lv = off ? p.box_lo[size_t(va)] : 0;
        Geometry fg;
        fg.dims = {NU, NV, 1};
        fg.spacing = {g.spacing[ua], g.spacing[va], g.spacing[a]};
        std::vector<float> f(size_t(NU * NV), kInfF);
        std::array<int64_t, 3> q{};
        if (off == 0) {
            q[a] = side ? na - 1 : 0;
            for (int64_t v = 0; v < nv; ++v)
                for (int64_t u = 0; u < nu; ++u) {
                    q[ua] = u;
                    q[va] = v;
                    const size_t i = labels.index(q[0], q[1], q[2]);
                    if (labels[i] == kBone) continue;
                    const double r = scale * distance[i];
                    f[size_t(u + nu * v)] = static_cast<float>(-(r * r));
                }
        } else {
            // Every voxel of the scan's face is empty; its squared distance to bone is a 2-D
            // transform of the squared depth of each column's first bone below the face (the
            // bone lies in the box; no bone: +inf).
            const std::vector<int32_t>& depth = first_bone[size_t(face)];
            for (int64_t v = 0; v < nv; ++v)
                for (int64_t u = 0; u < nu; ++u) {
                    const int32_t t = depth[size_t(u + nu * v)];
                    if (t >= 0) f[size_t(u + lu + NU * (v + lv))] = static_cast<float>(w2 * double(off + t) * double(off + t));
                }
            generalized_squared_distance(f, fg);
            for (float& x : f) x = scale > 0 ? static_cast<float>(-(scale * scale * double(x))) : 0.0f;
        }
        generalized_squared_distance(f, fg);
        std::vector<int32_t>& deep = deepest[size_t(face)];
        deep.assign(size_t(nu * nv), -1);
        for (int64_t v = 0; v < nv; ++v)
            for (int64_t u = 0; u < nu; ++u) {
                const double fk = f[size_t(u + lu + NU * (v + lv))];
                auto covered = [&](int64_t t) {
                    const double dq = double(t);
                    return static_cast<float>(w2 * dq * dq + fk) <= 0.0f;
                };
                int32_t& dk = deep[size_t(u + nu * v)];
                // A face of the box inside the scan: its voxels are empty, reached from beyond.
                if (off > 0) dk = 0;
                if (!covered(0)) continue;
                // covered() is monotone in t (true, then false): start at the root of w2 t^2 + fk
                // and settle on the last covered layer (a step or two for rounding), instead of
                // walking down the whole covered depth (t counts from the scan's face).
                int64_t t = std::min<int64_t>(NA - 1, int64_t(std::floor(std::sqrt(std::max(0.0, -fk / w2)))));
                while (t > 0 && !covered(t)) --t;
                while (t + 1 < NA && covered(t + 1)) ++t;
                if (t >= off) dk = int32_t(std::min<int64_t>(na - 1, t - off));
            }
    }
    const int64_t nx = dm[0], ny = dm[1], nz = dm[2];
    size_t n = 0;
#pragma omp parallel for schedule(static) reduction(+ : n)
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < ny; ++y) {
            // Covered from the x faces: x <= x0 or x >= x1; from the others, per x.
            const int64_t x0 = deepest[0][size_t(y + ny * z)], x1 = nx - 1 - deepest[1][size_t(y + ny * z)];
            const int32_t* y0 = deepest[2].data() + nx * z;
            const int32_t* y1 = deepest[3].data() + nx * z;
            const int32_t* z0 = deepest[4].data() + nx * y;
            const int32_t* z1 = deepest[5].data() + nx * y;
            uint8_t* row = labels.data() + labels.index(0, y, z);
            const int64_t ty1 = ny - 1 - y, tz1 = nz - 1 - z;
            // Without branches (vectorized): the row's covered empty voxels become kOther.
            const int32_t yy = int32_t(y), zz = int32_t(z), ry = int32_t(ty1), rz = int32_t(tz1);
            size_t row_n = 0;
            for (int64_t x = 0; x < nx; ++x) {
                const bool covered = (x <= x0) | (x >= x1) | (yy <= y0[x]) | (ry <= y1[x]) | (zz <= z0[x]) | (rz <= z1[x]);
                const bool mark = covered & (row[x] != kBone);
                row[x] = mark ? uint8_t(kOther) : row[x];
                row_n += mark;
            }
            n += row_n;
        }
    return n;
}

// The voxels of one face of the volume (face = 2 * axis + side) that an empty path within the
// face (4-connected, through voxels not kBone) joins to the face's rim: reached[u + nu * v], (u, v)
// the other two axes in increasing order.
struct FaceFlood {
    int a = 0, side = 0, ua = 0, va = 0;
    int64_t nu = 0, nv = 0;
    std::vector<uint8_t> reached;
    size_t index(const Dims& dm, int64_t u, int64_t v) const {  // the voxel at (u, v) in the volume
        std::array<int64_t, 3> q{};
        q[size_t(a)] = side ? dm[size_t(a)] - 1 : 0;
        q[size_t(ua)] = u;
        q[size_t(va)] = v;
        return size_t(q[0] + dm[0] * (q[1] + dm[1] * q[2]));
    }
};
FaceFlood flood_face_from_rim(const Volume<uint8_t>& labels, int face) {
    const Dims& dm = labels.dims();
    FaceFlood f;
    f.a = face / 2, f.side = face % 2;
    f.ua = f.a == 0 ? 1 : 0, f.va = f.a == 2 ? 1 : 2;
    f.nu = dm[size_t(f.ua)], f.nv = dm[size_t(f.va)];
    auto label = [&](int64_t u, int64_t v) { return labels[f.index(dm, u, v)]; };
    f.reached.assign(size_t(f.nu * f.nv), 0);
    std::vector<uint8_t> seen(f.reached.size(), 0);
    std::vector<std::pair<int64_t, int64_t>> stack;
    auto visit = [&](int64_t u, int64_t v) {
        if (u < 0 || v < 0 || u >= f.nu || v >= f.nv || seen[size_t(u + f.nu * v)]) return;
        seen[size_t(u + f.nu * v)] = 1;
        if (label(u, v) == kBone) return;
        stack.push_back({u, v});
    };
    for (int64_t u = 0; u < f.nu; ++u) visit(u, 0), visit(u, f.nv - 1);
    for (int64_t v = 0; v < f.nv; ++v) visit(0, v), visit(f.nu - 1, v);
    while (!stack.empty()) {
        const auto [u, v] = stack.back();
        stack.pop_back();
        f.reached[size_t(u + f.nu * v)] = 1;
        visit(u - 1, v), visit(u + 1, v), visit(u, v - 1), visit(u, v + 1);
    }
    return f;
}

// The "other" seeds of a scan cropped through the braincase: the empty voxels of each face of the
// volume that an empty path within that face joins to the face's rim (4-connected). The cavity's
// cut section and the pockets cut by the face are ringed by bone there, so they are not seeded
// and the cavity reaches the border (a flat closure, no dent); the air or tissue around the skull
// is. Returns how many became kOther.
size_t open_border_seeds(Volume<uint8_t>& labels) {
    size_t n = 0;
    for (int face = 0; face < 6; ++face) {
        const FaceFlood f = flood_face_from_rim(labels, face);
        for (int64_t v = 0; v < f.nv; ++v)
            for (int64_t u = 0; u < f.nu; ++u) {
                uint8_t& l = labels[f.index(labels.dims(), u, v)];
                if (f.reached[size_t(u + f.nu * v)] && l == kUnlabelled) {
                    l = kOther;
                    ++n;
                }
            }
    }
    return n;
}

// The area (mm^2) of the largest empty region of a face of the volume that bone rings within the
// face (not joined to the face's rim by an empty path in it): the section of a cavity the border
// cuts (a scan cropped through the braincase; a canal's or the foramen magnum's where the scan
// stops below the skull).
double largest_ringed_section_mm2(const Volume<uint8_t>& labels) {
    const Geometry& g = labels.geometry();
    double best = 0;
    for (int face = 0; face < 6; ++face) {
        const FaceFlood f = flood_face_from_rim(labels, face);
        const double pixel = g.spacing[size_t(f.ua)] * g.spacing[size_t(f.va)];
        // The ringed regions: the face's empty voxels the rim's flood did not reach, as a volume
        // of one slice, where 6-connected components are the face's 4-connected regions.
        Geometry fg;
        fg.dims = {f.nu, f.nv, 1};
        Volume<uint8_t> ringed(fg, 0);
        for (int64_t v = 0; v < f.nv; ++v)
            for (int64_t u = 0; u < f.nu; ++u)
                ringed(u, v, 0) = !f.reached[size_t(u + f.nu * v)] && labels[f.index(labels.dims(), u, v)] != kBone;
        for (size_t voxels : connected_components(ringed, Connectivity::Face6).sizes)
            best = std::max(best, double(voxels) * pixel);
    }
    return best;
}

// kBone on bone, kUnlabelled elsewhere: the labels before any seed is placed.
Volume<uint8_t> unseeded_labels(const Volume<uint8_t>& bone) {
    Volume<uint8_t> labels(bone.geometry());
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(bone.size()); ++i) labels[i] = bone[i] ? kBone : kUnlabelled;
    return labels;
}

// Paints `label` on the unlabelled voxels within radius r (mm) of voxel c; with `override_other`,
// "other" seed voxels inside the ball are painted too.
size_t ball_seed(Volume<uint8_t>& labels, const std::array<int64_t, 3>& c, double r,
                 bool override_other, uint8_t label = kEndocast) {
    const Geometry& g = labels.geometry();
    const double r2 = r * r * (1.0 + 1e-9);
    std::array<int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        const int64_t ext = int64_t(std::floor(r / g.spacing[a]));
        lo[a] = std::max<int64_t>(0, c[a] - ext);
        hi[a] = std::min<int64_t>(g.dims[a] - 1, c[a] + ext);
    }
    // Each row tests only the voxels within a voxel of the ball's chord (the same test, so the same
    // voxels); the planes in parallel (each voxel written once: any thread count).
    size_t n = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : n)
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y) {
            const double dy = double(y - c[1]) * g.spacing[1];
            const double dz = double(z - c[2]) * g.spacing[2];
            const double rest = std::max(0.0, r2 - dy * dy - dz * dz);
            const int64_t half = int64_t(std::floor(std::sqrt(rest) / g.spacing[0])) + 1;
            const int64_t x0 = std::max(lo[0], c[0] - half), x1 = std::min(hi[0], c[0] + half);
            for (int64_t x = x0; x <= x1; ++x) {
                const double dx = double(x - c[0]) * g.spacing[0];
                if (dx * dx + dy * dy + dz * dz > r2) continue;
                uint8_t& l = labels(x, y, z);
                if (l == kUnlabelled || (override_other && l == kOther)) {
                    l = label;
                    ++n;
                }
            }
        }
    return n;
}

// Voxels holding `label`, counted in parallel.
size_t count_label(const Volume<uint8_t>& labels, uint8_t label) {
    size_t n = 0;
    const uint8_t* l = labels.data();
#pragma omp parallel for schedule(static) reduction(+ : n)
    for (int64_t i = 0; i < int64_t(labels.size()); ++i) n += l[i] == label;
    return n;
}

std::array<int64_t, 3> coords(const Geometry& g, size_t i) {
    const int64_t nx = g.dims[0], ny = g.dims[1];
    return {int64_t(i % size_t(nx)), int64_t((i / size_t(nx)) % size_t(ny)),
            int64_t(i / size_t(nx * ny))};
}

// Deepest local maxima (26-neighbourhood) of d among unlabelled voxels with d >= dmin, deepest
// first (ties by index).
std::vector<size_t> deep_maxima(const Volume<uint8_t>& labels, const Volume<float>& d, float dmin) {
    const int64_t nx = labels.nx(), ny = labels.ny(), nz = labels.nz();
    // Per slice in parallel, concatenated in slice order: the scan order of one thread.
    std::vector<std::vector<size_t>> per_z(size_t(std::max<int64_t>(nz, 0)));
#pragma omp parallel for schedule(dynamic, 4)
    for (int64_t z = 1; z < nz - 1; ++z)
        for (int64_t y = 1; y + 1 < ny; ++y)
            for (int64_t x = 1; x + 1 < nx; ++x) {
                const size_t i = labels.index(x, y, z);
                const float v = d[i];
                if (v < dmin || labels[i] != kUnlabelled) continue;
                bool is_max = true;
                for (int dz = -1; dz <= 1 && is_max; ++dz)
                    for (int dy = -1; dy <= 1 && is_max; ++dy)
                        for (int dx = -1; dx <= 1; ++dx)
                            if (d(x + dx, y + dy, z + dz) > v) {
                                is_max = false;
                                break;
                            }
                if (is_max) per_z[size_t(z)].push_back(i);
            }
    std::vector<size_t> out;
    for (const auto& v : per_z) out.insert(out.end(), v.begin(), v.end());
    std::stable_sort(out.begin(), out.end(), [&](size_t a, size_t b) { return d[a] > d[b]; });
    return out;
}

// Union-find over candidates; the root is the smallest index (the deepest).
int find_root(std::vector<int>& parent, int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
}

// SeedMode::Auto: chooses the cavity by enclosure and size (see seeds.h). `r.labels` holds the
// border seeds on entry; on return the chosen cavity's seed balls are kEndocast and the other
// candidates' balls kOther.
// Candidate centres: deep maxima of the empty space outside the maximal balls of deeper
// candidates (at most p.max_candidates), or the deepest voxel when there are none.
std::vector<size_t> candidate_centres(const SeedResult& r, const Volume<float>& distance, const SeedParams& p) {
    const Geometry& g = r.labels.geometry();
    float dmax = 0;
#pragma omp parallel for schedule(static) reduction(max : dmax)
    for (int64_t i = 0; i < int64_t(r.labels.size()); ++i)
        if (r.labels[i] == kUnlabelled) dmax = std::max(dmax, distance[i]);
    if (dmax <= 0)
        throw NoResult("no empty space is left away from the volume border once the border "
                       "seeds are placed: expected an enclosed braincase (is the skull open "
                       "to the border, or the isovalue too high?)");
    const float dmin = std::max(float(p.min_candidate_depth) * dmax,
                                float(2 * g.smallest_spacing()));
    std::vector<size_t> centres;
    const size_t kmax = size_t(std::clamp(p.max_candidates, 1, 250));
    for (size_t m : deep_maxima(r.labels, distance, std::min(dmin, dmax))) {
        if (centres.size() >= kmax) break;
        const auto cm = coords(g, m);
        bool inside = false;
        for (size_t c : centres) {
            const auto cc = coords(g, c);
            double d2 = 0;
            for (int a = 0; a < 3; ++a) d2 += std::pow(double(cm[a] - cc[a]) * g.spacing[a], 2);
            if (d2 <= double(distance[c]) * double(distance[c])) {
                inside = true;
                break;
            }
        }
        if (!inside) centres.push_back(m);
    }
    if (centres.empty()) {  // a plateau at the border of the volume: fall back to the deepest voxel
        for (size_t i = 0; i < r.labels.size(); ++i)
            if (r.labels[i] == kUnlabelled && distance[i] == dmax) {
                centres.push_back(i);
                break;
            }
    }
    return centres;
}

// Per candidate region of the flood: voxels, boundary faces (all, on bone, on the border seeds'
// balls, on the volume border) and, per pair of regions, the faces between them and the deepest
// saddle (pass) across them. Row-major K x K for the pairs.
struct RegionStats {
    std::vector<double> voxels, faces, bone_faces, ball_faces, border_faces, pair_faces, pass;
};

RegionStats region_stats(const Volume<uint8_t>& flood, const Volume<uint8_t>& labels, const Volume<float>& distance,
                         int K) {
    RegionStats st;
    st.voxels.assign(K, 0), st.faces.assign(K, 0), st.bone_faces.assign(K, 0), st.ball_faces.assign(K, 0);
    st.border_faces.assign(K, 0), st.pair_faces.assign(size_t(K) * K, 0), st.pass.assign(size_t(K) * K, 0);
    const Geometry& g = flood.geometry();
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    const int64_t off[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    // Per thread (slices handed out in turn: the regions lie in some of them), then summed: counts
    // (exact in double) and maxima, so the totals do not depend on the thread count. A row without
    // a region's voxel is passed over.
#pragma omp parallel
    {
        std::vector<double> t_voxels(K, 0), t_faces(K, 0), t_bone(K, 0), t_ball(K, 0), t_border(K, 0);
        std::vector<double> t_pair(size_t(K) * K, 0), t_pass(size_t(K) * K, 0);
        // A voxel inside the volume whose six neighbours are of its region adds a voxel and no
        // face: counted as a whole number (the voxel counts are whole numbers in double, so the
        // sums are the same).
        std::vector<uint64_t> t_inner(K, 0);
#pragma omp for schedule(dynamic, 2)
        for (int64_t z = 0; z < nz; ++z)
            for (int64_t y = 0; y < ny; ++y) {
                const uint8_t* row = flood.data() + flood.index(0, y, z);
                uint8_t any = 0;
                for (int64_t x = 0; x < nx; ++x) any |= uint8_t(row[x] > kBone);
                if (!any) continue;
                const bool inner_row = y > 0 && z > 0 && y < ny - 1 && z < nz - 1;
                const int64_t sy = nx, sz = nx * ny;
                for (int64_t x = 0; x < nx; ++x) {
                    const size_t i = flood.index(x, y, z);
                    const int L = flood[i];
                    if (L <= kBone) continue;
                    const int k = L - kBone - 1;
                    if (inner_row && x > 0 && x < nx - 1 && row[x - 1] == L && row[x + 1] == L && row[x - sy] == L &&
                        row[x + sy] == L && row[x - sz] == L && row[x + sz] == L) {
                        ++t_inner[size_t(k)];
                        continue;
                    }
                    t_voxels[k] += 1;
                    for (const auto& o : off) {
                        const int64_t qx = x + o[0], qy = y + o[1], qz = z + o[2];
                        if (qx < 0 || qy < 0 || qz < 0 || qx >= nx || qy >= ny || qz >= nz) {
                            t_faces[k] += 1;
                            t_border[k] += 1;
                            continue;
                        }
                        const size_t j = flood.index(qx, qy, qz);
                        const int M = flood[j];
                        if (M == L) continue;
                        t_faces[k] += 1;
                        if (M == kBone) t_bone[k] += 1;
                        // labels holds the border seeds: a ball voxel off the border.
                        if (M == kOther && labels[j] == kOther && qx > 0 && qy > 0 && qz > 0 &&
                            qx < nx - 1 && qy < ny - 1 && qz < nz - 1)
                            t_ball[k] += 1;
                        if (M > kBone) {
                            const size_t pk = size_t(k) * K + size_t(M - kBone - 1);
                            t_pair[pk] += 1;
                            t_pass[pk] = std::max(t_pass[pk], double(std::min(distance[i], distance[j])));
                        }
                    }
                }
            }
        for (int k = 0; k < K; ++k) t_voxels[k] += double(t_inner[size_t(k)]);
#pragma omp critical(seeds_region_stats)
        {
            for (int k = 0; k < K; ++k) {
                st.voxels[k] += t_voxels[k];
                st.faces[k] += t_faces[k];
                st.bone_faces[k] += t_bone[k];
                st.ball_faces[k] += t_ball[k];
                st.border_faces[k] += t_border[k];
            }
            for (size_t q = 0; q < t_pair.size(); ++q) {
                st.pair_faces[q] += t_pair[q];
                st.pass[q] = std::max(st.pass[q], t_pass[q]);
            }
        }
    }
    return st;
}

// Merges the regions of one cavity (shallow saddle between them); returns each region's parent
// (find_root gives its group). b (the shallower of a pair; candidates are sorted deepest first)
// joins a's cavity only if b's group is itself enclosed by bone apart from the faces it shares with
// other candidates' regions (watershed boundaries within the empty space, not its walls): a lobe
// of a braincase is (also a basin between two merged lobes, or the junction between the cerebrum
// and a rodent's olfactory bulbs, whose faces toward both are shared); the neck or a canal below a
// foramen is not. Faces on the volume border do not count: a lobe the border cuts (a middle fossa
// of a scan cropped through the skull base) is still a lobe. Repeated until no group changes.
std::vector<int> merge_lobes(const RegionStats& st, const Volume<float>& distance, const std::vector<size_t>& centres,
                             const SeedParams& p) {
    const int K = int(centres.size());
    std::vector<int> parent(K);
    for (int k = 0; k < K; ++k) parent[k] = k;
    for (bool changed = true; changed;) {
        changed = false;
        for (int a = 0; a < K; ++a)
            for (int b = a + 1; b < K; ++b) {
                const int ra = find_root(parent, a), rb = find_root(parent, b);
                if (ra == rb) continue;
                const double ps = std::max(st.pass[size_t(a) * K + b], st.pass[size_t(b) * K + a]);
                const double shallow = std::min(distance[centres[a]], distance[centres[b]]);
                if (!(ps > 0 && ps >= p.merge_pass * shallow)) continue;
                double own = 0, bone = 0;
                for (int m = 0; m < K; ++m) {
                    if (find_root(parent, m) != rb) continue;
                    own += st.faces[m] - st.border_faces[m];
                    bone += st.bone_faces[m];
                    for (int n = 0; n < K; ++n) own -= st.pair_faces[size_t(m) * K + n];
                }
                if (own > 0 && bone / own >= p.merge_enclosure) {
                    parent[std::max(ra, rb)] = std::min(ra, rb);
                    changed = true;
                }
            }
    }
    return parent;
}

// Each candidate's group scored (enclosure^4 x volume); the best group's balls become the
// endocast seeds, the other centres "other"; a warning when the runner-up scores over half as much.
void score_and_seed(SeedResult& r, const Volume<float>& distance, const SeedParams& p, const std::vector<size_t>& centres,
                    const RegionStats& st, std::vector<int>& parent) {
    const Geometry& g = r.labels.geometry();
    const int K = int(centres.size());
    std::vector<double> gvox(K, 0), gfaces(K, 0), gbone(K, 0), gball(K, 0);
    for (int k = 0; k < K; ++k) {
        const int root = find_root(parent, k);
        gvox[root] += st.voxels[k];
        gfaces[root] += st.faces[k];
        gbone[root] += st.bone_faces[k];
        gball[root] += st.ball_faces[k];
        for (int m = 0; m < K; ++m)
            if (m != k && find_root(parent, m) == root) gfaces[root] -= st.pair_faces[size_t(k) * K + m];
    }
    r.candidates.resize(K);
    int best = -1, second = -1;
    for (int k = 0; k < K; ++k) {
        const int root = find_root(parent, k);
        CavityCandidate& c = r.candidates[k];
        const auto cc = coords(g, centres[k]);
        c.centre_world = g.index_to_world(double(cc[0]), double(cc[1]), double(cc[2]));
        c.depth_mm = distance[centres[k]];
        c.volume_ml = gvox[root] * g.voxel_volume_mm3() / 1000.0;
        c.enclosure = gfaces[root] > 0 ? gbone[root] / gfaces[root] : 0.0;
        c.score = std::pow(c.enclosure, 4) * c.volume_ml;
        c.border_ball_share = gfaces[root] > 0 ? gball[root] / gfaces[root] : 0.0;
        c.merged_into = root == k ? -1 : root;
        if (root != k) continue;
        if (best < 0 || c.score > r.candidates[best].score) {
            second = best;
            best = k;
        } else if (second < 0 || c.score > r.candidates[second].score) {
            second = k;
        }
    }
    for (int k = 0; k < K; ++k) {
        const bool chosen = find_root(parent, k) == best;
        r.candidates[k].chosen = chosen;
        const auto cc = coords(g, centres[k]);
        const double radius = p.scale * distance[centres[k]];
        if (chosen) {
            r.endocast_seed_voxels += ball_seed(r.labels, cc, radius, false, kEndocast);
            r.endocast_seeds_world.push_back(r.candidates[k].centre_world);
            r.endocast_seed_radii_mm.push_back(radius);
        } else if (r.labels[centres[k]] == kUnlabelled) {
            // Only the centre: a rejected candidate often sits in an opening of the braincase
            // (depth = the opening's radius), where a ball would reach into the cavity.
            r.labels[centres[k]] = kOther;
        }
    }
    r.endocast_seed_distance_mm = distance[centres[best]];
    if (second >= 0 && r.candidates[second].score > 0.5 * r.candidates[best].score) {
        std::ostringstream w;
        w << "the cavity choice is close: the chosen cavity (" << r.candidates[best].volume_ml
          << " mL, enclosure " << r.candidates[best].enclosure << ", score "
          << r.candidates[best].score << ") and the runner-up (" << r.candidates[second].volume_ml
          << " mL, enclosure " << r.candidates[second].enclosure << ", score "
          << r.candidates[second].score << ", centre " << r.candidates[second].centre_world[0]
          << " " << r.candidates[second].centre_world[1] << " "
          << r.candidates[second].centre_world[2] << " mm); check the result or give --seed-point";
        r.warnings.push_back({"cavity_choice_close", w.str(),
                              {{"chosen_score", r.candidates[best].score},
                               {"runner_up_score", r.candidates[second].score},
                               {"runner_up_volume_ml", r.candidates[second].volume_ml}}});
    }
}

// The candidate flood made the start of the watershed of the seeds chosen (SeedResult::flood): the
// chosen candidates' regions kEndocast, the others' kUnlabelled, every seed of r.labels set at its
// own level (the flood gave it its label or one taken away; else none: the voxel is claimed by a
// kept region, and the watershed floods the seeds from scratch).
std::optional<SeedResult::ResumableFlood> resumable_flood(Volume<uint8_t>&& flood, FloodLevels&& levels,
                                                          const SeedResult& r, const Volume<float>& distance) {
    std::array<uint8_t, 256> map{};
    for (size_t l = 0; l < map.size(); ++l) map[l] = uint8_t(l);
    for (size_t k = 0; k < r.candidates.size(); ++k)
        map[kBone + 1 + k] = r.candidates[k].chosen ? kEndocast : kUnlabelled;
    const int64_t n = int64_t(flood.size());
    uint8_t* f = flood.data();
    const uint8_t* seeds = r.labels.data();
    uint16_t* level = levels.level.data();
    const double quantum = levels.quantum_mm;
    const size_t count = levels.levels;
    int agree = 1;
#pragma omp parallel for schedule(static) reduction(& : agree)
    for (int64_t i = 0; i < n; ++i) {
        const uint8_t m = map[f[i]], s = seeds[i];
        if (s == kEndocast || s == kOther) {
            agree &= int(m == s || m == kUnlabelled);
            f[i] = s;
            level[i] = uint16_t(flood_level(distance[i], quantum, count));
        } else {
            f[i] = m;
        }
    }
    if (!agree) return std::nullopt;
    return SeedResult::ResumableFlood{std::move(flood), std::move(levels)};
}

void choose_cavity(SeedResult& r, const Volume<float>& distance, const SeedParams& p) {
    const Geometry& g = r.labels.geometry();
    const std::vector<size_t> centres = candidate_centres(r, distance, p);
    const int K = int(centres.size());
    // One flood with a label per candidate.
    Volume<uint8_t> flood = r.labels;
    for (int k = 0; k < K; ++k)
        ball_seed(flood, coords(g, centres[k]), p.scale * distance[centres[k]], false,
                  uint8_t(kBone + 1 + k));
    FloodLevels levels;
    flood = p.keep_flood ? watershed(std::move(flood), distance, WatershedParams{}, levels).labels
                         : watershed(std::move(flood), distance).labels;  // flooded in the seeds' memory
    const RegionStats st = region_stats(flood, r.labels, distance, K);
    std::vector<int> parent = merge_lobes(st, distance, centres, p);
    score_and_seed(r, distance, p, centres, st, parent);
    if (p.keep_flood && !levels.empty()) r.flood = resumable_flood(std::move(flood), std::move(levels), r, distance);
}

}  // namespace

std::string to_string(SeedMode m) {
    switch (m) {
        case SeedMode::Auto: return "auto";
        case SeedMode::AutoLargest: return "auto-largest";
        case SeedMode::Distance: return "distance";
        case SeedMode::Point: return "point";
    }
    return "?";
}

namespace {

// The paper's alternative for small braincases: the component of the empty space at least
// distance_threshold_mm from bone that is enclosed away from the border is the endocast seed, those
// touching the border "other".
void seed_by_distance(SeedResult& r, const Volume<uint8_t>& bone, const Volume<float>& distance, const SeedParams& p) {
    const Geometry& g = bone.geometry();
    if (!(p.distance_threshold_mm > 0) || !std::isfinite(p.distance_threshold_mm))
        throw InvalidParameter("distance threshold " + fmt(p.distance_threshold_mm) +
                               " mm, expected > 0 (use --distance-threshold MM)");
    Volume<uint8_t> above(g);
    for (size_t i = 0; i < above.size(); ++i)
        above[i] = (!bone[i] && distance[i] >= p.distance_threshold_mm) ? 1 : 0;
    const Components comp = connected_components(above, Connectivity::Face6);
    size_t best = 0, best_size = 0;
    for (size_t k = 0; k < comp.sizes.size(); ++k)
        if (!comp.touches_border[k] && comp.sizes[k] > best_size) {
            best = k + 1;
            best_size = comp.sizes[k];
        }
    if (best == 0)
        throw NoResult("no empty region with distance >= " + fmt(p.distance_threshold_mm) +
                       " mm is enclosed away from the volume border: expected the braincase; "
                       "try a smaller --distance-threshold");
    size_t centre = 0;
    float dmax = -1;
    for (size_t i = 0; i < above.size(); ++i) {
        const uint32_t l = comp.labels[i];
        if (!l) continue;
        if (l == best) {
            r.labels[i] = kEndocast;
            ++r.endocast_seed_voxels;
            if (distance[i] > dmax) {
                dmax = distance[i];
                centre = i;
            }
        } else if (comp.touches_border[l - 1]) {
            r.labels[i] = kOther;
            ++r.other_seed_voxels;
        }
    }
    // Border voxels are always "other": a flood must have somewhere to come from outside.
    r.other_seed_voxels += border_seeds(r.labels, distance, p.border_scale >= 0 ? p.border_scale : p.scale, p);
    const auto c = coords(g, centre);
    r.endocast_seeds_world.push_back(g.index_to_world(double(c[0]), double(c[1]), double(c[2])));
    r.endocast_seed_radii_mm.push_back(dmax);
    r.endocast_seed_distance_mm = dmax;
}

// Candidate cavities (choose_cavity) with border balls of border_scale; retried with the border
// voxels alone as seeds when the chosen cavity faces the border balls too much, or when the
// border cuts a section of it (SeedParams::border_retry_section_share).
void seed_automatic(SeedResult& r, const Volume<uint8_t>& bone, const Volume<float>& distance, const SeedParams& p,
                    double border_scale) {
    // The border balls can eat into a cavity cut by the volume border (a scan that stops at
    // the skull base): the chosen cavity then faces "other" over much of its boundary. Then
    // try again with the border voxels alone as seeds, and keep that when it finds the same
    // cavity better enclosed.
    const bool may_retry = p.border_scale < 0 && p.border_retry_enclosure > 0 && border_scale > 0;
    const double section_mm2 = may_retry ? largest_ringed_section_mm2(r.labels) : 0.0;
    r.other_seed_voxels = border_seeds(r.labels, distance, border_scale, p);
    choose_cavity(r, distance, p);
    auto chosen = [](const SeedResult& s) -> const CavityCandidate* {
        for (const auto& c : s.candidates)
            if (c.chosen) return &c;
        return nullptr;
    };
    const CavityCandidate* c1 = chosen(r);
    // The cross-section of a ball of the chosen cavity's volume: a section of the cavity the
    // border cuts is a good part of it; a canal's (the foramen magnum's where a scan stops at it) is not.
    const double ball_section_mm2 =
        c1 ? M_PI * std::pow(3.0 * c1->volume_ml * 1000.0 / (4.0 * M_PI), 2.0 / 3.0) : 0.0;
    const bool cut = c1 && p.border_retry_section_share > 0 && section_mm2 >= p.border_retry_section_share * ball_section_mm2;
    if (may_retry && c1 && (cut || c1->enclosure < p.border_retry_enclosure || c1->border_ball_share > p.border_retry_ball_share)) {
        // The first choice's flood is released before the retry floods (one at a time in memory):
        // kept, the first choice is flooded from scratch.
        r.flood.reset();
        SeedResult retry;
        retry.labels = unseeded_labels(bone);
        open_border_seeds(retry.labels);
        retry.border_scale = 0.0;
        choose_cavity(retry, distance, p);
        const CavityCandidate* c2 = chosen(retry);
        // The same cavity (centres closer than its depth), not worse enclosed (a dent's faces
        // and the flat cut's are both off bone: the enclosure hardly moves; a leak through the
        // border would lower it far more).
        const bool same = c2 && c2->enclosure >= c1->enclosure - p.border_retry_enclosure_slack &&
                          std::hypot(c2->centre_world[0] - c1->centre_world[0], c2->centre_world[1] - c1->centre_world[1],
                                     c2->centre_world[2] - c1->centre_world[2]) < c1->depth_mm;
        if (same) {
            // Said only when the border balls ate a good part of the cavity: in a tight field of
            // view (a mouse's head in a microCT) a ball may graze it through thin bone.
            if (c2->volume_ml > (1.0 + p.border_retry_warn_growth) * c1->volume_ml)
                retry.warnings.push_back(
                    {"border_seeds_retried",
                     "the chosen cavity faced the volume border over " + fmt(100 * (1 - c1->enclosure)) +
                         " % of its boundary with border seed balls of scale " + fmt(border_scale) +
                         ": seeded the border voxels alone instead (enclosure " + fmt(c2->enclosure) +
                         "); is the scan cropped through the braincase?",
                     {{"enclosure_before", c1->enclosure}, {"enclosure", c2->enclosure},
                      {"border_seed_scale", border_scale}}});
            r = std::move(retry);
        } else if (cut && c2 && c2->score > c1->score && c2->enclosure >= p.border_retry_min_enclosure) {
            retry.warnings.push_back(
                {"border_section_retried",
                 "the volume border cuts a section of " + fmt(section_mm2) +
                     " mm^2 ringed by bone, and its border seed balls of scale " + fmt(border_scale) +
                     " left a part of the cavity (" + fmt(c1->volume_ml) + " mL, enclosure " + fmt(c1->enclosure) +
                     "): seeded the border voxels alone instead (" + fmt(c2->volume_ml) + " mL, enclosure " +
                     fmt(c2->enclosure) + "); is the scan cropped through the braincase?",
                 {{"section_mm2", section_mm2}, {"volume_before_ml", c1->volume_ml}, {"volume_ml", c2->volume_ml}}});
            r = std::move(retry);
        }
    }
    r.other_seed_voxels = count_label(r.labels, kOther);
}

// The endocast ball centres of the paper's rule (the deepest empty voxel) or the user's points.
std::vector<size_t> rule_or_point_centres(const SeedResult& r, const Volume<uint8_t>& bone, const Volume<float>& distance,
                                          const SeedParams& p) {
    const Geometry& g = bone.geometry();
    std::vector<size_t> centres;
    if (p.mode == SeedMode::AutoLargest) {
        size_t best = size_t(-1);
        float dmax = 0;
        for (size_t i = 0; i < bone.size(); ++i)
            if (r.labels[i] == kUnlabelled && distance[i] > dmax) {
                dmax = distance[i];
                best = i;
            }
        if (best == size_t(-1))
            throw NoResult("no empty space is left away from the volume border once the border "
                           "seeds are placed: expected an enclosed braincase (is the skull open "
                           "to the border, or the isovalue too high?)");
        centres.push_back(best);
    } else {
        if (p.points_world.empty())
            throw InvalidParameter("seed mode point needs at least one --seed-point X Y Z (mm)");
        for (const Vec3& w : p.points_world) {
            const Vec3 idx = g.world_to_index(w);
            std::array<int64_t, 3> c{};
            for (int a = 0; a < 3; ++a) c[a] = std::llround(idx[a]);
            if (!bone.contains(c[0], c[1], c[2]))
                throw InvalidParameter("seed point (" + fmt(w[0]) + ", " + fmt(w[1]) + ", " +
                                       fmt(w[2]) + ") mm lies outside the volume (index " +
                                       fmt(idx[0]) + ", " + fmt(idx[1]) + ", " + fmt(idx[2]) + ")");
            const size_t i = bone.index(c[0], c[1], c[2]);
            if (bone[i])
                throw InvalidParameter("seed point (" + fmt(w[0]) + ", " + fmt(w[1]) + ", " +
                                       fmt(w[2]) + ") mm lies in bone: expected a point inside "
                                       "the braincase");
            centres.push_back(i);
        }
    }
    return centres;
}

}  // namespace

SeedResult place_seeds(const Volume<uint8_t>& bone, const Volume<float>& distance,
                       const SeedParams& p) {
    if (!(p.scale > 0 && p.scale < 1))
        throw InvalidParameter("seed scale " + fmt(p.scale) + ", expected 0 < s < 1");
    if (bone.size() != distance.size())
        throw InvalidParameter("place_seeds: bone and distance volumes differ in size");
    const Geometry& g = bone.geometry();
    SeedResult r;
    r.labels = unseeded_labels(bone);
    if (p.mode == SeedMode::Distance) {
        seed_by_distance(r, bone, distance, p);
        return r;
    }
    const double border_scale = p.border_scale >= 0 ? p.border_scale : p.scale;
    r.border_scale = border_scale;
    if (p.mode == SeedMode::Auto) {
        seed_automatic(r, bone, distance, p, border_scale);
        return r;
    }
    r.other_seed_voxels = border_seeds(r.labels, distance, border_scale, p);
    const std::vector<size_t> centres = rule_or_point_centres(r, bone, distance, p);
    for (size_t i : centres) {
        const auto c = coords(g, i);
        const double radius = p.scale * distance[i];
        // A user's point wins over the border rule; the automatic centre never overlaps it.
        const bool override_other = p.mode == SeedMode::Point;
        r.endocast_seed_voxels += ball_seed(r.labels, c, radius, override_other);
        r.endocast_seeds_world.push_back(g.index_to_world(double(c[0]), double(c[1]), double(c[2])));
        r.endocast_seed_radii_mm.push_back(radius);
    }
    r.endocast_seed_distance_mm = distance[centres.front()];
    r.other_seed_voxels = count_label(r.labels, kOther);
    if (r.endocast_seed_voxels == 0) throw NoResult("the endocast seed is empty");
    return r;
}

}  // namespace endocast
