#include "endocast/marching_cubes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include "endocast/components.h"

namespace endocast {
namespace {

using P3 = std::array<double, 3>;

P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
P3 cross(const P3& a, const P3& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm2(const P3& a) { return dot(a, a); }

// The six tetrahedra of the Freudenthal subdivision: 0 -> e_a -> e_a + e_b -> 7 for every
// permutation (a, b, c) of the axes. Corner k of a cube is (k&1, (k>>1)&1, (k>>2)&1).
constexpr int kTets[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7},
                             {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};

class Mesher {
public:
    Mesher(const Volume<float>& f, double iso) : f_(f), iso_(iso) {
        map_.reserve(1 << 16);
    }

    void run() {
        const int64_t nx = f_.nx(), ny = f_.ny(), nz = f_.nz();
        // Cubes from -1 to n-1 on each axis, so that samples outside the volume (outside) close
        // the surface at the border.
        for (int64_t z = -1; z < nz; ++z)
            for (int64_t y = -1; y < ny; ++y)
                for (int64_t x = -1; x < nx; ++x) cube(x, y, z);
        finish();
    }

    meshpost::TriangleMesh take() { return std::move(mesh_); }

private:
    double value(int64_t x, int64_t y, int64_t z) const {
        if (!f_.contains(x, y, z)) return std::numeric_limits<double>::infinity();
        return f_(x, y, z);
    }

    void cube(int64_t x, int64_t y, int64_t z) {
        double v[8];
        int inside_bits = 0;
        for (int k = 0; k < 8; ++k) {
            v[k] = value(x + (k & 1), y + ((k >> 1) & 1), z + ((k >> 2) & 1));
            if (v[k] < iso_) inside_bits |= 1 << k;
        }
        if (inside_bits == 0 || inside_bits == 255) return;
        for (const auto& t : kTets) tet(x, y, z, t, v);
    }

    // Vertex on the cube edge from corner u to corner v (u's bits a subset of v's).
    uint32_t vertex(int64_t x, int64_t y, int64_t z, int u, int w, const double* v) {
        const int64_t bx = x + (u & 1), by = y + ((u >> 1) & 1), bz = z + ((u >> 2) & 1);
        const int mask = u ^ w;
        // Key: base sample (shifted by one so -1 is representable) and direction mask.
        const uint64_t key =
            ((uint64_t(bx + 1) + uint64_t(f_.nx() + 2) *
                                     (uint64_t(by + 1) + uint64_t(f_.ny() + 2) * uint64_t(bz + 1)))
             << 3) |
            uint64_t(mask);
        auto it = map_.find(key);
        if (it != map_.end()) return it->second;
        double t = (iso_ - v[u]) / (v[w] - v[u]);
        if (!std::isfinite(t)) t = 0.5;  // an infinite outside sample: midpoint (border only)
        if (std::isinf(v[w]) && std::isfinite(v[u])) t = 0.5;
        t = std::clamp(t, kEdgeClamp, 1.0 - kEdgeClamp);
        const P3 p{double(bx) + t * double(mask & 1), double(by) + t * double((mask >> 1) & 1),
                   double(bz) + t * double((mask >> 2) & 1)};
        const uint32_t id = uint32_t(idx_.size());
        idx_.push_back(p);
        map_.emplace(key, id);
        return id;
    }

    void emit(uint32_t a, uint32_t b, uint32_t c) { mesh_.faces.push_back({a, b, c}); }

    void tet(int64_t x, int64_t y, int64_t z, const int* t, const double* v) {
        int in[4], out[4], ni = 0, no = 0;
        for (int k = 0; k < 4; ++k) {
            if (v[t[k]] < iso_) in[ni++] = t[k];
            else out[no++] = t[k];
        }
        if (ni == 0 || no == 0) return;
        auto corner = [&](int k) {
            return P3{double(x + (k & 1)), double(y + ((k >> 1) & 1)), double(z + ((k >> 2) & 1))};
        };
        auto edge = [&](int a, int b) {
            return a < b ? vertex(x, y, z, a, b, v) : vertex(x, y, z, b, a, v);
        };
        P3 cin{0, 0, 0}, cout{0, 0, 0};
        for (int k = 0; k < ni; ++k) {
            const P3 c = corner(in[k]);
            for (int a = 0; a < 3; ++a) cin[a] += c[a] / ni;
        }
        for (int k = 0; k < no; ++k) {
            const P3 c = corner(out[k]);
            for (int a = 0; a < 3; ++a) cout[a] += c[a] / no;
        }
        const P3 w = sub(cout, cin);  // points from inside to outside
        if (ni == 1 || no == 1) {
            const int lone = ni == 1 ? in[0] : out[0];
            const int* others = ni == 1 ? out : in;
            uint32_t q[3] = {edge(lone, others[0]), edge(lone, others[1]), edge(lone, others[2])};
            const P3 n = cross(sub(idx_[q[1]], idx_[q[0]]), sub(idx_[q[2]], idx_[q[0]]));
            if (dot(n, w) < 0) std::swap(q[1], q[2]);
            emit(q[0], q[1], q[2]);
            return;
        }
        // Two inside (a, b), two outside (c, d): quad ac, ad, bd, bc.
        const int a = in[0], b = in[1], c = out[0], d = out[1];
        uint32_t q[4] = {edge(a, c), edge(a, d), edge(b, d), edge(b, c)};
        // Newell normal of the quad decides its orientation.
        P3 n{0, 0, 0};
        for (int k = 0; k < 4; ++k) {
            const P3& p0 = idx_[q[k]];
            const P3& p1 = idx_[q[(k + 1) % 4]];
            n[0] += (p0[1] - p1[1]) * (p0[2] + p1[2]);
            n[1] += (p0[2] - p1[2]) * (p0[0] + p1[0]);
            n[2] += (p0[0] - p1[0]) * (p0[1] + p1[1]);
        }
        if (dot(n, w) < 0) std::swap(q[1], q[3]);
        // Split along the shorter diagonal.
        if (norm2(sub(idx_[q[0]], idx_[q[2]])) <= norm2(sub(idx_[q[1]], idx_[q[3]]))) {
            emit(q[0], q[1], q[2]);
            emit(q[0], q[2], q[3]);
        } else {
            emit(q[0], q[1], q[3]);
            emit(q[1], q[2], q[3]);
        }
    }

    void finish() {
        const Geometry& g = f_.geometry();
        mesh_.vertices.resize(idx_.size());
        for (size_t i = 0; i < idx_.size(); ++i)
            mesh_.vertices[i] = g.index_to_world(idx_[i][0], idx_[i][1], idx_[i][2]);
        if (g.direction_determinant() < 0)
            for (auto& f : mesh_.faces) std::swap(f[1], f[2]);
    }

    const Volume<float>& f_;
    double iso_;
    std::unordered_map<uint64_t, uint32_t> map_;
    std::vector<P3> idx_;
    meshpost::TriangleMesh mesh_;
};

}  // namespace

meshpost::TriangleMesh isosurface(const Volume<float>& f, double iso) {
    if (!std::isfinite(iso))
        throw InvalidParameter("isosurface: isovalue " + std::to_string(iso) +
                               ", expected a finite number");
    Mesher m(f, iso);
    m.run();
    return m.take();
}

PolygonizeResult polygonize(const Volume<float>& ct, const Volume<uint8_t>& labels,
                            const PolygonizeParams& p) {
    if (ct.size() != labels.size())
        throw InvalidParameter("polygonize: CT and label volumes differ in size");
    const double T = p.isovalue;
    if (!std::isfinite(T))
        throw InvalidParameter("polygonize: isovalue " + std::to_string(T) + ", expected finite");
    PolygonizeResult r;
    r.mask = Volume<uint8_t>(ct.geometry());
    for (size_t i = 0; i < ct.size(); ++i) r.mask[i] = labels[i] == kEndocast ? 1 : 0;
    r.fragments_removed = keep_largest_component(r.mask, Connectivity::Face6);
    r.holes_filled = fill_holes(r.mask, Connectivity::Face6);

    // Bounding box of the region.
    const Geometry& g = ct.geometry();
    std::array<int64_t, 3> lo{g.dims[0], g.dims[1], g.dims[2]}, hi{-1, -1, -1};
    std::vector<float> inside_values;
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                const size_t i = r.mask.index(x, y, z);
                if (!r.mask[i]) continue;
                ++r.mask_voxels;
                lo = {std::min(lo[0], x), std::min(lo[1], y), std::min(lo[2], z)};
                hi = {std::max(hi[0], x), std::max(hi[1], y), std::max(hi[2], z)};
                if ((r.mask_voxels & 7) == 1) inside_values.push_back(ct[i]);
            }
    if (r.mask_voxels == 0) throw NoResult("polygonize: no voxel is labelled endocast");

    auto mid = inside_values.begin() + inside_values.size() / 2;
    std::nth_element(inside_values.begin(), mid, inside_values.end());
    const double median = *mid;
    const double floor_contrast = 1e-3 * std::max(1.0, std::fabs(T));
    const double contrast = std::max(T - median, floor_contrast);
    r.other_value = T + contrast;
    const float high = static_cast<float>(r.other_value);
    // Inside values must be strictly below T; a voxel of E at or above T (a detached bone fragment
    // in the cavity) is lowered just below it.
    const float low = static_cast<float>(T - floor_contrast);
    const float just_above = static_cast<float>(T + floor_contrast);

    // Sub-volume: bounding box plus one voxel on every side (outside samples are "outside").
    Geometry sg = g;
    for (int a = 0; a < 3; ++a) sg.dims[a] = hi[a] - lo[a] + 3;
    sg.origin = g.index_to_world(double(lo[0] - 1), double(lo[1] - 1), double(lo[2] - 1));
    Volume<float> field(sg, high);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < sg.dims[2]; ++z)
        for (int64_t y = 0; y < sg.dims[1]; ++y)
            for (int64_t x = 0; x < sg.dims[0]; ++x) {
                const int64_t gx = x + lo[0] - 1, gy = y + lo[1] - 1, gz = z + lo[2] - 1;
                if (!ct.contains(gx, gy, gz)) continue;
                const size_t i = ct.index(gx, gy, gz);
                const float v = ct[i];
                // Outside E: true bone (CT >= T) keeps its value, nudged strictly above T;
                // filled voids and "other" space (CT < T) are raised to T + contrast.
                field(x, y, z) = r.mask[i] ? std::min(v, low) : (v >= T ? std::max(v, just_above) : high);
            }
    r.mesh = isosurface(field, T);
    return r;
}

}  // namespace endocast
