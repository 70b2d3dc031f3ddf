// `endocast inspect`: is a mesh a clean closed 2-manifold? Topology, self-intersections, volume.
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "meshpost/io.h"
#include "meshpost/measure.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"

namespace endocast::cli {
namespace {

struct InspectOptions {
    std::string input, json;
};

/// A defect found in the mesh: a short code (JSON) and a sentence (stdout).
struct Defect {
    std::string code, text;
};

int run_inspect(const InspectOptions& o, const GlobalOptions& g) {
    const meshpost::TriangleMesh mesh = meshpost::read_mesh(o.input);
    const meshpost::TopologyReport t = meshpost::analyze_topology(mesh);
    const meshpost::SelfIntersectionReport si = meshpost::find_self_intersections(mesh);
    const double volume = meshpost::signed_volume_mm3(mesh);
    const double area = meshpost::surface_area_mm2(mesh);
    const meshpost::BoundingBox box = meshpost::bounding_box(mesh);
    // Outward: a closed surface without inconsistently oriented edges enclosing positive volume.
    const bool consistent = t.inconsistent_edges == 0 && t.faces > 0;
    const bool outward = t.closed && consistent && volume > 0;

    std::vector<Defect> defects;
    auto n = [](size_t k, const char* what) { return std::to_string(k) + " " + what; };
    if (t.faces == 0) defects.push_back({"no_faces", "the mesh has no faces"});
    if (t.boundary_edges > 0)
        defects.push_back({"hole", "hole: " + n(t.boundary_edges, "boundary edges") + " (not closed)"});
    if (t.nonmanifold_edges > 0)
        defects.push_back({"nonmanifold_edge", "non-manifold edge: " + n(t.nonmanifold_edges, "edges with more than two faces")});
    if (t.nonmanifold_vertices > 0)
        defects.push_back({"nonmanifold_vertex", "non-manifold vertex: " + n(t.nonmanifold_vertices, "vertices whose faces form several fans")});
    if (t.inconsistent_edges > 0)
        defects.push_back({"flipped_face", "flipped face: " + n(t.inconsistent_edges, "edges whose two faces disagree in orientation")});
    if (t.closed && consistent && !(volume > 0))
        defects.push_back({"inward", "inward orientation: the faces point inward (signed volume " +
                                         std::to_string(volume / 1000.0) + " mL)"});
    if (t.degenerate_faces > 0)
        defects.push_back({"degenerate_face", "degenerate face: " + n(t.degenerate_faces, "faces with zero area or a repeated vertex")});
    if (si.intersecting_pairs > 0) {
        std::string ex;
        for (size_t i = 0; i < si.examples.size() && i < 3; ++i)
            ex += (i ? ", " : " (e.g. faces ") + std::to_string(si.examples[i].first) + "/" + std::to_string(si.examples[i].second);
        if (!ex.empty()) ex += ")";
        defects.push_back({"self_intersection", "self-intersection: " + n(si.intersecting_pairs, "intersecting face pairs") + ex});
    }

    nlohmann::json j;
    j["tool"] = "endocast inspect";
    j["input"] = o.input;
    j["vertices"] = t.vertices;
    j["faces"] = t.faces;
    j["edges"] = t.edges;
    j["closed"] = t.closed;
    j["manifold"] = t.manifold;
    j["oriented"] = t.oriented;
    j["outward"] = outward;
    j["components"] = t.components;
    j["genus"] = t.genus;
    j["degenerate_faces"] = t.degenerate_faces;
    j["self_intersections"] = si.intersecting_pairs;
    j["volume_ml"] = volume / 1000.0;
    j["area_mm2"] = area;
    j["bbox_mm"] = {{"min", {box.min[0], box.min[1], box.min[2]}},
                    {"max", {box.max[0], box.max[1], box.max[2]}},
                    {"size", {box.max[0] - box.min[0], box.max[1] - box.min[1], box.max[2] - box.min[2]}}};
    j["boundary_edges"] = t.boundary_edges;
    j["nonmanifold_edges"] = t.nonmanifold_edges;
    j["nonmanifold_vertices"] = t.nonmanifold_vertices;
    j["inconsistent_edges"] = t.inconsistent_edges;
    j["isolated_vertices"] = t.isolated_vertices;
    nlohmann::json codes = nlohmann::json::array();
    for (const Defect& d : defects) codes.push_back(d.code);
    j["defects"] = codes;
    j["clean"] = defects.empty();
    if (!o.json.empty()) meshpost::write_file_atomic(o.json, j.dump(2) + "\n");

    if (!g.quiet) {
        auto yn = [](bool b) { return b ? "yes" : "NO"; };
        std::ostringstream s;
        s << o.input << ": " << t.vertices << " vertices, " << t.faces << " faces, " << t.edges << " edges\n";
        s << "  closed:              " << yn(t.closed) << " (" << t.boundary_edges << " boundary edges)\n";
        s << "  manifold:            " << yn(t.manifold) << " (" << t.nonmanifold_edges << " non-manifold edges, "
          << t.nonmanifold_vertices << " non-manifold vertices)\n";
        s << "  oriented:            " << yn(t.oriented) << " (" << t.inconsistent_edges << " inconsistent edges)\n";
        s << "  outward:             " << yn(outward) << "\n";
        s << "  components:          " << t.components << "\n";
        s << "  genus:               " << t.genus << "\n";
        s << "  degenerate faces:    " << t.degenerate_faces << "\n";
        s << "  self-intersections:  " << si.intersecting_pairs << " face pairs\n";
        if (t.isolated_vertices > 0) s << "  isolated vertices:   " << t.isolated_vertices << " (ignored)\n";
        s << std::fixed << std::setprecision(3);
        s << "  volume:              " << volume / 1000.0 << " mL" << (t.closed ? "" : " (not closed: not meaningful)") << "\n";
        s << std::setprecision(2);
        s << "  area:                " << area << " mm^2\n";
        s << "  bounding box:        [" << box.min[0] << ", " << box.min[1] << ", " << box.min[2] << "] - ["
          << box.max[0] << ", " << box.max[1] << ", " << box.max[2] << "] mm\n";
        if (defects.empty()) {
            s << "clean closed 2-manifold\n";
        } else {
            s << "DEFECTS (" << defects.size() << "):\n";
            for (const Defect& d : defects) s << "  - " << d.text << "\n";
        }
        if (!o.json.empty()) s << "wrote " << o.json << "\n";
        std::cout << s.str();
    }
    return defects.empty() ? kOk : kDefects;
}

}  // namespace

void setup_inspect(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<InspectOptions>();
    auto* sub = app.add_subcommand(
        "inspect",
        "Check a mesh: closed, edge- and vertex-manifold, consistently and outward oriented, "
        "components, genus, degenerate faces, self-intersecting face pairs (CGAL), volume (mL), "
        "area (mm^2), bounding box. Exit status 0 for a clean closed 2-manifold, 1 when defects "
        "are found (listed), 3 for unreadable input.");
    sub->add_option("MESH", o->input, "Mesh file: .stl (binary or ASCII), .ply, .obj or .off")->required();
    sub->add_option("--json", o->json, "Write the findings as JSON to this file");
    // Status 1 (defects found) is not an error: it ends the process after everything is written.
    sub->callback([o, &g] { exit_unless_ok(run_inspect(*o, g)); });
}

}  // namespace endocast::cli
