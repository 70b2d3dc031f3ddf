// Gantry tilt and mixed slice spacing: measuring a stack of slices and resampling it onto a
// regular grid in patient space (slice_stack.h).
#include "slice_stack.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "kernels/vec3.h"

namespace endocast {
namespace {

std::string mm(double v, int digits = 4) {
    std::ostringstream s;
    s.precision(digits);
    s << v;
    return s.str();
}

}  // namespace

SliceStack analyze_slice_stack(const std::vector<Vec3>& positions, const Vec3& row_dir, const Vec3& col_dir,
                               double pixel_mm, const std::string& what, const std::vector<std::string>& files) {
    SliceStack st;
    const size_t n_slices = positions.size();
    if (n_slices == 0) return st;
    const Vec3 n = normalized(cross(row_dir, col_dir));
    auto name = [&](size_t k) {
        return files.size() == n_slices ? std::filesystem::path(files[k]).filename().string()
                                        : "#" + std::to_string(k + 1);
    };
    double last_offset = 0;  // in-plane offset of the last slice from the first (mm)
    for (const Vec3& p : positions) {
        const Vec3 d = sub(p, positions.front());
        const double a = dot(d, n);
        st.along_mm.push_back(a);
        last_offset = norm(sub(d, mul(n, a)));
        st.shear_mm = std::max(st.shear_mm, last_offset);
    }
    if (n_slices < 2) return st;
    std::vector<double> steps;
    for (size_t i = 1; i < n_slices; ++i) steps.push_back(st.along_mm[i] - st.along_mm[i - 1]);
    std::vector<double> sorted = steps;
    for (double& s : sorted) s = std::fabs(s);
    std::nth_element(sorted.begin(), sorted.begin() + long(sorted.size() / 2), sorted.end());
    const double median = sorted[sorted.size() / 2];
    auto fail = [&](size_t i, double expected, const std::string& why) {
        std::ostringstream m;
        const double base = dot(positions.front(), n);  // positions along the normal as the headers give them
        m << what << ": DICOM slices " << name(i) << " (at " << mm(base + st.along_mm[i], 7) << " mm) and " << name(i + 1)
          << " (at " << mm(base + st.along_mm[i + 1], 7) << " mm) are " << mm(steps[i])
          << " mm apart along the slice normal, expected " << mm(expected) << " mm like the slices beside them: "
          << why;
        throw IoError(m.str());
    };
    if (!(median > 0)) fail(0, 0, "the slices do not step along the slice normal");
    for (size_t i = 0; i < steps.size(); ++i) {
        if (std::fabs(steps[i]) < 0.01 * median) fail(i, median, "a slice is duplicated");
        if (steps[i] < 0) fail(i, median, "the slices are out of order along the slice normal");
    }
    // A real gap: a step >= 1.5 x its neighbours where they agree (inside a regular stack), or at
    // either end, close to a whole multiple >= 2 of its one neighbour.
    for (size_t i = 0; i < steps.size(); ++i) {
        const bool has_left = i > 0, has_right = i + 1 < steps.size();
        if (has_left && has_right) {
            const double l = steps[i - 1], r = steps[i + 1];
            if (std::fabs(l - r) <= 0.05 * std::max(l, r) && steps[i] >= 1.5 * std::max(l, r))
                fail(i, 0.5 * (l + r), "slices are missing");
        } else if (has_left || has_right) {
            const double nb = has_left ? steps[i - 1] : steps[i + 1];
            const double ratio = steps[i] / nb;
            if (ratio >= 1.5 && std::fabs(ratio - std::round(ratio)) <= 0.1) fail(i, nb, "slices are missing");
        }
    }
    // Runs of equal steps (within 5 % of the run's mean).
    SliceRun run{0, 2, steps[0]};
    for (size_t i = 1; i < steps.size(); ++i) {
        if (std::fabs(steps[i] - run.step_mm) <= 0.05 * run.step_mm) {
            run.step_mm = (run.step_mm * double(run.slices - 1) + steps[i]) / double(run.slices);
            ++run.slices;
        } else {
            st.runs.push_back(run);
            run = SliceRun{i, 2, steps[i]};
        }
    }
    st.runs.push_back(run);
    st.min_run_step_mm = 0;
    for (const SliceRun& r : st.runs)
        if (r.slices >= 3 && (st.min_run_step_mm == 0 || r.step_mm < st.min_run_step_mm)) st.min_run_step_mm = r.step_mm;
    if (st.min_run_step_mm == 0) st.min_run_step_mm = median;
    // Regular: every slice within a fifth of a step of the grid from the first to the last.
    const double mean = st.along_mm.back() / double(n_slices - 1);
    for (size_t k = 0; k < n_slices; ++k)
        if (std::fabs(st.along_mm[k] - double(k) * mean) > 0.2 * mean) st.regular = false;
    if (!st.regular && st.runs.size() > 1)
        for (const SliceRun& r : st.runs)
            st.changes.push_back(name(r.first) + " to " + name(r.first + r.slices - 1) + ": " +
                                 std::to_string(r.slices) + " slices " + mm(r.step_mm) + " mm apart");
    st.tilt_deg = std::atan2(last_offset, st.along_mm.back()) * 180.0 / M_PI;
    st.tilted = st.shear_mm > 0.1 * pixel_mm;
    if (!st.tilted) st.tilt_deg = 0;
    return st;
}

namespace {

// What resample_slice_stack needs of the geometry: the output grid and each slice's in-plane offset.
struct Plan {
    Geometry grid;
    std::vector<double> ou, ov;  ///< offset of slice k from the first along r and c (mm)
    double umin = 0, vmin = 0;
};

Plan plan(const Geometry& g, const std::vector<Vec3>& positions, const SliceStack& stack, const SliceResampling& p) {
    const int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
    if (int64_t(positions.size()) != nz || stack.along_mm.size() != positions.size() || nz < 2)
        throw IoError("resampling the slices: " + std::to_string(positions.size()) + " slice positions for " +
                      std::to_string(nz) + " slices, expected as many (at least 2)");
    const double sz = p.slice_spacing_mm > 0 ? p.slice_spacing_mm : stack.min_run_step_mm;
    if (!std::isfinite(sz) || !(sz > 0))
        throw InvalidParameter("slice spacing " + std::to_string(sz) + " mm, expected a finite value > 0");
    const auto& d = g.direction;
    const Vec3 r{d[0], d[3], d[6]}, c{d[1], d[4], d[7]};
    const Vec3 n = normalized(cross(r, c));
    Plan pl;
    pl.ou.resize(size_t(nz));
    pl.ov.resize(size_t(nz));
    double umax = 0, vmax = 0;
    for (int64_t k = 0; k < nz; ++k) {
        const Vec3 dk = sub(positions[size_t(k)], positions.front());
        pl.ou[size_t(k)] = dot(dk, r);
        pl.ov[size_t(k)] = dot(dk, c);
        pl.umin = std::min(pl.umin, pl.ou[size_t(k)]);
        umax = std::max(umax, pl.ou[size_t(k)]);
        pl.vmin = std::min(pl.vmin, pl.ov[size_t(k)]);
        vmax = std::max(vmax, pl.ov[size_t(k)]);
    }
    const double sx = g.spacing[0], sy = g.spacing[1];
    Geometry& o = pl.grid;
    o = g;
    // Each extent in voxels, checked before the cast: a sheared grid with a tiny spacing or far-apart
    // slices (a corrupt header) would overflow int64 here.
    auto extent = [&](double span_mm, double step_mm, int64_t n, const char* axis) {
        const double e = std::floor(span_mm / step_mm + 1e-6) + double(n);
        if (!std::isfinite(e) || e > double(int64_t{1} << 40))
            throw IoError("resampling the slices: they span " + std::to_string(span_mm) + " mm along " + axis +
                          " at a spacing of " + std::to_string(step_mm) +
                          " mm, expected a grid of at most 2^40 voxels per axis");
        return int64_t(e);
    };
    o.dims = {extent(umax - pl.umin, sx, nx, "the rows"), extent(vmax - pl.vmin, sy, ny, "the columns"),
              extent(stack.along_mm.back(), sz, 1, "the slice normal")};
    o.spacing = {sx, sy, sz};
    const Vec3& p0 = positions.front();
    for (int a = 0; a < 3; ++a) o.origin[a] = p0[a] + pl.umin * r[a] + pl.vmin * c[a];
    o.direction = {r[0], c[0], n[0], r[1], c[1], n[1], r[2], c[2], n[2]};
    return pl;
}

}  // namespace

Geometry resampled_geometry(const Geometry& g, const std::vector<Vec3>& positions, const SliceStack& stack,
                            const SliceResampling& p) {
    return plan(g, positions, stack, p).grid;
}

Volume<float> resample_slice_stack(const Volume<float>& v, const std::vector<Vec3>& positions,
                                   const SliceStack& stack, const SliceResampling& p) {
    const Geometry& g = v.geometry();
    const int64_t nx = g.dims[0], ny = g.dims[1];
    const Plan pl = plan(g, positions, stack, p);
    const Geometry& o = pl.grid;
    const std::vector<double>&ou = pl.ou, &ov = pl.ov;
    const double umin = pl.umin, vmin = pl.vmin, sx = o.spacing[0], sy = o.spacing[1], sz = o.spacing[2];
    const double span = stack.along_mm.back();
    Volume<float> out(o, p.outside);
    const std::vector<double>& along = stack.along_mm;
    auto sample = [&](int64_t k, double u, double w) -> double {  // bilinear in slice k, pixel units
        if (u < -1e-6 || w < -1e-6 || u > double(nx - 1) + 1e-6 || w > double(ny - 1) + 1e-6) return p.outside;
        u = std::clamp(u, 0.0, double(nx - 1));
        w = std::clamp(w, 0.0, double(ny - 1));
        const int64_t x0 = std::min<int64_t>(int64_t(u), nx - 2 < 0 ? 0 : nx - 2);
        const int64_t y0 = std::min<int64_t>(int64_t(w), ny - 2 < 0 ? 0 : ny - 2);
        const int64_t x1 = std::min(x0 + 1, nx - 1), y1 = std::min(y0 + 1, ny - 1);
        const double fx = u - double(x0), fy = w - double(y0);
        return (1 - fy) * ((1 - fx) * v(x0, y0, k) + fx * v(x1, y0, k)) + fy * ((1 - fx) * v(x0, y1, k) + fx * v(x1, y1, k));
    };
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t kz = 0; kz < o.dims[2]; ++kz) {
        const double a = std::min(double(kz) * sz, span);
        // The two slices around a (along is ascending).
        size_t k1 = size_t(std::upper_bound(along.begin(), along.end(), a) - along.begin());
        k1 = std::clamp<size_t>(k1, 1, along.size() - 1);
        const size_t k0 = k1 - 1;
        const double t = std::clamp((a - along[k0]) / (along[k1] - along[k0]), 0.0, 1.0);
        for (int64_t j = 0; j < o.dims[1]; ++j)
            for (int64_t i = 0; i < o.dims[0]; ++i) {
                const double U = umin + double(i) * sx, W = vmin + double(j) * sy;
                double val = 0;
                if (t < 1) val += (1 - t) * sample(int64_t(k0), (U - ou[k0]) / sx, (W - ov[k0]) / sy);
                if (t > 0) val += t * sample(int64_t(k1), (U - ou[k1]) / sx, (W - ov[k1]) / sy);
                out(i, j, kz) = float(val);
            }
    }
    return out;
}

}  // namespace endocast
