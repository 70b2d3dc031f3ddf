#pragma once
// Small volumes for kernel tests: random masks, spheres, shells.
#include <cstdint>
#include <random>

#include "endocast/volume.h"

namespace endocast::testing {

inline Geometry grid(int64_t nx, int64_t ny, int64_t nz, Vec3 spacing = {1, 1, 1}) {
    Geometry g;
    g.dims = {nx, ny, nz};
    g.spacing = spacing;
    return g;
}

inline Volume<uint8_t> random_mask(const Geometry& g, double density, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    Volume<uint8_t> v(g);
    for (size_t i = 0; i < v.size(); ++i) v[i] = u(rng) < density ? 1 : 0;
    return v;
}

/// Shell of bone between radii r_in and r_out (mm) around the centre of the grid; 1 = bone.
inline Volume<uint8_t> shell(const Geometry& g, double r_in, double r_out) {
    Volume<uint8_t> v(g);
    const double cx = (g.dims[0] - 1) / 2.0, cy = (g.dims[1] - 1) / 2.0, cz = (g.dims[2] - 1) / 2.0;
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                const double dx = (x - cx) * g.spacing[0], dy = (y - cy) * g.spacing[1],
                             dz = (z - cz) * g.spacing[2];
                const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
                v(x, y, z) = (r >= r_in && r <= r_out) ? 1 : 0;
            }
    return v;
}

}  // namespace endocast::testing
