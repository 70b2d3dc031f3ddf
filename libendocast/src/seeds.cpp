#include "endocast/seeds.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "endocast/components.h"
#include "endocast/distance.h"

namespace endocast {
namespace {

std::string fmt(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

bool on_face(const Dims& d, int64_t x, int64_t y, int64_t z) {
    return x == 0 || y == 0 || z == 0 || x == d[0] - 1 || y == d[1] - 1 || z == d[2] - 1;
}

// Marks as kOther every empty voxel within scale*d(b) of an empty face voxel b.
size_t border_seeds(Volume<uint8_t>& labels, const Volume<float>& distance, double scale) {
    const Geometry& g = labels.geometry();
    const Dims& dm = g.dims;
    std::vector<float> f(labels.size(), std::numeric_limits<float>::infinity());
    for (int64_t z = 0; z < dm[2]; ++z)
        for (int64_t y = 0; y < dm[1]; ++y)
            for (int64_t x = 0; x < dm[0]; ++x) {
                if (!on_face(dm, x, y, z)) {
                    // jump to the far face on interior rows
                    if (x == 0) continue;
                    x = dm[0] - 2;
                    continue;
                }
                const size_t i = labels.index(x, y, z);
                if (labels[i] == kBone) continue;
                const double r = scale * distance[i];
                f[i] = static_cast<float>(-(r * r));
            }
    generalized_squared_distance(f, g);
    size_t n = 0;
    for (size_t i = 0; i < labels.size(); ++i)
        if (f[i] <= 0.0f && labels[i] != kBone) {
            labels[i] = kOther;
            ++n;
        }
    return n;
}

// Marks as kEndocast the unlabelled voxels within radius r (mm) of voxel c.
// With `override_other`, "other" seed voxels inside the ball become endocast too.
size_t ball_seed(Volume<uint8_t>& labels, const std::array<int64_t, 3>& c, double r,
                 bool override_other) {
    const Geometry& g = labels.geometry();
    const double r2 = r * r * (1.0 + 1e-9);
    std::array<int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        const int64_t ext = int64_t(std::floor(r / g.spacing[a]));
        lo[a] = std::max<int64_t>(0, c[a] - ext);
        hi[a] = std::min<int64_t>(g.dims[a] - 1, c[a] + ext);
    }
    size_t n = 0;
    for (int64_t z = lo[2]; z <= hi[2]; ++z)
        for (int64_t y = lo[1]; y <= hi[1]; ++y)
            for (int64_t x = lo[0]; x <= hi[0]; ++x) {
                const double dx = double(x - c[0]) * g.spacing[0];
                const double dy = double(y - c[1]) * g.spacing[1];
                const double dz = double(z - c[2]) * g.spacing[2];
                if (dx * dx + dy * dy + dz * dz > r2) continue;
                uint8_t& l = labels(x, y, z);
                if (l == kUnlabelled || (override_other && l == kOther)) {
                    l = kEndocast;
                    ++n;
                }
            }
    return n;
}

std::array<int64_t, 3> coords(const Geometry& g, size_t i) {
    const int64_t nx = g.dims[0], ny = g.dims[1];
    return {int64_t(i % size_t(nx)), int64_t((i / size_t(nx)) % size_t(ny)),
            int64_t(i / size_t(nx * ny))};
}

}  // namespace

SeedMode parse_seed_mode(const std::string& s) {
    if (s == "auto") return SeedMode::Auto;
    if (s == "distance") return SeedMode::Distance;
    if (s == "point") return SeedMode::Point;
    throw InvalidParameter("seed mode '" + s + "', expected auto, distance or point");
}

std::string to_string(SeedMode m) {
    switch (m) {
        case SeedMode::Auto: return "auto";
        case SeedMode::Distance: return "distance";
        case SeedMode::Point: return "point";
    }
    return "?";
}

SeedResult place_seeds(const Volume<uint8_t>& bone, const Volume<float>& distance,
                       const SeedParams& p) {
    if (!(p.scale > 0 && p.scale < 1))
        throw InvalidParameter("seed scale " + fmt(p.scale) + ", expected 0 < s < 1");
    if (bone.size() != distance.size())
        throw InvalidParameter("place_seeds: bone and distance volumes differ in size");
    const Geometry& g = bone.geometry();
    SeedResult r;
    r.labels = Volume<uint8_t>(g);
    for (size_t i = 0; i < bone.size(); ++i) r.labels[i] = bone[i] ? kBone : kUnlabelled;

    if (p.mode == SeedMode::Distance) {
        if (!(p.distance_threshold_mm > 0) || !std::isfinite(p.distance_threshold_mm))
            throw InvalidParameter("distance threshold " + fmt(p.distance_threshold_mm) +
                                   " mm, expected > 0 (use --distance-threshold MM)");
        Volume<uint8_t> above(g);
        for (size_t i = 0; i < above.size(); ++i)
            above[i] = (!bone[i] && distance[i] >= p.distance_threshold_mm) ? 1 : 0;
        const Components comp = connected_components(above, Connectivity::Face6);
        size_t best = 0, best_size = 0;
        for (size_t k = 0; k < comp.sizes.size(); ++k)
            if (!comp.touches_border[k] && comp.sizes[k] > best_size) {
                best = k + 1;
                best_size = comp.sizes[k];
            }
        if (best == 0)
            throw NoResult("no empty region with distance >= " + fmt(p.distance_threshold_mm) +
                           " mm is enclosed away from the volume border: expected the braincase; "
                           "try a smaller --distance-threshold");
        size_t centre = 0;
        float dmax = -1;
        for (size_t i = 0; i < above.size(); ++i) {
            const uint32_t l = comp.labels[i];
            if (!l) continue;
            if (l == best) {
                r.labels[i] = kEndocast;
                ++r.endocast_seed_voxels;
                if (distance[i] > dmax) {
                    dmax = distance[i];
                    centre = i;
                }
            } else if (comp.touches_border[l - 1]) {
                r.labels[i] = kOther;
                ++r.other_seed_voxels;
            }
        }
        // Border voxels are always "other": a flood must have somewhere to come from outside.
        r.other_seed_voxels += border_seeds(r.labels, distance, p.scale);
        const auto c = coords(g, centre);
        r.endocast_seeds_world.push_back(g.index_to_world(double(c[0]), double(c[1]), double(c[2])));
        r.endocast_seed_radii_mm.push_back(dmax);
        r.endocast_seed_distance_mm = dmax;
        return r;
    }

    r.other_seed_voxels = border_seeds(r.labels, distance, p.scale);

    std::vector<size_t> centres;
    if (p.mode == SeedMode::Auto) {
        size_t best = size_t(-1);
        float dmax = 0;
        for (size_t i = 0; i < bone.size(); ++i)
            if (r.labels[i] == kUnlabelled && distance[i] > dmax) {
                dmax = distance[i];
                best = i;
            }
        if (best == size_t(-1))
            throw NoResult("no empty space is left away from the volume border once the border "
                           "seeds are placed: expected an enclosed braincase (is the skull open "
                           "to the border, or the isovalue too high?)");
        centres.push_back(best);
    } else {
        if (p.points_world.empty())
            throw InvalidParameter("seed mode point needs at least one --seed-point X Y Z (mm)");
        for (const Vec3& w : p.points_world) {
            const Vec3 idx = g.world_to_index(w);
            std::array<int64_t, 3> c{};
            for (int a = 0; a < 3; ++a) c[a] = std::llround(idx[a]);
            if (!bone.contains(c[0], c[1], c[2]))
                throw InvalidParameter("seed point (" + fmt(w[0]) + ", " + fmt(w[1]) + ", " +
                                       fmt(w[2]) + ") mm lies outside the volume (index " +
                                       fmt(idx[0]) + ", " + fmt(idx[1]) + ", " + fmt(idx[2]) + ")");
            const size_t i = bone.index(c[0], c[1], c[2]);
            if (bone[i])
                throw InvalidParameter("seed point (" + fmt(w[0]) + ", " + fmt(w[1]) + ", " +
                                       fmt(w[2]) + ") mm lies in bone: expected a point inside "
                                       "the braincase");
            centres.push_back(i);
        }
    }
    for (size_t i : centres) {
        const auto c = coords(g, i);
        const double radius = p.scale * distance[i];
        // A user's point wins over the border rule; the automatic centre never overlaps it.
        const bool override_other = p.mode == SeedMode::Point;
        r.endocast_seed_voxels += ball_seed(r.labels, c, radius, override_other);
        r.endocast_seeds_world.push_back(g.index_to_world(double(c[0]), double(c[1]), double(c[2])));
        r.endocast_seed_radii_mm.push_back(radius);
    }
    r.endocast_seed_distance_mm = distance[centres.front()];
    r.other_seed_voxels = size_t(std::count(r.labels.buffer().begin(), r.labels.buffer().end(), kOther));
    if (r.endocast_seed_voxels == 0) throw NoResult("the endocast seed is empty");
    return r;
}

}  // namespace endocast
