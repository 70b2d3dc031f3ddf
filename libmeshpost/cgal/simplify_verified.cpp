// simplify() with checks and stricter retries (see simplify_verified.h).
#include "meshpost/simplify_verified.h"

#include <algorithm>
#include <vector>

#include "meshpost/self_intersections.h"

namespace meshpost {

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
