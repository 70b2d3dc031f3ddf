#pragma once
// The Freudenthal (Kuhn) triangulation of the voxel grid that isosurface() contours: each cube split
// into six tetrahedra along its main diagonal, so a grid point has 14 neighbours (the offsets in
// {0,1}^3 and their negatives). The mesh around a set of voxels below the level is the boundary of
// that set's full subcomplex; these helpers decide its topology voxel by voxel.
#include <array>
#include <cstdint>
#include <cstdlib>

#include "endocast/volume.h"

namespace endocast {

// Adding a voxel v keeps the topology of the set (and so of its mesh) iff the set's part of v's
// link (a triangulated sphere on the 14 neighbours, two of them joined when they are neighbours
// too) and the rest of the link are both non-empty and connected: v is a simple point.
class FreudenthalLink {
public:
    FreudenthalLink(int64_t nx, int64_t ny) {
        int k = 0;
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    if (!neighbour(dx, dy, dz)) continue;
                    d_[k][0] = dx, d_[k][1] = dy, d_[k][2] = dz;
                    step_[k++] = dx + nx * (dy + ny * dz);
                }
        for (int a = 0; a < 14; ++a) {
            adj_[a] = 0;
            for (int b = 0; b < 14; ++b)
                if (a != b && neighbour(d_[b][0] - d_[a][0], d_[b][1] - d_[a][1], d_[b][2] - d_[a][2]))
                    adj_[a] |= uint16_t(1u << b);
        }
    }

    /// Index offset of neighbour k (0..13) in a grid of nx x ny x ...
    int64_t step(int k) const { return step_[k]; }

    // Whether setting mask voxel w (unset, not on the border) keeps the topology of the set: the
    // answer for each of the 2^14 configurations of the link, from a table built once.
    bool simple(const Volume<uint8_t>& mask, size_t w) const {
        unsigned in = 0;
        for (int k = 0; k < 14; ++k) in |= unsigned(mask[size_t(int64_t(w) + step_[k])] != 0) << k;
        return (simple_table()[in >> 3] >> (in & 7)) & 1;
    }

    // The test itself, for one configuration (bit k: neighbour k in the set).
    bool simple_config(uint16_t in) const {
        const uint16_t out = uint16_t(~in & 0x3FFF);
        return in && out && connected(in) && connected(out);
    }

private:
    // Bit c of the table: simple_config(c). The link's adjacency does not depend on the grid's
    // size (only the offsets do), so one table serves every FreudenthalLink.
    static const uint8_t* simple_table() {
        static const std::array<uint8_t, (1u << 14) / 8> table = [] {
            const FreudenthalLink any(3, 3);
            std::array<uint8_t, (1u << 14) / 8> t{};
            for (unsigned c = 0; c < (1u << 14); ++c)
                if (any.simple_config(uint16_t(c))) t[c >> 3] = uint8_t(t[c >> 3] | (1u << (c & 7)));
            return t;
        }();
        return table.data();
    }

    static bool neighbour(int dx, int dy, int dz) {
        if (!dx && !dy && !dz) return false;
        const bool up = dx >= 0 && dy >= 0 && dz >= 0, down = dx <= 0 && dy <= 0 && dz <= 0;
        return (up || down) && std::abs(dx) <= 1 && std::abs(dy) <= 1 && std::abs(dz) <= 1;
    }
    bool connected(uint16_t set) const {
        uint16_t reached = uint16_t(set & -set), frontier = reached;
        while (frontier) {
            uint16_t next = 0;
            for (int k = 0; k < 14; ++k)
                if (frontier & (1u << k)) next |= adj_[k];
            frontier = uint16_t(next & set & ~reached);
            reached |= frontier;
        }
        return reached == set;
    }

    int d_[14][3];
    int64_t step_[14];
    uint16_t adj_[14];
};

}  // namespace endocast
