// Marching cubes on the Freudenthal subdivision (marching_cubes.h).
#include "endocast/stages/marching_cubes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>


#include <omp.h>

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

// Polygonizes the cube layers [z_begin, z_end) (cube z spans samples z and z+1; cubes run from -1 to
// n-1 on each axis so that samples outside the volume close the surface at the border).
//
// Vertices live on the edges of the Freudenthal triangulation: a base sample and a direction mask
// (1..7). They are cached in edge-index arrays: two planes of in-plane edges (masks 1, 2, 3) for
// the samples at z and z+1, and one array of the edges that cross the layer (masks 4..7). A vertex
// crossing is met first by the lowest layer that touches its edge, so in the serial order every
// vertex on the bottom plane of a slab is created by the previous slab. The slab therefore numbers
// its own vertices in creation order and records the bottom-plane ones as "external", to be
// resolved against the previous slab's top plane: concatenating slabs reproduces exactly the
// vertex and face order of a single serial sweep, for any number of slabs or threads.
class SlabMesher {
public:
    // `z_offset`: the grid index of f's plane 0 (f holds planes of a larger field: the vertices'
    // positions are computed in that field's indices, so that they do not depend on the slabs).
    SlabMesher(const Volume<float>& f, double iso, int64_t z_begin, int64_t z_end, bool first_slab,
               int64_t z_offset = 0)
        : f_(f), iso_(iso), z_begin_(z_begin), z_end_(z_end), z_offset_(z_offset), first_slab_(first_slab) {
        px_ = f.nx() + 2;
        const size_t plane = size_t(px_ * (f.ny() + 2));
        lower_.assign(3 * plane, 0);
        upper_.assign(3 * plane, 0);
        cross_.assign(4 * plane, 0);
    }

    void run() {
        const int64_t nx = f_.nx(), ny = f_.ny(), nz = f_.nz();
        for (int64_t z = z_begin_; z < z_end_; ++z) {
            z_ = z;
            for (int64_t y = -1; y < ny; ++y) {
                for (int c = 0; c < 4; ++c) {
                    const int64_t yy = y + (c & 1), zz = z + (c >> 1);
                    rows_[c] = (yy >= 0 && yy < ny && zz >= 0 && zz < nz) ? &f_(0, yy, zz) : nullptr;
                }
                for (int64_t x = -1; x < nx; ++x) cube(x, y, z);
            }
            // Next layer: this layer's top plane becomes the bottom one.
            for (uint32_t k : touched_lower_) lower_[k] = 0;
            touched_lower_.clear();
            for (uint32_t k : touched_cross_) cross_[k] = 0;
            touched_cross_.clear();
            if (z + 1 < z_end_) {
                lower_.swap(upper_);
                touched_lower_.swap(touched_upper_);
            }
        }
        std::vector<uint32_t>().swap(lower_);
        std::vector<uint32_t>().swap(cross_);
    }

    // Results, in local indices (vertex k of this slab is pos_[k]).
    std::vector<P3> pos_;
    std::vector<meshpost::Face> faces_;
    std::vector<std::pair<uint32_t, uint32_t>> external_;  ///< (local vertex, bottom-plane key)
    std::vector<uint32_t> upper_;                           ///< top plane after run(): key -> local + 1
    std::vector<uint32_t> touched_upper_;                   ///< its keys in use

    // Key of an in-plane edge at base sample (bx, by) with direction mask 1..3.
    size_t plane_key(int64_t bx, int64_t by, int mask) const {
        return 3 * size_t((bx + 1) + px_ * (by + 1)) + size_t(mask - 1);
    }

private:
    double value(int64_t x, int c) const {
        const float* r = rows_[c];
        if (!r || x < 0 || x >= f_.nx()) return std::numeric_limits<double>::infinity();
        return r[x];
    }

    void cube(int64_t x, int64_t y, int64_t z) {
        double v[8];
        int inside_bits = 0;
        for (int k = 0; k < 8; ++k) {
            v[k] = value(x + (k & 1), (k >> 1) & 3);
            if (v[k] < iso_) inside_bits |= 1 << k;
        }
        if (inside_bits == 0 || inside_bits == 255) return;
        for (const auto& t : kTets) tet(x, y, z, t, v);
    }

    // Vertex on the cube edge from corner u to corner v (u's bits a subset of v's).
    uint32_t vertex(int64_t x, int64_t y, int64_t z, int u, int w, const double* v) {
        const int64_t bx = x + (u & 1), by = y + ((u >> 1) & 1), bz = z + ((u >> 2) & 1);
        const int mask = u ^ w;
        const size_t s = size_t((bx + 1) + px_ * (by + 1));
        std::vector<uint32_t>* arr;
        std::vector<uint32_t>* touched;
        size_t key;
        bool external = false;
        if (mask & 4) {
            arr = &cross_;
            touched = &touched_cross_;
            key = 4 * s + size_t(mask - 4);
        } else if (bz == z_) {
            arr = &lower_;
            touched = &touched_lower_;
            key = 3 * s + size_t(mask - 1);
            external = !first_slab_ && z_ == z_begin_;
        } else {
            arr = &upper_;
            touched = &touched_upper_;
            key = 3 * s + size_t(mask - 1);
        }
        uint32_t* slot = &(*arr)[key];
        if (*slot) return *slot - 1;
        double t = (iso_ - v[u]) / (v[w] - v[u]);
        if (!std::isfinite(t)) t = 0.5;  // an infinite outside sample: midpoint (border only)
        if (std::isinf(v[w]) && std::isfinite(v[u])) t = 0.5;
        t = std::clamp(t, kEdgeClamp, 1.0 - kEdgeClamp);
        const P3 p{double(bx) + t * double(mask & 1), double(by) + t * double((mask >> 1) & 1),
                   double(bz + z_offset_) + t * double((mask >> 2) & 1)};
        const uint32_t id = uint32_t(pos_.size());
        pos_.push_back(p);
        *slot = id + 1;
        touched->push_back(uint32_t(key));
        if (external) external_.push_back({id, uint32_t(key)});
        return id;
    }

    void emit(uint32_t a, uint32_t b, uint32_t c) { faces_.push_back({a, b, c}); }

    void tet(int64_t x, int64_t y, int64_t z, const int* t, const double* v) {
        int in[4], out[4], ni = 0, no = 0;
        for (int k = 0; k < 4; ++k) {
            if (v[t[k]] < iso_) in[ni++] = t[k];
            else out[no++] = t[k];
        }
        if (ni == 0 || no == 0) return;
        auto corner = [&](int k) {
            return P3{double(x + (k & 1)), double(y + ((k >> 1) & 1)), double(z + z_offset_ + ((k >> 2) & 1))};
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
            const P3 n = cross(sub(pos_[q[1]], pos_[q[0]]), sub(pos_[q[2]], pos_[q[0]]));
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
            const P3& p0 = pos_[q[k]];
            const P3& p1 = pos_[q[(k + 1) % 4]];
            n[0] += (p0[1] - p1[1]) * (p0[2] + p1[2]);
            n[1] += (p0[2] - p1[2]) * (p0[0] + p1[0]);
            n[2] += (p0[0] - p1[0]) * (p0[1] + p1[1]);
        }
        if (dot(n, w) < 0) std::swap(q[1], q[3]);
        // Split along the shorter diagonal.
        if (norm2(sub(pos_[q[0]], pos_[q[2]])) <= norm2(sub(pos_[q[1]], pos_[q[3]]))) {
            emit(q[0], q[1], q[2]);
            emit(q[0], q[2], q[3]);
        } else {
            emit(q[0], q[1], q[3]);
            emit(q[1], q[2], q[3]);
        }
    }

    const Volume<float>& f_;
    double iso_;
    int64_t z_begin_, z_end_, z_offset_, z_ = 0, px_ = 0;
    bool first_slab_;
    const float* rows_[4] = {nullptr, nullptr, nullptr, nullptr};
    std::vector<uint32_t> lower_, cross_;
    std::vector<uint32_t> touched_lower_, touched_cross_;
};

}  // namespace

struct IsosurfaceStream::State {
    Geometry grid;
    double iso = 0;
    int64_t next_layer = -1;                // the first cube layer not meshed yet
    std::vector<uint32_t> top;              // the last meshed layer's top plane: key -> global vertex + 1
    std::vector<uint32_t> top_keys;         // its keys in use
    meshpost::TriangleMesh mesh;
};

IsosurfaceStream::IsosurfaceStream(const Geometry& grid, double iso) : s_(std::make_unique<State>()) {
    if (!std::isfinite(iso))
        throw InvalidParameter("isosurface: isovalue " + std::to_string(iso) + ", expected a finite number");
    s_->grid = grid;
    s_->iso = iso;
    s_->top.assign(3 * size_t(grid.dims[0] + 2) * size_t(grid.dims[1] + 2), 0);
}

IsosurfaceStream::~IsosurfaceStream() = default;

int64_t IsosurfaceStream::next_layer() const { return s_->next_layer; }

void IsosurfaceStream::add(const Volume<float>& planes, int64_t z_first, int64_t layer_end) {
    State& st = *s_;
    const Dims& gd = st.grid.dims;
    const int64_t begin = st.next_layer;
    layer_end = std::min(layer_end, gd[2]);
    if (layer_end <= begin) return;
    // The planes the layers [begin, layer_end) touch inside the grid must all be in `planes`.
    const int64_t need_lo = std::max<int64_t>(begin, 0), need_hi = std::min(layer_end, gd[2] - 1);
    if (planes.nx() != gd[0] || planes.ny() != gd[1] || z_first > need_lo ||
        z_first + planes.nz() <= need_hi || z_first < 0 || z_first + planes.nz() > gd[2])
        throw InvalidParameter("isosurface stream: planes " + std::to_string(z_first) + ".." +
                               std::to_string(z_first + planes.nz() - 1) + " of " + std::to_string(planes.nx()) +
                               " x " + std::to_string(planes.ny()) + " samples, expected planes " +
                               std::to_string(need_lo) + ".." + std::to_string(need_hi) + " of " +
                               std::to_string(gd[0]) + " x " + std::to_string(gd[1]));
    // Sub-slabs of the layers, meshed in parallel (local plane indices: grid index - z_first); eight
    // per thread, as the surface is uneven along z (two per thread left one thread idle at the end).
    // The mesh does not depend on their number (vertices and faces in creation order, slab after slab).
    const int64_t layers = layer_end - begin;
    const int64_t nslabs = std::max<int64_t>(1, std::min<int64_t>(layers, 8 * int64_t(omp_get_max_threads())));
    std::vector<std::unique_ptr<SlabMesher>> slabs(static_cast<size_t>(nslabs));
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t k = 0; k < nslabs; ++k) {
        const int64_t z0 = begin + layers * k / nslabs, z1 = begin + layers * (k + 1) / nslabs;
        auto m = std::make_unique<SlabMesher>(planes, st.iso, z0 - z_first, z1 - z_first, z0 == -1, z_first);
        m->run();
        slabs[size_t(k)] = std::move(m);
    }
    // Global vertex numbers: a slab's own vertices in creation order after those before it;
    // external ones (its bottom plane) from the top plane of the layer below.
    std::vector<std::vector<uint32_t>> global(static_cast<size_t>(nslabs));
    std::vector<size_t> vbase(size_t(nslabs) + 1, st.mesh.vertices.size()),
        fbase(size_t(nslabs) + 1, st.mesh.faces.size());
    for (int64_t k = 0; k < nslabs; ++k) {
        SlabMesher& m = *slabs[size_t(k)];
        std::vector<uint32_t>& g = global[size_t(k)];
        g.assign(m.pos_.size(), UINT32_MAX);
        for (const auto& e : m.external_) {
            const uint32_t below = st.top[e.second];
            if (below == 0) throw std::logic_error("isosurface: a slab-boundary vertex was not created below");
            g[e.first] = below - 1;
        }
        size_t next = vbase[size_t(k)];
        for (size_t i = 0; i < g.size(); ++i)
            if (g[i] == UINT32_MAX) g[i] = uint32_t(next++);
        if (next > size_t(UINT32_MAX)) throw InvalidParameter("isosurface: more than 2^32 vertices");
        vbase[size_t(k) + 1] = next;
        fbase[size_t(k) + 1] = fbase[size_t(k)] + m.faces_.size();
        for (uint32_t key : st.top_keys) st.top[key] = 0;
        st.top_keys.clear();
        for (uint32_t key : m.touched_upper_) {
            st.top[key] = g[m.upper_[key] - 1] + 1;
            st.top_keys.push_back(key);
        }
        std::vector<uint32_t>().swap(m.upper_);
    }
    meshpost::TriangleMesh& mesh = st.mesh;
    mesh.vertices.resize(vbase.back());
    mesh.faces.resize(fbase.back());
    const Geometry& geo = st.grid;
    const bool flip = geo.direction_determinant() < 0;
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t k = 0; k < nslabs; ++k) {
        SlabMesher& m = *slabs[size_t(k)];
        const std::vector<uint32_t>& g = global[size_t(k)];
        for (size_t i = 0; i < m.pos_.size(); ++i) {
            if (g[i] < vbase[size_t(k)]) continue;  // external: written by its own slab
            const P3& p = m.pos_[i];
            mesh.vertices[g[i]] = geo.index_to_world(p[0], p[1], p[2]);
        }
        meshpost::Face* out = mesh.faces.data() + fbase[size_t(k)];
        for (size_t i = 0; i < m.faces_.size(); ++i) {
            const meshpost::Face& t = m.faces_[i];
            out[i] = flip ? meshpost::Face{g[t[0]], g[t[2]], g[t[1]]}
                          : meshpost::Face{g[t[0]], g[t[1]], g[t[2]]};
        }
        std::vector<P3>().swap(m.pos_);
        std::vector<meshpost::Face>().swap(m.faces_);
    }
    st.next_layer = layer_end;
}

meshpost::TriangleMesh IsosurfaceStream::finish() {
    if (s_->next_layer != s_->grid.dims[2])
        throw InvalidParameter("isosurface stream: layers " + std::to_string(s_->next_layer) + ".." +
                               std::to_string(s_->grid.dims[2] - 1) + " were not meshed");
    return std::move(s_->mesh);
}

meshpost::TriangleMesh isosurface(const Volume<float>& f, double iso) {
    IsosurfaceStream s(f.geometry(), iso);
    s.add(f, 0, f.nz());
    return s.finish();
}

}  // namespace endocast
