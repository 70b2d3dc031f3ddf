// Uniform grid of triangles for exact nearest-triangle queries (see triangle_grid.h).
#include "meshpost/triangle_grid.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace meshpost {
namespace {

inline double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline void sub(const double* a, const double* b, double* r) {
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}
inline double sqnorm(const double* a) { return dot(a, a); }
/// |a - s * b|^2
inline double sqnorm_axpy(const double* a, double s, const double* b) {
    const double r[3] = {a[0] - b[0] * s, a[1] - b[1] * s, a[2] - b[2] * s};
    return sqnorm(r);
}

}  // namespace

double sq_dist_point_triangle(const double* p, const double* a, const double* b, const double* c) {
    double ab[3], ac[3], ap[3];
    sub(b, a, ab);
    sub(c, a, ac);
    sub(p, a, ap);
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return sqnorm(ap);
    double bp[3];
    sub(p, b, bp);
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return sqnorm(bp);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return sqnorm_axpy(ap, d1 / (d1 - d3), ab);
    double cp[3];
    sub(p, c, cp);
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return sqnorm(cp);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return sqnorm_axpy(ap, d2 / (d2 - d6), ac);
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        double bc[3];
        sub(c, b, bc);
        return sqnorm_axpy(bp, (d4 - d3) / ((d4 - d3) + (d5 - d6)), bc);
    }
    const double sum = va + vb + vc;
    if (!(sum > 0)) return std::min({sqnorm(ap), sqnorm(bp), sqnorm(cp)});  // degenerate: an upper bound
    const double v = vb / sum, w = vc / sum;
    const double r[3] = {ap[0] - ab[0] * v - ac[0] * w, ap[1] - ab[1] * v - ac[1] * w, ap[2] - ab[2] * v - ac[2] * w};
    return sqnorm(r);
}

TriangleGrid::TriangleGrid(const TriangleMesh& m, double cell, size_t max_cells_arg) {
    const size_t nv = m.vertices.size();
    tris_.resize(m.faces.size());
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (size_t f = 0; f < m.faces.size(); ++f) {
        Tri& t = tris_[f];
        for (int k = 0; k < 3; ++k) {
            if (m.faces[f][k] >= nv)
                throw InvalidMesh("TriangleGrid: face " + std::to_string(f) + " references vertex " +
                                  std::to_string(m.faces[f][k]) + " of " + std::to_string(nv));
            const Point& q = m.vertices[m.faces[f][k]];
            for (int a = 0; a < 3; ++a) {
                t.p[k][a] = q[a];
                lo[a] = std::min(lo[a], q[a]);
                hi[a] = std::max(hi[a], q[a]);
            }
        }
        for (int a = 0; a < 3; ++a) {
            t.lo[a] = std::min({t.p[0][a], t.p[1][a], t.p[2][a]});
            t.hi[a] = std::max({t.p[0][a], t.p[1][a], t.p[2][a]});
        }
        double u[3], v[3];
        sub(t.p[1], t.p[0], u);
        sub(t.p[2], t.p[0], v);
        t.n[0] = u[1] * v[2] - u[2] * v[1];
        t.n[1] = u[2] * v[0] - u[0] * v[2];
        t.n[2] = u[0] * v[1] - u[1] * v[0];
        const double len = std::sqrt(sqnorm(t.n));
        for (double& x : t.n) x = len > 0 ? x / len : 0.0;  // zero: the plane test never rejects
    }
    if (tris_.empty()) {
        start_.assign(2, 0);
        return;
    }
    double scale = 0;
    for (int a = 0; a < 3; ++a) {
        lo_[a] = lo[a];
        hi_[a] = hi[a];
        scale = std::max({scale, std::fabs(lo[a]), std::fabs(hi[a])});
    }
    margin_ = 1e-9 * (1.0 + scale);
    const double max_cells =
        max_cells_arg > 0 ? double(max_cells_arg) : std::max(double(1 << 20), 4.0 * double(tris_.size()));
    if (!(cell > 0)) cell = 1.0;
    auto cells = [&](double c) {
        double n = 1;
        for (int a = 0; a < 3; ++a) n *= (hi[a] - lo[a]) / c + 1;
        return n;
    };
    while (cells(cell) > max_cells) cell *= 1.25;
    cell_ = cell;
    inv_cell_ = 1.0 / cell;
    for (int a = 0; a < 3; ++a) n_[a] = int64_t((hi[a] - lo[a]) * inv_cell_) + 1;
    start_.assign(size_t(n_[0] * n_[1] * n_[2]) + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<uint32_t> fill;
        if (pass == 1) {
            for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
            items_.resize(start_.back());
            fill.assign(start_.begin(), start_.end() - 1);
        }
        for (uint32_t i = 0; i < tris_.size(); ++i) {
            const Tri& t = tris_[i];
            int64_t i0[3], i1[3];
            for (int a = 0; a < 3; ++a) {
                i0[a] = clamp_index(t.lo[a], a);
                i1[a] = clamp_index(t.hi[a], a);
            }
            for (int64_t z = i0[2]; z <= i1[2]; ++z)
                for (int64_t y = i0[1]; y <= i1[1]; ++y)
                    for (int64_t x = i0[0]; x <= i1[0]; ++x) {
                        const size_t c = size_t((z * n_[1] + y) * n_[0] + x);
                        if (pass == 0) ++start_[c + 1];
                        else items_[fill[c]++] = i;
                    }
        }
    }
}

int64_t TriangleGrid::clamp_index(double x, int axis) const {
    const double i = std::floor((x - lo_[axis]) * inv_cell_);
    if (!(i > 0)) return 0;  // also NaN
    return std::min<int64_t>(i >= double(n_[axis]) ? n_[axis] - 1 : int64_t(i), n_[axis] - 1);
}

double TriangleGrid::sq_dist_within(uint32_t i, const double* p, double limit2) const {
    const Tri& t = tris_[i];
    double box2 = 0;
    for (int a = 0; a < 3; ++a) {
        const double e = p[a] < t.lo[a] ? t.lo[a] - p[a] : (p[a] > t.hi[a] ? p[a] - t.hi[a] : 0.0);
        box2 += e * e;
    }
    if (box2 > limit2) return HUGE_VAL;
    double ap[3];
    sub(p, t.p[0], ap);
    const double plane = dot(ap, t.n);
    if (plane * plane > limit2) return HUGE_VAL;
    return sq_dist_point_triangle(p, t.p[0], t.p[1], t.p[2]);
}

bool TriangleGrid::nearest(const double* p, int max_rings, double& d2, uint32_t& tri) const {
    double best = HUGE_VAL, limit2 = HUGE_VAL;
    uint32_t bi = UINT32_MAX;
    // A triangle is skipped only when a lower bound of its distance exceeds sqrt(best) + margin_:
    // the triangle with the smallest computed distance is never skipped, whatever the order.
    auto consider = [&](uint32_t i) {
        const double d = sq_dist_within(i, p, limit2);
        if (d < best || (d == best && i < bi)) {
            best = d;
            bi = i;
            const double r = std::sqrt(best) + margin_;
            limit2 = r * r;
        }
    };
    int64_t b[3];
    double out[3], out2 = 0;  // p's distance to the grid's box, per axis
    for (int a = 0; a < 3; ++a) {
        b[a] = clamp_index(p[a], a);
        out[a] = p[a] < lo_[a] ? lo_[a] - p[a] : (p[a] > hi_[a] ? p[a] - hi_[a] : 0.0);
        out2 += out[a] * out[a];
    }
    if (out2 > double(max_rings) * cell_ * double(max_rings) * cell_) {  // too far for the rings
        d2 = HUGE_VAL;
        tri = UINT32_MAX;
        return false;
    }
    if (tri < tris_.size()) consider(tri);
    auto visit = [&](int64_t x, int64_t y, int64_t z) {
        const int64_t c3[3] = {x, y, z};
        double box2 = 0;  // squared distance from p to the cell
        for (int a = 0; a < 3; ++a) {
            const double l = lo_[a] + double(c3[a]) * cell_, h = l + cell_;
            const double e = p[a] < l ? l - p[a] : (p[a] > h ? p[a] - h : 0.0);
            box2 += e * e;
        }
        if (box2 > limit2) return;
        const size_t c = size_t((z * n_[1] + y) * n_[0] + x);
        for (uint32_t k = start_[c]; k < start_[c + 1]; ++k) consider(items_[k]);
    };
    for (int64_t r = 0;; ++r) {
        const int64_t z0 = std::max<int64_t>(b[2] - r, 0), z1 = std::min(b[2] + r, n_[2] - 1);
        const int64_t y0 = std::max<int64_t>(b[1] - r, 0), y1 = std::min(b[1] + r, n_[1] - 1);
        const int64_t x0 = std::max<int64_t>(b[0] - r, 0), x1 = std::min(b[0] + r, n_[0] - 1);
        for (int64_t z = z0; z <= z1; ++z)
            for (int64_t y = y0; y <= y1; ++y) {
                if (std::abs(z - b[2]) == r || std::abs(y - b[1]) == r) {
                    for (int64_t x = x0; x <= x1; ++x) visit(x, y, z);
                } else {
                    if (b[0] - r >= 0) visit(b[0] - r, y, z);
                    if (b[0] + r < n_[0]) visit(b[0] + r, y, z);
                }
            }
        // Every unvisited cell lies beyond one of the faces of the block visited so far (and in the
        // grid's box along the other axes).
        double lb2 = HUGE_VAL;
        for (int a = 0; a < 3; ++a) {
            const double others = out2 - out[a] * out[a];
            if (b[a] - r > 0) {
                const double gap = std::max(0.0, p[a] - (lo_[a] + double(b[a] - r) * cell_));
                lb2 = std::min(lb2, gap * gap + others);
            }
            if (b[a] + r < n_[a] - 1) {
                const double gap = std::max(0.0, lo_[a] + double(b[a] + r + 1) * cell_ - p[a]);
                lb2 = std::min(lb2, gap * gap + others);
            }
        }
        const double reach = std::sqrt(best) + margin_;
        const bool settled = lb2 == HUGE_VAL || (bi != UINT32_MAX && lb2 > reach * reach);
        if (settled || r >= max_rings) {
            d2 = best;
            tri = bi;
            return settled;
        }
    }
}

}  // namespace meshpost
