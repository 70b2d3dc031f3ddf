// Binary morphology with exact Euclidean balls from distance transforms, and the void fill (morphology.h).
#include "endocast/stages/morphology.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "endocast/stages/distance.h"

namespace endocast {

double ball_squared_radius(double r) { return r * r * (1.0 + 1e-6) + 1e-9; }

namespace {


void check_radius(double r, const char* what) {
    if (!std::isfinite(r) || r < 0)
        throw InvalidParameter(std::string(what) + ": ball radius " + std::to_string(r) +
                               " mm, expected a finite value >= 0");
}

}  // namespace

Volume<uint8_t> dilate_ball(const Volume<uint8_t>& mask, double radius_mm) {
    check_radius(radius_mm, "dilate_ball");
    const float r2 = static_cast<float>(ball_squared_radius(radius_mm));
    const Volume<float> d2 = squared_distance_transform_clamped(mask, false, r2);
    Volume<uint8_t> out(mask.geometry());
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(out.size()); ++i) out[i] = d2[i] <= r2 ? 1 : 0;
    return out;
}

Volume<uint8_t> erode_ball(const Volume<uint8_t>& mask, double radius_mm) {
    check_radius(radius_mm, "erode_ball");
    // Distance to the background (zero voxels), clamped above r^2: no background copy.
    const float r2 = static_cast<float>(ball_squared_radius(radius_mm));
    const Volume<float> d2 = squared_distance_transform_clamped(mask, true, r2);
    Volume<uint8_t> out(mask.geometry());
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < int64_t(out.size()); ++i) out[i] = d2[i] > r2 ? 1 : 0;
    return out;
}

Volume<uint8_t> close_ball(const Volume<uint8_t>& mask, double radius_mm) {
    return erode_ball(dilate_ball(mask, radius_mm), radius_mm);
}

Volume<uint8_t> close_ball(const Volume<uint8_t>& mask, double radius_mm, const WalledFaces& walls) {
    check_radius(radius_mm, "close_ball");
    if (std::none_of(walls.begin(), walls.end(), [](bool w) { return w; })) return close_ball(mask, radius_mm);
    // The mask padded with foreground on the walled faces, as deep as the ball (and a voxel).
    const Geometry& g = mask.geometry();
    int64_t lo[3], hi[3];
    Geometry pg = g;
    for (size_t a = 0; a < 3; ++a) {
        const int64_t m = int64_t(std::ceil(radius_mm / g.spacing[a])) + 1;
        lo[a] = walls[2 * a] ? m : 0;
        hi[a] = walls[2 * a + 1] ? m : 0;
        pg.dims[a] = g.dims[a] + lo[a] + hi[a];
    }
    Volume<uint8_t> padded(pg, 1);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) padded(x + lo[0], y + lo[1], z + lo[2]) = mask(x, y, z);
    const Volume<uint8_t> closed = close_ball(padded, radius_mm);
    Volume<uint8_t> out(g, 0);
#pragma omp parallel for schedule(static)
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) out(x, y, z) = closed(x + lo[0], y + lo[1], z + lo[2]);
    return out;
}

double void_fill_radius_mm(const VoidFillParams& p, const Geometry& g) {
    if (p.radius_mm) return *p.radius_mm;
    const double smin = g.smallest_spacing();
    return p.radius_voxels * smin;
}

VoidFillResult fill_voids(const Volume<uint8_t>& bone, const VoidFillParams& p) {
    if (!p.radius_mm && (!std::isfinite(p.radius_voxels) || p.radius_voxels < 0))
        throw InvalidParameter("void fill radius " + std::to_string(p.radius_voxels) +
                               " voxels, expected a finite value >= 0");
    VoidFillResult r;
    r.radius_mm = void_fill_radius_mm(p, bone.geometry());
    check_radius(r.radius_mm, "fill_voids");
    if (r.radius_mm == 0) {
        r.bone = bone;
        return r;
    }
    for (double k : p.keep_dilations_mm)
        if (!std::isfinite(k) || k < 0 || k > r.radius_mm)
            throw InvalidParameter("fill_voids: dilation radius " + std::to_string(k) + " mm to keep, expected within [0, " +
                                   std::to_string(r.radius_mm) + "] (the fill's radius)");
    {
        // close_ball, with the dilations asked for read off the same transform: its values up to the
        // clamp are exact, and a smaller ball's threshold lies below it.
        // One pass over the transform: bit 0 of `dilated` is the fill's dilation, bit 1 + k the
        // k-th kept one (inside the first: non-zero is the fill's dilation, as erode_ball reads it).
        const float R2 = static_cast<float>(ball_squared_radius(r.radius_mm));
        Volume<float> d2 = squared_distance_transform_clamped(bone, false, R2);
        const size_t K = std::min<size_t>(p.keep_dilations_mm.size(), 7);
        std::array<float, 7> k2{};
        for (size_t k = 0; k < K; ++k) k2[k] = static_cast<float>(ball_squared_radius(p.keep_dilations_mm[k]));
        Volume<uint8_t> dilated(bone.geometry());
#pragma omp parallel for schedule(static)
        for (int64_t i = 0; i < int64_t(dilated.size()); ++i) {
            const float v = d2[i];
            uint8_t bits = v <= R2 ? 1 : 0;
            for (size_t k = 0; k < K; ++k) bits |= uint8_t(v <= k2[k] ? 2u << k : 0u);
            dilated[i] = bits;
        }
        for (size_t k = 0; k < p.keep_dilations_mm.size(); ++k) {
            if (k < K) {
                r.dilations.push_back(PackedMask::where(bone.geometry(), [&](size_t i) { return (dilated[i] >> (k + 1)) & 1u; }));
            } else {  // more than seven asked: from the transform
                const float kk = static_cast<float>(ball_squared_radius(p.keep_dilations_mm[k]));
                r.dilations.push_back(PackedMask::where(bone.geometry(), [&](size_t i) { return d2[i] <= kk; }));
            }
        }
        d2 = Volume<float>();
        r.bone = erode_ball(dilated, r.radius_mm);
    }
    size_t filled = 0;
#pragma omp parallel for schedule(static) reduction(+ : filled)
    for (int64_t i = 0; i < int64_t(bone.size()); ++i) {
        if (bone[i]) {
            r.bone[i] = 1;  // closing is extensive already; kept explicit for clarity
        } else if (r.bone[i]) {
            ++filled;
        }
    }
    r.filled_voxels = filled;
    return r;
}

}  // namespace endocast
