// simplify() with checks, local repairs and stricter retries (see simplify_verified.h).
#include "meshpost/cgal/simplify_verified.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <vector>

#include "meshpost/cgal/self_intersections.h"

namespace meshpost {

namespace {

double mean_edge_length(const TriangleMesh& m) {
    double sum = 0;
    size_t n = 0;
    for (const Face& f : m.faces)
        for (int k = 0; k < 3; ++k) {
            const Point& a = m.vertices[f[k]];
            const Point& b = m.vertices[f[(k + 1) % 3]];
            sum += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                             (a[2] - b[2]) * (a[2] - b[2]));
            ++n;
        }
    return n ? sum / double(n) : 1.0;
}

// Locks (in `locked`) every input vertex within `radius` of a vertex of an intersecting face of
// `result`; returns how many were newly locked. A uniform grid of cell `radius` finds them.
size_t lock_around(const TriangleMesh& input, const TriangleMesh& result,
                   const SelfIntersectionReport& si, double radius, std::vector<uint8_t>& locked) {
    auto cell = [&](const Point& p) {
        return std::array<int64_t, 3>{int64_t(std::floor(p[0] / radius)), int64_t(std::floor(p[1] / radius)),
                                      int64_t(std::floor(p[2] / radius))};
    };
    std::map<std::array<int64_t, 3>, std::vector<uint32_t>> grid;
    for (uint32_t v = 0; v < input.vertices.size(); ++v) grid[cell(input.vertices[v])].push_back(v);
    size_t added = 0;
    const double r2 = radius * radius;
    for (const auto& pr : si.examples)
        for (size_t f : {pr.first, pr.second})
            for (uint32_t rv : result.faces[f]) {
                const Point& p = result.vertices[rv];
                const auto c = cell(p);
                for (int dz = -1; dz <= 1; ++dz)
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const auto it = grid.find({c[0] + dx, c[1] + dy, c[2] + dz});
                            if (it == grid.end()) continue;
                            for (uint32_t v : it->second) {
                                const Point& q = input.vertices[v];
                                const double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                                                  (p[2] - q[2]) * (p[2] - q[2]);
                                if (d2 <= r2 && !locked[v]) {
                                    locked[v] = 1;
                                    ++added;
                                }
                            }
                        }
            }
    return added;
}

}  // namespace

void repair_locally(const TriangleMesh& mesh, const SimplifyParams& p, VerifiedSimplifyResult& v) {
    SimplifyParams q = p;
    if (q.locked_vertices.empty()) q.locked_vertices.assign(mesh.vertices.size(), 0);
    const double edge = mean_edge_length(mesh);
    for (double k : {3.0, 6.0, 12.0, 24.0}) {
        const SelfIntersectionReport si = find_self_intersections(v.simplified.mesh, size_t(-1));
        lock_around(mesh, v.simplified.mesh, si, k * edge, q.locked_vertices);
        ++v.repair_rounds;
        SimplifyResult again = simplify(mesh, q);
        const TopologyReport t = analyze_topology(again.mesh);
        const TopologyReport& b = v.topology_before;
        if (t.closed != b.closed || !t.manifold || t.oriented != b.oriented ||
            t.components != b.components || t.genus != b.genus || t.degenerate_faces > 0)
            continue;  // keep locking more around the last clean-topology result's intersections
        v.simplified = std::move(again);
        v.topology_after = t;
        v.self_intersections_after = find_self_intersections(v.simplified.mesh).intersecting_pairs;
        v.locked_vertices = size_t(std::count(q.locked_vertices.begin(), q.locked_vertices.end(), 1));
        if (v.self_intersections_after <= v.self_intersections_before) return;
    }
}

VerifiedSimplifyResult simplify_verified(const TriangleMesh& mesh, const SimplifyParams& params) {
    VerifiedSimplifyResult v;
    v.topology_before = analyze_topology(mesh);
    bool before_known = false;  // the input's count is only needed when a result has some

    std::vector<SimplifyParams> schedule{params};
    auto stricter = [&](double deg, double aspect) {
        SimplifyParams p = params;
        p.max_normal_deviation_deg = std::min(params.max_normal_deviation_deg, deg);
        if (aspect > 0) p.max_aspect_ratio = params.max_aspect_ratio > 0 ? std::min(params.max_aspect_ratio, aspect) : aspect;
        schedule.push_back(p);
    };
    stricter(30, 0);
    stricter(15, 30);
    stricter(8, 10);

    const TopologyReport& b = v.topology_before;
    for (const SimplifyParams& p : schedule) {
        ++v.attempts;
        v.used = p;
        v.simplified = simplify(mesh, p);
        v.topology_after = analyze_topology(v.simplified.mesh);
        const TopologyReport& a = v.topology_after;
        v.failure.clear();
        if (a.closed != b.closed) v.failure = "closedness changed";
        else if (!a.manifold) v.failure = "not manifold";
        else if (a.oriented != b.oriented) v.failure = "orientation changed";
        else if (a.components != b.components) v.failure = "component count changed";
        else if (a.genus != b.genus) v.failure = "genus changed";
        else if (a.degenerate_faces > 0) v.failure = std::to_string(a.degenerate_faces) + " degenerate faces";
        if (v.failure.empty()) {
            v.self_intersections_after = find_self_intersections(v.simplified.mesh).intersecting_pairs;
            if (v.self_intersections_after > 0 && !before_known) {
                v.self_intersections_before = find_self_intersections(mesh).intersecting_pairs;
                before_known = true;
            }
            // Local repair: lock the input around the intersecting faces and simplify again, so
            // one bad spot does not force stricter guards on the whole mesh.
            if (v.self_intersections_after > v.self_intersections_before)
                repair_locally(mesh, p, v);
            if (v.self_intersections_after > v.self_intersections_before)
                v.failure = std::to_string(v.self_intersections_after) + " self-intersecting face pairs";
        }
        if (v.failure.empty()) {
            v.clean = true;
            break;
        }
    }
    return v;
}

}  // namespace meshpost
