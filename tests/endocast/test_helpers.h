#pragma once
// Small volumes for kernel tests (random masks, spheres, shells), and scratch directories and
// exception messages for the reader tests.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "endocast/volume.h"
#include "meshpost/mesh.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"

namespace endocast::testing {

/// A fresh, empty directory under the gtest temp dir (named after the process and `name`),
/// removed with everything in it at the end of its scope.
class ScratchDir {
public:
    explicit ScratchDir(const std::string& name)
        : path_(std::filesystem::path(::testing::TempDir()) /
                ("endocast_" + std::to_string(::getpid()) + "_" + name)) {
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~ScratchDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    ScratchDir(const ScratchDir&) = delete;
    ScratchDir& operator=(const ScratchDir&) = delete;
    const std::filesystem::path& path() const { return path_; }
    std::string str() const { return path_.string(); }
    std::string operator/(const std::string& f) const { return (path_ / f).string(); }
    /// The names in it, sorted.
    std::vector<std::string> entries() const {
        std::vector<std::string> out;
        for (const auto& e : std::filesystem::directory_iterator(path_)) out.push_back(e.path().filename().string());
        std::sort(out.begin(), out.end());
        return out;
    }

private:
    std::filesystem::path path_;
};

/// The message of the E that f() throws; a test failure (and "") when it throws nothing or
/// something else.
template <class E, class F>
std::string error_of(F f) {
    try {
        f();
    } catch (const E& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
        return "";
    }
    ADD_FAILURE() << "no exception";
    return "";
}

// A phantom's CT (int16 HU) as a float volume: endocast::to_float (volume.h).
using endocast::to_float;

/// A third of the area of each face around each vertex (mm^2): weights for surface averages.
inline std::vector<double> vertex_areas(const meshpost::TriangleMesh& m) {
    std::vector<double> w(m.vertices.size(), 0.0);
    for (const auto& f : m.faces) {
        const auto& a = m.vertices[f[0]];
        const auto& b = m.vertices[f[1]];
        const auto& c = m.vertices[f[2]];
        const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
        const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
        const double area = 0.5 * std::sqrt(std::pow(uy * vz - uz * vy, 2) + std::pow(uz * vx - ux * vz, 2) +
                                            std::pow(ux * vy - uy * vx, 2));
        for (uint32_t v : f) w[v] += area / 3;
    }
    return w;
}

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

/// A closed, clean 2-manifold of one component and genus 0, without self-intersections.
inline void expect_clean_genus0(const meshpost::TriangleMesh& m) {
    const auto t = meshpost::analyze_topology(m);
    EXPECT_TRUE(meshpost::is_closed_manifold(t));
    EXPECT_EQ(t.components, 1u);
    EXPECT_EQ(t.genus, 0);
    EXPECT_EQ(t.degenerate_faces, 0u);
    EXPECT_EQ(meshpost::find_self_intersections(m).intersecting_pairs, 0u);
}

/// A 30^3 volume of bone (CT 1000) holding a cube of air (-1000, voxels 5..24) whose lower half
/// (z < 15) is labelled "other" and upper half endocast.
inline void half_other_cavity(Volume<float>& ct, Volume<uint8_t>& labels) {
    const Geometry g = grid(30, 30, 30);
    ct = Volume<float>(g, 1000.0f);
    labels = Volume<uint8_t>(g, kBone);
    for (int64_t z = 5; z < 25; ++z)
        for (int64_t y = 5; y < 25; ++y)
            for (int64_t x = 5; x < 25; ++x) {
                ct(x, y, z) = -1000;
                labels(x, y, z) = z >= 15 ? kEndocast : kOther;
            }
}

}  // namespace endocast::testing
