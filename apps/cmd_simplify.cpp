// `endocast simplify`: quadric-error simplification that keeps a clean closed 2-manifold clean.
#include <omp.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "commands.h"
#include "endocast/errors.h"
#include "meshpost/cgal/deviation.h"
#include "meshpost/io.h"
#include "meshpost/cgal/simplify_verified.h"

namespace endocast::cli {
namespace {

/// Default two-sided distance bound, mm (see SimplifyParams::max_error_mm).
constexpr double kDefaultMaxErrorMm = 0.35;

struct SimplifyOptions {
    std::string input, output, report;
    std::optional<size_t> faces;
    std::optional<double> ratio;
    double max_error_mm = kDefaultMaxErrorMm;
};

bool is_mesh_extension(const std::string& p) {
    const auto dot = p.find_last_of('.');
    std::string e = dot == std::string::npos ? "" : p.substr(dot);
    for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
    return e == ".stl" || e == ".ply" || e == ".obj" || e == ".off";
}

void run_simplify(const SimplifyOptions& o, const GlobalOptions& g) {
    using Clock = std::chrono::steady_clock;
    auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    if (o.faces.has_value() == o.ratio.has_value())
        throw InvalidParameter("simplify: give exactly one of --faces N and --ratio R");
    if (!is_mesh_extension(o.output))
        throw InvalidParameter("-o " + o.output + ": unknown mesh extension, expected .stl, .ply, .obj or .off");
    const auto t0 = Clock::now();
    const meshpost::TriangleMesh mesh = meshpost::read_mesh(o.input);
    const auto t_read = Clock::now();

    const meshpost::TopologyReport before = meshpost::analyze_topology(mesh);
    if (!before.oriented || before.degenerate_faces > 0 || before.faces == 0)
        throw IoError(o.input + ": simplify needs a consistently oriented 2-manifold without degenerate faces "
                      "(see `endocast inspect`)");
    meshpost::SimplifyParams p;
    if (o.faces) p.target_faces = *o.faces;
    else p.ratio = *o.ratio;
    p.max_error_mm = o.max_error_mm;
    meshpost::VerifiedSimplifyResult v;
    try {
        v = meshpost::simplify_verified(mesh, p);
    } catch (const meshpost::InvalidMesh& e) {
        throw IoError(o.input + ": " + e.what());
    }
    const auto t_simplify = Clock::now();
    if (!v.clean)
        throw NoResult("simplify: could not reach " + std::to_string(v.simplified.target_faces) +
                       " faces without breaking the mesh (" + v.failure + "), even with the strictest guards");
    const meshpost::SimplifyResult& r = v.simplified;

    // Distance of the result to the input, both ways.
    const meshpost::HausdorffResult dev = meshpost::hausdorff_distance(r.mesh, mesh);
    const auto t_dev = Clock::now();
    meshpost::write_mesh(r.mesh, o.output);
    const auto t_write = Clock::now();

    const auto& ta = v.topology_after;
    nlohmann::json j;
    j["tool"] = "endocast simplify";
    j["input"] = o.input;
    j["output"] = o.output;
    j["target_faces"] = r.target_faces;
    j["faces_before"] = r.faces_before;
    j["faces_after"] = r.faces_after;
    j["vertices_after"] = r.mesh.vertices.size();
    j["volume_before_ml"] = r.volume_before_mm3 / 1000.0;
    j["volume_after_ml"] = r.volume_after_mm3 / 1000.0;
    j["volume_change_pct"] = r.volume_change_pct;
    j["hausdorff_mm"] = dev.hausdorff_mm;
    j["hausdorff_sampling_error_bound_mm"] = dev.sampling_error_bound_mm;
    j["mean_deviation_mm"] = {{"output_to_input", dev.mean_a_to_b_mm}, {"input_to_output", dev.mean_b_to_a_mm}};
    j["closed"] = ta.closed;
    j["manifold"] = ta.manifold;
    j["oriented"] = ta.oriented;
    j["components"] = ta.components;
    j["genus_before"] = v.topology_before.genus;
    j["genus"] = ta.genus;
    j["degenerate_faces"] = ta.degenerate_faces;
    j["self_intersections"] = v.self_intersections_after;
    j["attempts"] = v.attempts;
    j["repair_rounds"] = v.repair_rounds;
    j["locked_vertices"] = v.locked_vertices;
    j["max_normal_deviation_deg"] = v.used.max_normal_deviation_deg;
    j["max_aspect_ratio"] = v.used.max_aspect_ratio;
    j["max_error_mm"] = p.max_error_mm;
    j["max_error_used_mm"] = r.max_error_used_mm;
    j["threads"] = omp_get_max_threads();
    j["timings_s"] = {{"read", seconds(t0, t_read)},
                      {"simplify_and_check", seconds(t_read, t_simplify)},
                      {"hausdorff", seconds(t_simplify, t_dev)},
                      {"write", seconds(t_dev, t_write)},
                      {"total", seconds(t0, t_write)}};
    if (!o.report.empty()) meshpost::write_file_atomic(o.report, j.dump(2) + "\n");

    if (!g.quiet) {
        std::ostringstream s;
        s << "faces " << r.faces_before << " -> " << r.faces_after << " (target " << r.target_faces << ")";
        if (v.attempts > 1) s << ", attempt " << v.attempts;
        s << ", normal deviation <= " << v.used.max_normal_deviation_deg << " deg";
        if (r.max_error_used_mm > 0) {
            s << ", distance bound " << r.max_error_used_mm << " mm";
            if (r.max_error_used_mm > p.max_error_mm) s << " (relaxed from " << p.max_error_mm << " to reach the target)";
        }
        s << "\n";
        s << std::fixed << std::setprecision(3) << "volume " << r.volume_before_mm3 / 1000.0 << " -> "
          << r.volume_after_mm3 / 1000.0 << " mL (" << std::showpos << r.volume_change_pct << std::noshowpos
          << " %), Hausdorff " << dev.hausdorff_mm << " mm (+- " << dev.sampling_error_bound_mm << ")\n";
        s << "closed 2-manifold: " << (ta.closed && ta.manifold && ta.oriented ? "yes" : "NO") << ", genus "
          << ta.genus << ", self-intersections " << v.self_intersections_after << ", time " << std::setprecision(2)
          << seconds(t_read, t_simplify) << " s (simplify + checks)\n";
        s << "wrote " << o.output << "\n";
        if (!o.report.empty()) s << "wrote " << o.report << "\n";
        std::cout << s.str();
    }
}

}  // namespace

void setup_simplify(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<SimplifyOptions>();
    auto* sub = app.add_subcommand(
        "simplify",
        "Quadric-error simplification (OpenMesh) of an oriented manifold mesh: a closed 2-manifold "
        "stays closed and manifold with the same genus, without self-intersections (checked with "
        "CGAL; self-intersections are first repaired locally, then stricter guards are tried) or "
        "degenerate faces.");
    sub->add_option("IN", o->input, "Input mesh: .stl, .ply, .obj or .off")->required();
    sub->add_option("-o,--output", o->output, "Output mesh: .stl (binary), .ply, .obj or .off")->required();
    auto* faces = sub->add_option("--faces", o->faces, "Target number of faces")->check(CLI::PositiveNumber);
    auto* ratio = sub->add_option("--ratio", o->ratio, "Target fraction of the input faces, in (0, 1]")
                      ->check(CLI::Range(0.0, 1.0));
    faces->excludes(ratio);
    sub->add_option("--max-error", o->max_error_mm,
                    "Distance bound in mm, both ways: each collapse must keep the simplified surface "
                    "(sampled) and the input points it replaces within this distance of each other; "
                    "relaxed by x1.25 steps when the target cannot be reached otherwise; 0 = off")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    sub->add_option("--report", o->report,
                    "JSON report: faces_before, faces_after, volume_change_pct, hausdorff_mm (to the "
                    "input), topology checks, timings");
    sub->callback([o, &g] {
        if (o->ratio && !(*o->ratio > 0.0)) throw InvalidParameter("--ratio must be in (0, 1]");
        run_simplify(*o, g);
    });
}

}  // namespace endocast::cli
