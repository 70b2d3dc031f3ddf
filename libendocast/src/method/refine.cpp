// The coarse-to-fine path: the coarse region's band decided again by the full-resolution CT, slab
// by slab, and meshed as it goes (refine.h).
#include "refine.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "endocast/errors.h"
#include "endocast/stages/marching_cubes.h"
#include "kernels/max_filter.h"

namespace endocast {
namespace {

// Marks the voxels within `k` voxels (box distance) of a marked voxel.
void dilate_box(Volume<uint8_t>& m, int k) {
    for (int a = 0; a < 3; ++a) max_filter_axis(m, a, k);
}

// Keeps the mesh's largest edge-connected piece (by faces; vertices shared by faces join them);
// returns how many pieces were dropped. The kept faces and vertices keep their order.
size_t keep_largest_piece(meshpost::TriangleMesh& m) {
    std::vector<uint32_t> parent(m.vertices.size());
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](uint32_t v) {
        while (parent[v] != v) v = parent[v] = parent[parent[v]];
        return v;
    };
    for (const auto& f : m.faces)
        for (int k = 1; k < 3; ++k) {
            const uint32_t a = find(f[0]), b = find(f[size_t(k)]);
            if (a != b) parent[std::max(a, b)] = std::min(a, b);
        }
    std::vector<size_t> faces_of(m.vertices.size(), 0);
    for (const auto& f : m.faces) ++faces_of[find(f[0])];
    size_t pieces = 0, best = 0;
    for (size_t v = 0; v < faces_of.size(); ++v) {
        if (!faces_of[v]) continue;
        ++pieces;
        if (faces_of[v] > faces_of[best]) best = v;
    }
    if (pieces <= 1) return 0;
    std::vector<uint32_t> index(m.vertices.size(), UINT32_MAX);
    std::vector<meshpost::Point> vertices;
    for (size_t v = 0; v < m.vertices.size(); ++v)
        if (find(uint32_t(v)) == best) {
            index[v] = uint32_t(vertices.size());
            vertices.push_back(m.vertices[v]);
        }
    std::vector<meshpost::Face> faces;
    for (const auto& f : m.faces)
        if (find(f[0]) == best) faces.push_back({index[f[0]], index[f[1]], index[f[2]]});
    m.vertices = std::move(vertices);
    m.faces = std::move(faces);
    return pieces - 1;
}

// The crossings of the coarse mesh with the fine grid's rows (lines along x at integer y, z; fine
// index coordinates), for inside tests by parity. Triangles are bucketed by the rows they span.
class RowCrossings {
public:
    RowCrossings(const meshpost::TriangleMesh& m, const Geometry& fine, const Dims& rows_box_lo, const Dims& rows_box_hi)
        : lo_y_(rows_box_lo[1]), lo_z_(rows_box_lo[2]), ny_(rows_box_hi[1] - rows_box_lo[1]),
          nz_(rows_box_hi[2] - rows_box_lo[2]) {
        pos_.reserve(m.vertices.size());
        for (const auto& v : m.vertices) pos_.push_back(fine.world_to_index({v[0], v[1], v[2]}));
        // Buckets of (ny_ x nz_) rows, 8 x 8 rows each.
        by_ = (ny_ + 7) / 8;
        bz_ = (nz_ + 7) / 8;
        buckets_.resize(size_t(std::max<int64_t>(0, by_ * bz_)));
        for (size_t f = 0; f < m.faces.size(); ++f) {
            double y0 = 1e300, y1 = -1e300, z0 = 1e300, z1 = -1e300;
            for (uint32_t v : m.faces[f]) {
                y0 = std::min(y0, pos_[v][1]), y1 = std::max(y1, pos_[v][1]);
                z0 = std::min(z0, pos_[v][2]), z1 = std::max(z1, pos_[v][2]);
            }
            const int64_t a0 = std::max<int64_t>(0, (int64_t(std::floor(y0)) - lo_y_) / 8);
            const int64_t a1 = std::min<int64_t>(by_ - 1, (int64_t(std::ceil(y1)) - lo_y_) / 8);
            const int64_t b0 = std::max<int64_t>(0, (int64_t(std::floor(z0)) - lo_z_) / 8);
            const int64_t b1 = std::min<int64_t>(bz_ - 1, (int64_t(std::ceil(z1)) - lo_z_) / 8);
            if (int64_t(std::ceil(y1)) < lo_y_ || int64_t(std::ceil(z1)) < lo_z_) continue;
            for (int64_t b = b0; b <= b1; ++b)
                for (int64_t a = a0; a <= a1; ++a) buckets_[size_t(a + by_ * b)].push_back(m.faces[f]);
        }
    }

    // Sorted x of the crossings of the row (y, z) (fine indices), the row nudged off the grid so
    // that it never meets an edge or a corner of the mesh.
    void crossings(int64_t y, int64_t z, std::vector<double>& xs) const {
        xs.clear();
        const int64_t a = (y - lo_y_) / 8, b = (z - lo_z_) / 8;
        if (y < lo_y_ || z < lo_z_ || a >= by_ || b >= bz_) return;
        const double py = double(y) + 1.234567e-6, pz = double(z) + 2.345678e-6;
        for (const meshpost::Face& f : buckets_[size_t(a + by_ * b)]) {
            const Vec3& p0 = pos_[f[0]];
            const Vec3& p1 = pos_[f[1]];
            const Vec3& p2 = pos_[f[2]];
            // Barycentric coordinates of (py, pz) in the triangle's projection on (y, z).
            const double d = (p1[1] - p0[1]) * (p2[2] - p0[2]) - (p2[1] - p0[1]) * (p1[2] - p0[2]);
            if (d == 0) continue;
            const double u = ((py - p0[1]) * (p2[2] - p0[2]) - (p2[1] - p0[1]) * (pz - p0[2])) / d;
            const double v = ((p1[1] - p0[1]) * (pz - p0[2]) - (py - p0[1]) * (p1[2] - p0[2])) / d;
            if (u < 0 || v < 0 || u + v > 1) continue;
            xs.push_back(p0[0] + u * (p1[0] - p0[0]) + v * (p2[0] - p0[0]));
        }
        std::sort(xs.begin(), xs.end());
    }

private:
    std::vector<Vec3> pos_;
    int64_t lo_y_, lo_z_, ny_, nz_, by_ = 0, bz_ = 0;
    std::vector<std::vector<meshpost::Face>> buckets_;
};

}  // namespace

Volume<uint8_t> refine_classes(const Volume<uint8_t>& region, const Volume<uint8_t>& labels, const Volume<float>& ct,
                               double T, const meshpost::TriangleMesh& mesh, const std::vector<uint8_t>& face_on_bone,
                               int k) {
    if (region.dims() != labels.dims() || region.dims() != ct.dims())
        throw InvalidParameter("refine_classes: the region, labels and CT differ in size");
    if (face_on_bone.size() != mesh.faces.size())
        throw InvalidParameter("refine_classes: " + std::to_string(face_on_bone.size()) + " face flags for " +
                               std::to_string(mesh.faces.size()) + " faces");
    if (k < 1) throw InvalidParameter("refine_classes: band of " + std::to_string(k) + " coarse voxels, expected >= 1");
    const Dims& d = region.dims();
    // Near the boundary: within k of a voxel whose region value differs from a face neighbour's.
    Volume<uint8_t> near(region.geometry(), 0);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x) {
                const bool v = region(x, y, z) != 0;
                const int64_t q[6][3] = {{x - 1, y, z}, {x + 1, y, z}, {x, y - 1, z},
                                         {x, y + 1, z}, {x, y, z - 1}, {x, y, z + 1}};
                for (const auto& n : q)
                    if (region.contains(n[0], n[1], n[2]) && (region(n[0], n[1], n[2]) != 0) != v) {
                        near(x, y, z) = 1;
                        break;
                    }
            }
    Volume<uint8_t> touch(region.geometry());  // next to the region (26-neighbours)
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(touch.size()); ++i) touch[size_t(i)] = region[size_t(i)] != 0;
    dilate_box(touch, 1);
    dilate_box(near, k);
    Volume<uint8_t> cls(region.geometry());
    const float t = static_cast<float>(T);
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(cls.size()); ++i) {
        const size_t j = size_t(i);
        if (region[j]) cls[j] = near[j] ? kRefineBandIn : kRefineCore;
        else cls[j] = touch[j] && labels[j] == kBone && ct[j] >= t ? kRefineBandBone : kRefineOut;
    }
    // Within a voxel of a closing face's corners.
    Volume<uint8_t> clip(region.geometry(), 0);
    const Geometry& g = region.geometry();
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
        if (face_on_bone[f]) continue;
        for (uint32_t v : mesh.faces[f]) {
            const auto& w = mesh.vertices[v];
            const Vec3 q = g.world_to_index({w[0], w[1], w[2]});
            const int64_t x = std::llround(q[0]), y = std::llround(q[1]), z = std::llround(q[2]);
            if (clip.contains(x, y, z)) clip(x, y, z) = 1;
        }
    }
    dilate_box(clip, 1);
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(cls.size()); ++i) {
        uint8_t& c = cls[size_t(i)];
        if (clip[size_t(i)] && (c == kRefineBandIn || c == kRefineBandBone)) c |= kRefineClip;
    }
    return cls;
}

RefineResult refine_full_resolution(const Geometry& fine, const PlaneReader& read, const Volume<uint8_t>& classes,
                                    int factor, const RefineParams& p) {
    const Geometry coarse = downsampled_geometry(fine, factor);
    if (coarse.dims != classes.dims())
        throw InvalidParameter("refine: the coarse classes have " + std::to_string(classes.nx()) + " x " +
                               std::to_string(classes.ny()) + " x " + std::to_string(classes.nz()) +
                               " voxels, expected " + std::to_string(coarse.dims[0]) + " x " +
                               std::to_string(coarse.dims[1]) + " x " + std::to_string(coarse.dims[2]) +
                               " (the fine grid downsampled by " + std::to_string(factor) + ")");
    if (!std::isfinite(p.isovalue) || !std::isfinite(p.other_value) || !(p.other_value > p.isovalue))
        throw InvalidParameter("refine: isovalue " + std::to_string(p.isovalue) + " and other value " +
                               std::to_string(p.other_value) + ", expected finite values, the second above the first");
    if (p.slab_planes < 1)
        throw InvalidParameter("refine: slabs of " + std::to_string(p.slab_planes) + " planes, expected >= 1");
    const int64_t F = factor;

    // The box: the coarse voxels of the core and the band, on the fine grid, and a voxel more.
    const Dims& cd = classes.dims();
    int64_t lo[3] = {cd[0], cd[1], cd[2]}, hi[3] = {-1, -1, -1};
    for (int64_t z = 0; z < cd[2]; ++z)
        for (int64_t y = 0; y < cd[1]; ++y)
            for (int64_t x = 0; x < cd[0]; ++x)
                if (classes(x, y, z) != kRefineOut) {
                    const int64_t q[3] = {x, y, z};
                    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], q[a]), hi[a] = std::max(hi[a], q[a]);
                }
    if (hi[0] < 0) throw NoResult("refine: the coarse region is empty");
    RefineResult out;
    for (int a = 0; a < 3; ++a) {
        out.box.lo[a] = std::max<int64_t>(0, lo[a] * F - 1);
        out.box.hi[a] = std::min<int64_t>(fine.dims[a], (hi[a] + 1) * F + 1);
    }
    const Geometry boxg = cropped_geometry(fine, out.box);
    const Dims bd = boxg.dims;
    const int64_t plane = bd[0] * bd[1];

    const float T = static_cast<float>(p.isovalue);
    const double floor_contrast = 1e-3 * std::max(1.0, std::fabs(p.isovalue));
    const float high = static_cast<float>(p.other_value);
    const float low = static_cast<float>(p.isovalue - floor_contrast);
    const float just_above = static_cast<float>(p.isovalue + floor_contrast);

    // A bone voxel of the band averages >= T over its block: its empty part is the half next to the
    // region, where the wall runs through it. Its fine voxels are candidates within ceil(F / 2)
    // voxels (box distance) of a region voxel's block.
    const int64_t reach = (F + 1) / 2;
    auto near_region = [&](int64_t x, int64_t y, int64_t z) {  // fine indices
        const int64_t c[3] = {x / F, y / F, z / F}, o[3] = {x % F, y % F, z % F};
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int64_t q[3] = {c[0] + dx, c[1] + dy, c[2] + dz};
                    if (!classes.contains(q[0], q[1], q[2])) continue;
                    const uint8_t k = classes(q[0], q[1], q[2]);
                    const uint8_t kc = k & uint8_t(~kRefineClip);
                    if (kc != kRefineCore && kc != kRefineBandIn) continue;
                    const int d[3] = {dx, dy, dz};
                    int64_t far = 0;  // fine voxels to that block along the farthest axis
                    for (int a = 0; a < 3; ++a)
                        far = std::max(far, d[a] < 0 ? o[a] + 1 : (d[a] > 0 ? F - o[a] : int64_t(0)));
                    if (far <= reach) return true;
                }
        return false;
    };

    // Coarse rows holding kRefineClip voxels, and the coarse mesh's crossings for their fine rows.
    std::vector<uint8_t> clip_row(size_t(cd[1] * cd[2]), 0);
    for (int64_t z = 0; z < cd[2]; ++z)
        for (int64_t y = 0; y < cd[1]; ++y)
            for (int64_t x = 0; x < cd[0]; ++x)
                if (classes(x, y, z) & kRefineClip) clip_row[size_t(y + cd[1] * z)] = 1;
    const bool clipping = std::any_of(clip_row.begin(), clip_row.end(), [](uint8_t c) { return c != 0; });
    if (clipping && !p.clip_mesh) throw InvalidParameter("refine: the classes clip by the coarse mesh, none given");
    std::optional<RowCrossings> rows;
    if (clipping) rows.emplace(*p.clip_mesh, fine, out.box.lo, out.box.hi);

    IsosurfaceStream stream(boxg, p.isovalue);
    std::vector<float> whole(size_t(fine.dims[0] * fine.dims[1]));
    std::vector<float> last_plane;  // the previous slab's last plane of the field
    const int64_t S = p.slab_planes;
    for (int64_t z0 = 0; z0 < bd[2]; z0 += S) {
        const int64_t z1 = std::min(bd[2], z0 + S);
        // The field of planes [f0, z1): the previous slab's last plane, then this slab's.
        const int64_t f0 = z0 == 0 ? 0 : z0 - 1;
        Geometry fg = boxg;
        fg.dims[2] = z1 - f0;
        Volume<float> field(fg);
        if (z0 > 0) std::copy(last_plane.begin(), last_plane.end(), field.data());
        size_t band = 0, band_in = 0, changed = 0, region = 0, clipped = 0;
        for (int64_t z = z0; z < z1; ++z) {
            const int64_t gz = z + out.box.lo[2];
            read(gz, whole.data());
            float* dst = &field(0, 0, z - f0);
#pragma omp parallel for schedule(static) reduction(+ : band, band_in, changed, region, clipped)
            for (int64_t y = 0; y < bd[1]; ++y) {
                const int64_t gy = y + out.box.lo[1];
                const float* row = whole.data() + size_t(gy * fine.dims[0] + out.box.lo[0]);
                const uint8_t* crow = &classes(0, gy / F, gz / F);
                std::vector<double> xs;
                size_t next = 0;  // crossings before the current voxel
                if (rows && clip_row[size_t(gy / F + cd[1] * (gz / F))]) rows->crossings(gy, gz, xs);
                for (int64_t x = 0; x < bd[0]; ++x) {
                    const int64_t gx = x + out.box.lo[0];
                    while (next < xs.size() && xs[next] < double(gx)) ++next;
                    const uint8_t cf = crow[gx / F];
                    const uint8_t c = cf & uint8_t(~kRefineClip);
                    const float v = row[x];
                    bool in = c == kRefineCore;
                    if (c == kRefineBandIn || (c == kRefineBandBone && near_region(gx, gy, gz))) {
                        in = v < T;
                        if (in && (cf & kRefineClip) && next % 2 == 0) {  // outside the coarse mesh
                            in = false;
                            ++clipped;
                        }
                        ++band;
                        band_in += in;
                        changed += in != (c == kRefineBandIn);
                    }
                    region += in;
                    dst[y * bd[0] + x] = in ? std::min(v, low) : (v >= T ? std::max(v, just_above) : high);
                }
            }
        }
        out.band_voxels += band;
        out.band_endocast_voxels += band_in;
        out.changed_voxels += changed;
        out.clipped_voxels += clipped;
        out.region_voxels += region;
        last_plane.assign(&field(0, 0, fg.dims[2] - 1), &field(0, 0, fg.dims[2] - 1) + plane);
        stream.add(field, f0, z1 == bd[2] ? bd[2] : z1 - 1);
        ++out.slabs;
        if (p.progress) p.progress(z1, bd[2]);
    }
    if (out.region_voxels == 0) throw NoResult("refine: no fine voxel is endocast");
    out.mesh = stream.finish();
    out.pieces_removed = keep_largest_piece(out.mesh);
    out.region_volume_ml = double(out.region_voxels) * fine.voxel_volume_mm3() / 1000.0;
    return out;
}

}  // namespace endocast
