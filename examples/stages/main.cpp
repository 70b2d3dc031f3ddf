// The endocast method run stage by stage with the library's public functions, printing what each
// stage found (libendocast/src/method/pipeline.cpp runs the same sequence as extract_endocast()).
//
//   endocast_stages CT.nrrd [ISOVALUE [MESH.stl]]     (ISOVALUE "" = automatic)
//
// Stages: read -> binarize -> fill voids -> distance -> seeds -> watershed -> close openings ->
// polygonize -> measure (-> write).
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <exception>
#include <iomanip>
#include <iostream>
#include <stdexcept>
#include <sstream>
#include <string>

#include <endocast/stages/binarize.h>
#include <endocast/stages/distance.h>
#include <endocast/io.h>
#include <endocast/stages/polygonize.h>
#include <endocast/stages/morphology.h>
#include <endocast/stages/openings.h>
#include <endocast/stages/seeds.h>
#include <endocast/stages/watershed.h>
#include <meshpost/io.h>
#include <meshpost/measure.h>
#include <meshpost/topology.h>

namespace {

/// Prints "stage: <what>  (<seconds> s)" and restarts the clock.
class StageLog {
public:
    void operator()(const std::string& stage, const std::string& what) {
        const auto now = std::chrono::steady_clock::now();
        std::cout << std::left << std::setw(11) << stage << what << "  ("
                  << std::fixed << std::setprecision(2)
                  << std::chrono::duration<double>(now - last_).count() << " s)\n";
        std::cout.unsetf(std::ios::floatfield);
        last_ = now;
    }

private:
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

double parse_number(const std::string& s) {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (end == s.c_str() || *end) throw std::invalid_argument("ISOVALUE '" + s + "' is not a number");
    return v;
}

/// `v` with `digits` decimals.
std::string num(double v, int digits = 1) {
    std::ostringstream s;
    s << std::fixed << std::setprecision(digits) << v;
    return s.str();
}

size_t count(const endocast::Volume<uint8_t>& v, uint8_t value) {
    size_t n = 0;
    for (size_t i = 0; i < v.size(); ++i) n += v[i] == value;
    return n;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::cerr << "usage: endocast_stages CT.nrrd [ISOVALUE (\"\" = automatic) [MESH.stl]]\n";
        return 2;
    }
    try {
        using namespace endocast;
        StageLog log;

        const ReadResult in = read_volume({argv[1]});
        const Volume<float>& ct = in.volume;
        const Geometry& g = ct.geometry();
        log("read", in.info.format + ", " + std::to_string(g.dims[0]) + " x " + std::to_string(g.dims[1]) +
                        " x " + std::to_string(g.dims[2]) + " voxels");

        BinarizeParams bp;
        if (argc > 2 && *argv[2]) bp.isovalue = parse_number(argv[2]);  // "" = automatic
        BinarizeResult bin = binarize(ct, bp);
        log("binarize", "isovalue " + num(bin.isovalue) + " (" + bin.isovalue_rule + "), " +
                            std::to_string(bin.bone_voxels) + " bone voxels");

        const VoidFillResult filled = fill_voids(bin.bone, VoidFillParams{});
        log("fill", "ball radius " + num(filled.radius_mm) + " mm, " +
                        std::to_string(filled.filled_voxels) + " voxels filled");

        const Volume<float> dist = distance_transform(filled.bone);
        float deepest = 0;
        for (size_t i = 0; i < dist.size(); ++i) deepest = std::max(deepest, dist[i]);
        log("distance", "deepest empty voxel " + num(deepest) + " mm from bone");

        SeedResult seeds = place_seeds(filled.bone, dist, SeedParams{});
        log("seeds", std::to_string(seeds.endocast_seed_voxels) + " endocast and " +
                         std::to_string(seeds.other_seed_voxels) + " other seed voxels, " +
                         std::to_string(seeds.candidates.size()) + " candidate cavities");

        WatershedResult ws = watershed(seeds.labels, dist, WatershedParams{});
        log("watershed", std::to_string(ws.endocast_voxels) + " endocast voxels, " +
                             std::to_string(ws.other_voxels) + " other");

        const OpeningsResult op = close_openings(ws.labels, filled.bone, dist, OpeningParams{});
        log("openings", std::to_string(op.openings.size()) + " closed, " +
                            std::to_string(count(ws.labels, kEndocast)) + " endocast voxels left");

        PolygonizeParams pp;
        pp.isovalue = bin.isovalue;
        const PolygonizeResult poly = polygonize(ct, ws.labels, pp);
        log("polygonize", std::to_string(poly.mesh.vertices.size()) + " vertices, " +
                              std::to_string(poly.mesh.faces.size()) + " faces");

        const meshpost::TopologyReport topo = meshpost::analyze_topology(poly.mesh);
        log("measure", "ECV " + num(meshpost::signed_volume_mm3(poly.mesh) / 1000.0, 2) +
                           " mL, area " + num(meshpost::surface_area_mm2(poly.mesh), 0) +
                           " mm^2, closed 2-manifold " +
                           (meshpost::is_closed_manifold(topo) ? "yes" : "NO") + ", genus " +
                           std::to_string(topo.genus));

        if (argc > 3) {
            meshpost::write_mesh(poly.mesh, argv[3]);
            log("write", argv[3]);
        }
        for (const endocast::Warning& w : seeds.warnings) std::cerr << "warning (" << w.code << "): " << w.message << "\n";
        return meshpost::is_closed_manifold(topo) ? EXIT_SUCCESS : EXIT_FAILURE;
    } catch (const std::exception& e) {
        std::cerr << "endocast_stages: " << e.what() << "\n";
        return EXIT_FAILURE;
    }
}
