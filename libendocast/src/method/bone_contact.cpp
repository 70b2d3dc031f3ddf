// Bone contact (see bone_contact.h): each face's centroid moved offset_mm along its outward unit
// normal, the CT interpolated trilinearly there (continuous index from Geometry::world_to_index,
// so any origin, spacing and orthonormal direction), compared with the isovalue. Faces are
// processed in fixed chunks; each chunk sums its areas in face order and the chunk sums are added
// in chunk order, so the result does not depend on how OpenMP shares the chunks out.
#include "endocast/stages/bone_contact.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "endocast/errors.h"
#include "meshpost/patches.h"

namespace endocast {
namespace {

constexpr int64_t kChunkFaces = 8192;

/// The CT at continuous index q (trilinear between voxel centres); false when q lies outside the
/// box of voxel centres [0, n-1] along any axis (or the volume is empty).
template <class T>
bool sample(const Volume<T>& ct, const Vec3& q, double& value) {
    int64_t i0[3];
    double t[3];
    for (int a = 0; a < 3; ++a) {
        const int64_t n = ct.dims()[size_t(a)];
        if (!(q[size_t(a)] >= 0.0) || q[size_t(a)] > double(n - 1)) return false;  // NaN too
        const int64_t i = std::min<int64_t>(int64_t(q[size_t(a)]), std::max<int64_t>(n - 2, 0));
        i0[a] = i;
        t[a] = n > 1 ? q[size_t(a)] - double(i) : 0.0;
    }
    const int64_t x1 = std::min(i0[0] + 1, ct.nx() - 1), y1 = std::min(i0[1] + 1, ct.ny() - 1),
                  z1 = std::min(i0[2] + 1, ct.nz() - 1);
    auto lerp = [](double a, double b, double s) { return a + (b - a) * s; };
    const double c00 = lerp(ct(i0[0], i0[1], i0[2]), ct(x1, i0[1], i0[2]), t[0]);
    const double c10 = lerp(ct(i0[0], y1, i0[2]), ct(x1, y1, i0[2]), t[0]);
    const double c01 = lerp(ct(i0[0], i0[1], z1), ct(x1, i0[1], z1), t[0]);
    const double c11 = lerp(ct(i0[0], y1, z1), ct(x1, y1, z1), t[0]);
    value = lerp(lerp(c00, c10, t[1]), lerp(c01, c11, t[1]), t[2]);
    return true;
}

// bone_contact; with `keep` (per face), the faces it marks keep their flag in `before` instead of
// being sampled (their areas summed as sampled ones are).
template <class T>
BoneContact contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                    const BoneContactParams& p, const std::vector<uint8_t>* keep, const std::vector<uint8_t>* before,
                    const PackedMask* skull = nullptr) {
    if (!(p.offset_mm >= 0) || !std::isfinite(p.offset_mm))
        throw InvalidParameter("bone contact offset " + std::to_string(p.offset_mm) +
                               " mm, expected a finite value >= 0");
    const size_t nv = mesh.vertices.size();
    for (const meshpost::Face& f : mesh.faces)
        if (f[0] >= nv || f[1] >= nv || f[2] >= nv)
            throw InvalidParameter("bone contact: a face references a vertex beyond the mesh's " +
                                   std::to_string(nv) + " vertices");

    BoneContact r;
    const int64_t nf = int64_t(mesh.faces.size());
    r.face_on_bone.assign(size_t(nf), 0);
    const int64_t chunks = (nf + kChunkFaces - 1) / kChunkFaces;
    std::vector<double> chunk_all(size_t(chunks), 0.0), chunk_on(size_t(chunks), 0.0);
    const Geometry& g = ct.geometry();
    const bool have_ct = !ct.empty();
    uint8_t* flags = r.face_on_bone.data();
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t c = 0; c < chunks; ++c) {
        double all = 0, on = 0;
        const int64_t end = std::min(nf, (c + 1) * kChunkFaces);
        for (int64_t fi = c * kChunkFaces; fi < end; ++fi) {
            const meshpost::Face& f = mesh.faces[size_t(fi)];
            const meshpost::Point &a = mesh.vertices[f[0]], &b = mesh.vertices[f[1]], &d = mesh.vertices[f[2]];
            const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
            const double v[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
            const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
            const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            const double area = 0.5 * len;
            all += area;
            if (keep && (*keep)[size_t(fi)]) {
                if ((*before)[size_t(fi)]) {
                    flags[fi] = 1;
                    on += area;
                }
                continue;
            }
            if (!(len > 0) || !have_ct) continue;
            const double s = p.offset_mm / len;
            const Vec3 q{(a[0] + b[0] + d[0]) / 3.0 + s * n[0], (a[1] + b[1] + d[1]) / 3.0 + s * n[1],
                         (a[2] + b[2] + d[2]) / 3.0 + s * n[2]};
            const Vec3 qi = g.world_to_index(q);
            double value = 0;
            bool bone = sample(ct, qi, value) && value >= isovalue;
            if (!bone && skull) {  // in the box of voxel centres (sample's test): the nearest voxel
                const int64_t x = std::llround(qi[0]), y = std::llround(qi[1]), z = std::llround(qi[2]);
                bone = x >= 0 && y >= 0 && z >= 0 && x < ct.nx() && y < ct.ny() && z < ct.nz() &&
                       skull->test(size_t(x + ct.nx() * (y + ct.ny() * z)));
            }
            if (bone) {
                flags[fi] = 1;
                on += area;
            }
        }
        chunk_all[size_t(c)] = all;
        chunk_on[size_t(c)] = on;
    }
    for (int64_t c = 0; c < chunks; ++c) {
        r.area_mm2 += chunk_all[size_t(c)];
        r.area_on_bone_mm2 += chunk_on[size_t(c)];
    }
    r.share = r.area_mm2 > 0 ? r.area_on_bone_mm2 / r.area_mm2 : 0.0;
    return r;
}

}  // namespace

template <class T>
BoneContact bone_contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                         const BoneContactParams& p) {
    return contact(mesh, ct, isovalue, p, nullptr, nullptr);
}

template <class T>
BoneContact bone_contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                         const BoneContactParams& p, const std::vector<uint8_t>& before,
                         const std::vector<uint32_t>& moved) {
    if (before.size() != mesh.faces.size())
        throw InvalidParameter("bone contact: " + std::to_string(before.size()) + " flags before the move for " +
                               std::to_string(mesh.faces.size()) + " faces");
    const size_t nv = mesh.vertices.size();
    for (uint32_t v : moved)
        if (v >= nv)
            throw InvalidParameter("bone contact: moved vertex " + std::to_string(v) + " beyond the mesh's " +
                                   std::to_string(nv) + " vertices");
    // A face keeps its flag unless a vertex of it moved (an index beyond the mesh: sampled, and
    // refused there).
    std::vector<uint8_t> keep = meshpost::faces_touching(mesh, moved);
    for (uint8_t& k : keep) k = !k;
    return contact(mesh, ct, isovalue, p, &keep, &before);
}

template <class T>
BoneContact bone_contact(const meshpost::TriangleMesh& mesh, const Volume<T>& ct, double isovalue,
                         const BoneContactParams& p, const PackedMask& skull) {
    const Dims& sd = skull.geometry().dims;
    if (sd != ct.dims())
        throw InvalidParameter("bone contact: a skull mask of " + std::to_string(sd[0]) + " x " + std::to_string(sd[1]) + " x " +
                               std::to_string(sd[2]) + " voxels for a CT of " + std::to_string(ct.nx()) + " x " +
                               std::to_string(ct.ny()) + " x " + std::to_string(ct.nz()));
    return contact(mesh, ct, isovalue, p, nullptr, nullptr, &skull);
}

std::vector<ClosingSurface> closing_surfaces(const meshpost::TriangleMesh& mesh,
                                             const std::vector<uint8_t>& face_on_bone, double min_area_mm2) {
    return closing_surfaces(mesh, face_on_bone, min_area_mm2, meshpost::face_neighbours(mesh));
}

std::vector<ClosingSurface> closing_surfaces(const meshpost::TriangleMesh& mesh,
                                             const std::vector<uint8_t>& face_on_bone, double min_area_mm2,
                                             const std::vector<std::array<uint32_t, 3>>& neighbours) {
    if (neighbours.size() != mesh.faces.size())
        throw meshpost::InvalidMesh("closing_surfaces: " + std::to_string(neighbours.size()) + " neighbour triples for " +
                                    std::to_string(mesh.faces.size()) + " faces");
    if (const size_t bad = meshpost::first_face_with_bad_index(mesh); bad < mesh.faces.size())
        throw meshpost::InvalidMesh("closing_surfaces: face " + std::to_string(bad) + " references a vertex beyond the mesh's " +
                                    std::to_string(mesh.vertices.size()));
    // The edge-connected patches of the off-bone faces (numbered in order of their lowest face),
    // then per patch its area, area-weighted centroid and normal, summed in face order.
    const size_t nf = std::min(mesh.faces.size(), face_on_bone.size());
    std::vector<uint8_t> off(mesh.faces.size(), 0);
    for (size_t f = 0; f < nf; ++f) off[f] = !face_on_bone[f];
    const std::vector<std::vector<uint32_t>> found = meshpost::face_patches(neighbours, off);
    std::vector<int64_t> patch_of(mesh.faces.size(), -1);
    for (size_t id = 0; id < found.size(); ++id)
        for (uint32_t f : found[id]) patch_of[f] = int64_t(id);
    std::vector<ClosingSurface> patches(found.size());
    std::vector<Vec3> sums(found.size(), Vec3{0, 0, 0});
    for (size_t f = 0; f < nf; ++f) {
        if (patch_of[f] < 0) continue;
        const auto& t = mesh.faces[f];
        const auto& A = mesh.vertices[t[0]];
        const auto& B = mesh.vertices[t[1]];
        const auto& C = mesh.vertices[t[2]];
        const Vec3 u{B[0] - A[0], B[1] - A[1], B[2] - A[2]}, v{C[0] - A[0], C[1] - A[1], C[2] - A[2]};
        const Vec3 n{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        const double area = 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        ClosingSurface& s = patches[size_t(patch_of[f])];
        s.area_mm2 += area;
        for (int a = 0; a < 3; ++a) {
            s.centre[size_t(a)] += area * (A[size_t(a)] + B[size_t(a)] + C[size_t(a)]) / 3.0;
            sums[size_t(patch_of[f])][size_t(a)] += 0.5 * n[size_t(a)];
        }
    }
    std::vector<ClosingSurface> out;
    for (size_t i = 0; i < patches.size(); ++i) {
        ClosingSurface s = patches[i];
        if (!(s.area_mm2 >= min_area_mm2) || !(s.area_mm2 > 0)) continue;
        for (int a = 0; a < 3; ++a) s.centre[size_t(a)] /= s.area_mm2;
        const Vec3& m = sums[i];
        const double len = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
        if (len > 1e-12 * s.area_mm2)
            for (int a = 0; a < 3; ++a) s.normal[size_t(a)] = m[size_t(a)] / len;
        out.push_back(s);
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const ClosingSurface& x, const ClosingSurface& y) { return x.area_mm2 > y.area_mm2; });
    return out;
}

template BoneContact bone_contact<float>(const meshpost::TriangleMesh&, const Volume<float>&, double, const BoneContactParams&);
template BoneContact bone_contact<int16_t>(const meshpost::TriangleMesh&, const Volume<int16_t>&, double, const BoneContactParams&);
template BoneContact bone_contact<float>(const meshpost::TriangleMesh&, const Volume<float>&, double, const BoneContactParams&,
                                        const std::vector<uint8_t>&, const std::vector<uint32_t>&);
template BoneContact bone_contact<int16_t>(const meshpost::TriangleMesh&, const Volume<int16_t>&, double,
                                          const BoneContactParams&, const std::vector<uint8_t>&, const std::vector<uint32_t>&);
template BoneContact bone_contact<float>(const meshpost::TriangleMesh&, const Volume<float>&, double, const BoneContactParams&,
                                        const PackedMask&);
template BoneContact bone_contact<int16_t>(const meshpost::TriangleMesh&, const Volume<int16_t>&, double,
                                          const BoneContactParams&, const PackedMask&);

}  // namespace endocast
