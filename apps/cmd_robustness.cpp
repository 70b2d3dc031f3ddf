// `endocast robustness`: the paper's Fig 11 - how much the endocast moves with the isovalue.
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "method_options.h"
#include "report.h"
#include "meshpost/io.h"
#include "endocast/endocast.h"
#include "meshpost/cgal/deviation.h"
#include "meshpost/topology.h"

namespace endocast::cli {
namespace {

struct RobustnessOptions {
    InputOptions input;    // INPUT, --series, --slice-spacing, raw input (method_options.h)
    MethodOptions method;  // the method's options but --iso (method_options.h)
    GridOptions grid;      // --crop, --downsample, --refine, --refine-slab, --max-memory (method_options.h)
    std::string report;
    double iso = 0;
    double delta = 400;
};

nlohmann::json stats(const meshpost::DistanceStats& s) {
    return {{"mean", s.mean}, {"rms", s.rms}, {"median", s.median}, {"p95", s.p95}, {"max", s.max},
            {"samples", s.samples}};
}

void run_robustness(const RobustnessOptions& o, const GlobalOptions& g) {
    if (!(o.delta > 0)) throw InvalidParameter("--delta " + std::to_string(o.delta) + ", expected > 0");
    const ExtractParams method = method_params(o.method);  // checked before the read
    // Each run is `extract`'s (endocast.h): the same reading, memory plan and path.
    Options lo;
    lo.method = method;
    lo.method.keep_mask = false;  // only the meshes are compared
    lo.read = read_options(o.input);
    apply_grid_options(o.grid, lo);
    const double isos[3] = {o.iso - o.delta, o.iso, o.iso + o.delta};
    std::vector<Result> results;
    nlohmann::json jruns = nlohmann::json::array();
    for (double t : isos) {
        if (!g.quiet) std::cerr << "extracting at isovalue " << t << " ...\n";
        lo.method.binarize.isovalue = t;
        results.push_back(endocast::extract(Source{o.input.inputs}, lo));
        if (results.size() == 1)
            for (const auto& w : results[0].input.warnings) std::cerr << "endocast: warning: " << w << "\n";
        const Result& r = results.back();
        jruns.push_back({{"isovalue", t}, {"ecv_ml", r.ecv_ml()}, {"bone_contact", r.method.bone_contact},
                         {"faces", r.mesh().faces.size()}, {"closed_manifold", r.closed_manifold()},
                         {"path", to_string(r.plan.path)}, {"ecv_change_pct", 0.0}});
        if (r.method.params.surface == SurfaceMode::HalfMax) jruns.back()["half_max"] = half_max_json(r.method.half_max);
    }
    std::vector<ExtractionResult> runs;
    for (Result& r : results) runs.push_back(std::move(r.method));
    const double voxel = results[1].mesh_grid.smallest_spacing();
    for (int k = 0; k < 3; ++k)
        jruns[k]["ecv_change_pct"] = 100.0 * (runs[k].ecv_ml - runs[1].ecv_ml) / runs[1].ecv_ml;
    nlohmann::json devs = nlohmann::json::array();
    double worst_mean = 0, worst_p95 = 0, worst_mean_vs_t = 0;
    const int pairs[3][2] = {{0, 1}, {2, 1}, {0, 2}};  // the first two against T (the paper's Fig 11)
    for (const auto& pr : pairs) {
        const meshpost::DeviationResult d = meshpost::surface_deviation(runs[pr[0]].mesh, runs[pr[1]].mesh);
        const double mean = 0.5 * (d.a_to_b.mean + d.b_to_a.mean);
        const double p95 = std::max(d.a_to_b.p95, d.b_to_a.p95);
        worst_mean = std::max(worst_mean, mean);
        if (pr[1] == 1) worst_mean_vs_t = std::max(worst_mean_vs_t, mean);
        worst_p95 = std::max(worst_p95, p95);
        devs.push_back({{"a_isovalue", isos[pr[0]]}, {"b_isovalue", isos[pr[1]]}, {"mean", mean},
                        {"mean_voxels", mean / voxel}, {"p95", p95}, {"hausdorff", d.hausdorff_mm},
                        {"a_to_b", stats(d.a_to_b)}, {"b_to_a", stats(d.b_to_a)},
                        {"sampling_error_bound_mm", d.sampling_error_bound_mm}});
    }
    nlohmann::json j;
    j["tool"] = "endocast robustness";
    j["input"] = input_json(o.input.inputs, results[1].input, results[1].input_grid);
    if (!results[1].input.warnings.empty()) j["input"]["warnings"] = results[1].input.warnings;
    j["parameters"] = method_parameters_json(method, runs[1]);  // those of the run at T
    j["isovalue"] = o.iso;
    j["delta"] = o.delta;
    j["surface"] = to_string(o.method.surface);
    j["voxel_mm"] = voxel;
    j["runs"] = jruns;
    j["deviations"] = devs;
    j["max_mean_deviation_mm"] = worst_mean;
    j["max_mean_deviation_voxels"] = worst_mean / voxel;
    j["max_p95_deviation_mm"] = worst_p95;
    // The same against the result at T only (T-delta vs T and T+delta vs T).
    j["max_mean_deviation_vs_reference_mm"] = worst_mean_vs_t;
    j["max_mean_deviation_vs_reference_voxels"] = worst_mean_vs_t / voxel;
    if (!o.report.empty()) meshpost::write_file_atomic(o.report, j.dump(2) + "\n");
    if (!g.quiet) {
        std::ostringstream s;
        for (int k = 0; k < 3; ++k)
            s << "isovalue " << isos[k] << ": ECV " << runs[k].ecv_ml << " mL ("
              << jruns[k]["ecv_change_pct"].get<double>() << " %)\n";
        s << "largest mean deviation between results " << worst_mean << " mm (" << worst_mean / voxel
          << " voxel), largest p95 " << worst_p95 << " mm\n"
          << "largest mean deviation from the result at T " << worst_mean_vs_t << " mm ("
          << worst_mean_vs_t / voxel << " voxel)\n";
        if (!o.report.empty()) s << "wrote " << o.report << "\n";
        std::cout << s.str();
    }
}

}  // namespace

void setup_robustness(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<RobustnessOptions>();
    auto* sub = app.add_subcommand(
        "robustness",
        "Extract the endocast at T-delta, T and T+delta (the other method options as for extract) and report the ECV of each and the surface "
        "deviation (mean, p95, Hausdorff, mm and voxels) between them (the paper's Fig 11).");
    sub->add_option("INPUT", o->input.inputs, "A volume file, a DICOM directory or raw file(s) (as for extract)")->required();
    sub->add_option("--iso", o->iso, "Central isovalue T, in the scan's units")->required();
    sub->add_option("--delta", o->delta, "Isovalue step (scan units)")->capture_default_str();
    add_method_options(*sub, o->method, false);  // every extract method option but --iso
    add_input_options(*sub, o->input);
    add_grid_options(*sub, o->grid);
    sub->add_option("--report", o->report, "JSON report: runs (isovalue, ecv_ml, ecv_change_pct, bone_contact), deviations (each pair), max_mean_deviation_mm / _voxels (largest of the three pairs), max_mean_deviation_vs_reference_mm / _voxels (T-delta and T+delta against T), max_p95_deviation_mm, surface, input, parameters (those of the run at T, as extract reports them), and with half-max each run's half_max (cavity level, range of local thresholds); a voxel is the smallest spacing");
    sub->callback([o, &g] { run_robustness(*o, g); });
}

}  // namespace endocast::cli
