// `endocast extract`: the whole method, from a CT scan to an endocast mesh, mask and report.
#include <chrono>
#include <exception>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <system_error>

#include "commands.h"
#include "extract_outputs.h"
#include "method_options.h"
#include "report.h"
#include "endocast/endocast.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/io.h"
#include "meshpost/text.h"
#include "meshpost/topology.h"

namespace endocast::cli {
namespace {

using meshpost::text::lower_extension;

struct ExtractOptions {
    InputOptions input;     // INPUT, --series, --slice-spacing, raw input (method_options.h)
    MethodOptions method;   // --iso ... --surface (method_options.h)
    std::string output, mask, report;
    QcOptions pictures;     // --qc, --html, --qc-panel-px (extract_outputs.h)
    GridOptions grid;       // --crop, --downsample, --refine, --refine-slab, --max-memory (method_options.h)
    bool check_all_faces = false;   // self-intersections among every pair of faces, not only the moved ones
};

void check_output_extensions(const ExtractOptions& o) {
    if (!o.output.empty()) {
        const std::string e = lower_extension(o.output);
        if (e != ".stl" && e != ".ply" && e != ".obj" && e != ".off")
            throw InvalidParameter("-o " + o.output + ": unknown mesh extension '" + e +
                                   "', expected .stl, .ply, .obj or .off");
    }
    if (!o.mask.empty()) {
        const std::string& m = o.mask;
        const std::string e = lower_extension(m);
        const bool ok = e == ".nrrd" || e == ".nii" || e == ".mha" || meshpost::text::ends_with(m, ".nii.gz");
        if (!ok)
            throw InvalidParameter("--mask " + m + ": expected a .nrrd, .nii.gz, .nii or .mha file");
    }
}

// What `extract` prints when it is not quiet: the parameters used, the ECV, bone contact, the
// mesh's checks, time and memory, and the files written.
std::string summary_text(const ExtractOptions& o, const Result& res, double min_bone_contact, double total) {
    const ExtractionResult& r = res.method;
    const meshpost::TopologyReport& topo = res.topology;
    std::ostringstream s;
    s << std::fixed << std::setprecision(1);
    s << "isovalue " << r.params.isovalue << (r.params.isovalue_automatic ? " (automatic, " + r.params.isovalue_rule + ")" : "")
      << ", void radius " << r.params.void_radius_mm << " mm, seeds " << to_string(r.params.seed_mode)
      << " (scale " << r.params.seed_scale << ")\n";
    s << "ECV " << std::setprecision(2) << r.ecv_ml << " mL (mask " << r.mask_volume_ml
      << " mL), area " << std::setprecision(0) << r.surface_area_mm2 << " mm^2, "
      << r.mesh.vertices.size() << " vertices, " << r.mesh.faces.size() << " faces\n";
    s << "bone contact " << std::setprecision(3) << r.bone_contact << " (share of the surface on bone"
      << std::setprecision(2);
    if (r.bone_contact < min_bone_contact) s << "; below " << min_bone_contact << ": check the openings";
    s << ")\n";
    s << "closed 2-manifold: " << (meshpost::is_closed_manifold(topo) ? "yes" : "NO") << ", genus " << topo.genus
      << ", self-intersections " << res.self_intersections << ", time " << std::setprecision(2)
      << total << " s, peak memory " << std::setprecision(0) << peak_memory_mb() << " MB\n";
    if (!o.output.empty()) s << "wrote " << o.output << "\n";
    if (!o.mask.empty()) s << "wrote " << o.mask << "\n";
    if (!o.report.empty()) s << "wrote " << o.report << "\n";
    if (!o.pictures.qc.empty()) s << "wrote " << o.pictures.qc << "\n";
    if (!o.pictures.html.empty()) s << "wrote " << o.pictures.html << "/index.html\n";
    return s.str();
}

// The library's options for `o` (endocast.h): the method's, the reader's, shrinking, the memory
// guard, and the self-intersection check (meshpost/cgal).
Options library_options(const ExtractOptions& o) {
    Options lo;
    lo.method = method_params(o.method);
    lo.method.keep_mask = !o.mask.empty();
    lo.read = read_options(o.input);
    apply_grid_options(o.grid, lo);
    lo.keep_ct = !o.pictures.qc.empty() || !o.pictures.html.empty();
    lo.check_all_faces = o.check_all_faces;
    lo.self_intersections = meshpost::count_self_intersections;
    return lo;
}

// The library's progress on the CLI's (progress.h): its stage count is known once the path is.
struct CliProgress : endocast::Progress {
    CliProgress(const ExtractOptions& o, const GlobalOptions& g) : o(o), g(g) {}
    void planned(const ExtractPlan& plan) override {
        const bool coarse_to_fine = plan.path == ExtractPath::CoarseToFine;
        const int stages = extract_stage_count(!o.method.keep_openings, o.pictures) + (coarse_to_fine ? 1 : 0);
        bar = std::make_unique<cli::Progress>(choose_progress_style(g.quiet, g.log_json), stages);
    }
    void stage(const std::string& name) override { bar->stage(name); }
    void info(const std::string& line) override { bar->info(line); }
    const ExtractOptions& o;
    const GlobalOptions& g;
    std::unique_ptr<cli::Progress> bar;
};

// Removes the mesh written beside the check when an error follows (the mask, the pictures, the
// report), so that an error leaves no mesh behind.
struct RemoveOnError {
    const std::string& path;
    bool armed = false;
    const int errors = std::uncaught_exceptions();
    ~RemoveOnError() {
        if (armed && std::uncaught_exceptions() > errors) {
            std::error_code ignored;
            std::filesystem::remove(path, ignored);
        }
    }
};

void run_extract(const ExtractOptions& o, const GlobalOptions& g) {
    const auto t0 = std::chrono::steady_clock::now();
    auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    check_output_extensions(o);
    check_qc_options(o.pictures);
    Options lo = library_options(o);
    // The mesh is written on a thread of its own while it is checked (mostly the file system's
    // time: the bytes, the sync, the rename).
    double mesh_write_s = 0;
    RemoveOnError remove_mesh{o.output};
    if (!o.output.empty())
        lo.beside_check = [&](const meshpost::TriangleMesh& mesh) {
            const auto tw = std::chrono::steady_clock::now();
            meshpost::write_mesh(mesh, o.output);
            remove_mesh.armed = true;
            mesh_write_s = seconds(tw, std::chrono::steady_clock::now());
        };
    CliProgress progress(o, g);
    Result r = endocast::extract(Source{o.input.inputs}, lo, &progress);
    const ExtractionResult& m = r.method;

    progress.stage("write");  // each output atomically; the mesh was written during the check
    const auto t_write = std::chrono::steady_clock::now();
    if (!o.mask.empty()) write_volume(m.mask, o.mask);
    nlohmann::json j = extract_report(r, lo);
    j["outputs"] = {{"mesh", o.output}, {"mask", o.mask}, {"qc", o.pictures.qc}, {"html", o.pictures.html}};
    j["timings_s"]["write"] = mesh_write_s + seconds(t_write, std::chrono::steady_clock::now());
    const double total = seconds(t0, std::chrono::steady_clock::now());
    j["timings_s"]["total"] = total;
    if (lo.keep_ct) {  // adds timings_s.qc / .html
        if (r.ct16.empty()) write_qc_outputs(o.pictures, r.ct, m, j, *progress.bar);
        else write_qc_outputs(o.pictures, r.ct16, m, j, *progress.bar);
    }
    if (!o.report.empty()) meshpost::write_file_atomic(o.report, j.dump(2) + "\n");
    for (const auto& w : m.warnings) progress.bar->warning(w.message);
    progress.bar->done({{"ecv_ml", m.ecv_ml}, {"bone_contact", m.bone_contact}, {"faces", m.mesh.faces.size()},
                        {"closed_manifold", r.closed_manifold()}});
    if (!g.quiet) std::cout << summary_text(o, r, lo.method.min_bone_contact, total);
}

}  // namespace

void setup_extract(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<ExtractOptions>();
    auto* sub = app.add_subcommand(
        "extract",
        "Extract the endocast (braincase cavity) of a skull CT as a closed, oriented 2-manifold "
        "triangle mesh in the scan's world coordinates (mm, ITK/LPS space, so it overlays the CT "
        "in 3D Slicer and ITK-SNAP).");
    sub->add_option("INPUT", o->input.inputs,
                    "A .nrrd/.nhdr/.nii/.nii.gz/.mha/.mhd file, a directory holding DICOM series (searched "
                    "recursively; see --series) or its DICOMDIR file, a TIFF stack (a folder of .tif/.tiff slices, "
                    "a multi-page .tif, or a slice pattern such as 'scan/slice%04d.tif'; see --spacing), "
                    "or headerless raw file(s) / a slice pattern (with --raw-size)")
        ->required();
    sub->add_option("-o,--output", o->output, "Mesh to write: .stl (binary), .ply, .obj or .off");
    sub->add_option("--mask", o->mask, "Endocast label volume (1 = endocast) in the input's geometry (the grid after --crop/--downsample): .nrrd or .nii.gz");
    sub->add_option("--report", o->report, "JSON report: input, parameters used, ECV, area, mesh checks, timings, memory");
    add_qc_options(*sub, o->pictures);
    add_method_options(*sub, o->method);
    add_input_options(*sub, o->input);
    add_grid_options(*sub, o->grid);
    sub->add_flag("--check-all-faces", o->check_all_faces,
                  "Test every pair of faces for self-intersections (default: the faces moved after marching "
                  "cubes, by the flush of dips, against the faces near them; marching cubes on the Freudenthal "
                  "subdivision cannot self-intersect)");
    sub->callback([o, &g] { run_extract(*o, g); });
}

}  // namespace endocast::cli
