// The QC picture and HTML page of `endocast extract` (extract_outputs.h).
#include "extract_outputs.h"

#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <utility>

#include "commands.h"
#include "meshpost/io.h"
#include "endocast/errors.h"
#include "endocast/qc.h"
#include "html_report.h"
#include "meshpost/simplify.h"

namespace endocast::cli {

void add_qc_options(CLI::App& sub, QcOptions& o) {
    sub.add_option("--qc", o.qc,
                    "Quality-control PNG: the CT (grey window from the soft tissue in the endocast to "
                    "twice the isovalue's distance above it) with the endocast's outline in green, on "
                    "the axial, coronal and sagittal planes through its centroid and 6 axial slices "
                    "through its extent (square mm pixels), plus the mesh shaded from the left, top, front, "
                    "its faces not on bone (closing surfaces across openings, leaks) in orange; the title "
                    "gives the bone contact first");
    sub.add_option("--html", o.html,
                    "Directory for a self-contained offline HTML report (DIR/index.html; created if "
                    "missing): numbers, timings, warnings, the QC picture and an interactive 3D view "
                    "of the mesh (three.js, embedded in the page)");
    sub.add_option("--qc-panel-px", o.panel_px,
                   "Size in pixels of the QC picture's large panels (the picture is about 3 x this "
                   "wide and 2.6 x this tall)")
        ->check(CLI::Range(64, 4000))
        ->capture_default_str();
}

void check_qc_options(const QcOptions& o) {
    if (!o.qc.empty()) {
        std::string e = o.qc.size() >= 4 ? o.qc.substr(o.qc.size() - 4) : o.qc;
        for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
        if (e != ".png") throw InvalidParameter("--qc " + o.qc + ": expected a .png file name");
    }
    // Fail before the work, not after it, when an output cannot be created.
    for (const auto& [flag, path] : {std::pair<const char*, std::string>{"--qc", o.qc}, {"--html", o.html}}) {
        if (path.empty()) continue;
        const std::filesystem::path parent = std::filesystem::path(path).parent_path();
        if (!parent.empty() && !std::filesystem::is_directory(parent))
            throw IoError(std::string(flag) + " " + path + ": the directory " + parent.string() +
                          " does not exist, expected an existing directory to write into");
    }
}

int extract_stage_count(bool openings, const QcOptions& o) {
    return 1 + (openings ? 7 : 6) + 2 + (o.qc.empty() && o.html.empty() ? 0 : 1) + (o.html.empty() ? 0 : 1);
}

// The most triangles the HTML page's 3D view embeds (about 24 MB of base64 per million).
constexpr size_t kHtmlViewFaces = 1000000;

template <class T>
void write_qc_outputs(const QcOptions& o, const Volume<T>& ct, const ExtractionResult& r,
                      nlohmann::json& report, Progress& progress) {
    const std::string &qc = o.qc, &html = o.html;
    if (qc.empty() && html.empty()) return;
    using clock = std::chrono::steady_clock;
    auto t0 = clock::now();
    progress.stage("qc");
    QcParams qp;
    qp.isovalue = r.params.isovalue;
    qp.panel_px = o.panel_px;
    char title[256];
    // Bone contact first: the figure to read before the others (the path, longest, last).
    const double least = ExtractParams{}.min_bone_contact;
    char low[64] = "";
    if (r.bone_contact < least) std::snprintf(low, sizeof low, " (below %.2f: check the openings)", least);
    std::snprintf(title, sizeof title, "bone contact %.2f%s   ECV %.2f mL   %zu triangles, isovalue %.6g   %s",
                  r.bone_contact, low, r.ecv_ml, r.mesh.faces.size(), r.params.isovalue,
                  report.value("/input/path"_json_pointer, std::string()).c_str());
    qp.title = title;
    if (r.face_on_bone.size() == r.mesh.faces.size()) qp.face_on_bone = &r.face_on_bone;
    if (r.face_leaks.size() == r.mesh.faces.size()) qp.face_leaks = &r.face_leaks;
    // The closures: the openings cut at their rims, then the largest other closing surfaces.
    for (int pass = 0; pass < 2; ++pass)
        for (const Opening& op : r.openings.openings) {
            if ((pass == 0) != (op.cut && op.plane_fitted)) continue;
            QcParams::Closure c;
            c.centre = op.centre_world;
            c.normal = op.normal;
            c.radius_mm = op.radius_mm;
            c.label = pass == 0 ? (op.wide ? "cut (wide)" : "cut") : "closing";
            qp.closures.push_back(c);
        }
    const std::string png = encode_png(render_qc(ct, r.mask, r.mesh, qp));
    if (!qc.empty()) meshpost::write_file_atomic(qc, png);
    auto t1 = clock::now();
    report["timings_s"]["qc"] = std::chrono::duration<double>(t1 - t0).count();
    if (html.empty()) return;
    progress.stage("html");
    // A mesh of microCT size (tens of millions of faces) would make a page of hundreds of MB that no
    // browser opens: the 3D view shows a preview of about kHtmlViewFaces faces (vertex clustering:
    // seconds, where the quadric simplification of 29 M faces takes minutes).
    std::string note;
    meshpost::TriangleMesh simplified;
    if (r.mesh.faces.size() > kHtmlViewFaces) {
        simplified = meshpost::cluster_vertices(r.mesh, meshpost::cluster_cell_for_faces(r.mesh, kHtmlViewFaces));
        note = "The 3D view shows a preview of the mesh: its " + std::to_string(r.mesh.faces.size()) +
               " triangles clustered to " + std::to_string(simplified.faces.size()) +
               " (vertex clustering; the mesh file has them all).";
    }
    if (!write_html_report(html, report, png, note.empty() ? r.mesh : simplified, note))
        progress.warning("--html: this binary was built without three.js, so the report has no 3D view "
                         "(install npm, run scripts/install-deps.sh and rebuild)");
    report["timings_s"]["html"] = std::chrono::duration<double>(clock::now() - t1).count();
}

template void write_qc_outputs<float>(const QcOptions&, const Volume<float>&, const ExtractionResult&, nlohmann::json&,
                                      Progress&);
template void write_qc_outputs<int16_t>(const QcOptions&, const Volume<int16_t>&, const ExtractionResult&, nlohmann::json&,
                                        Progress&);

}  // namespace endocast::cli
