// `endocast extract --html DIR`: a self-contained report page. three.js (from npm, embedded into
// the binary at build time) is inlined as data: URLs in an import map, so OrbitControls' `import
// ... from 'three'` resolves without a network or a server; the page opens from file://.
#include "html_report.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <system_error>

#include "commands.h"
#include "meshpost/io.h"
#include "endocast/errors.h"
#include "endocast/pipeline.h"
#include "meshpost/measure.h"

namespace endocast::cli {
namespace {

/// A JSON value as table text: strings unquoted, numbers with up to 6 significant digits.
std::string cell(const nlohmann::json& v) {
    if (v.is_string()) return escape_markup(v.get<std::string>());
    if (v.is_number_float()) {
        std::ostringstream s;
        s.precision(6);
        s << v.get<double>();
        return s.str();
    }
    return escape_markup(v.dump());
}

std::string row(const std::string& key, const nlohmann::json& v) {
    return "<tr><th>" + escape_markup(key) + "</th><td>" + cell(v) + "</td></tr>\n";
}

std::string table_of(const nlohmann::json& obj) {
    std::string t = "<table>\n";
    for (auto it = obj.begin(); it != obj.end(); ++it) t += row(it.key(), it.value());
    return t + "</table>\n";
}

/// "cthead" for ".../cthead.nhdr", "skull" for ".../skull.nii.gz" or a DICOM directory ".../skull/".
std::string specimen_name(const std::string& path) {
    std::filesystem::path p(path);
    if (!p.has_filename()) p = p.parent_path();
    std::string name = p.filename().string();
    for (const char* ext : {".nii.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd", ".raw", ".dcm"}) {
        const std::string e(ext);
        if (name.size() > e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0) {
            name.resize(name.size() - e.size());
            break;
        }
    }
    return name;
}

std::string data_url(const std::string& js) { return "data:text/javascript;base64," + base64(js); }

const char* kStyle = R"css(
body { font-family: sans-serif; margin: 1.5em; color: #222; max-width: 1280px; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.4em; }
table { border-collapse: collapse; margin: 0.4em 0; }
th, td { border: 1px solid #ddd; padding: 3px 8px; text-align: left; font-size: 0.92em; }
th { background: #f4f4f4; font-weight: 600; }
.key { font-size: 1.15em; } .bad { color: #b00; font-weight: 600; } .ok { color: #070; }
#view3d { width: 100%; height: 600px; background: #202020; position: relative; }
#view3d .note { color: #eee; padding: 1em; }
img.qc { max-width: 100%; border: 1px solid #ccc; }
.columns { display: flex; gap: 2em; flex-wrap: wrap; }
.wide { flex: 1; min-width: 480px; }
)css";

// Catches errors before anything else runs; the page's state is in <body data-rendered> and
// <html data-errors> (what the headless-browser test reads).
const char* kErrorCatcher = R"js(
window.__endocastErrors = [];
function __endocastNote(m) {
  window.__endocastErrors.push(String(m));
  document.documentElement.dataset.errors = window.__endocastErrors.join(' | ');
}
window.addEventListener('error', e => __endocastNote(e.message || e));
window.addEventListener('unhandledrejection', e => __endocastNote(e.reason && e.reason.stack || e.reason));
(function () { const ce = console.error; console.error = (...a) => { __endocastNote(a.join(' ')); ce.apply(console, a); }; })();
)js";

const char* kViewer = R"js(
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
const view = document.getElementById('view3d');
function bytes(id) {
  const s = atob(document.getElementById(id).textContent.trim());
  const u = new Uint8Array(s.length);
  for (let i = 0; i < s.length; ++i) u[i] = s.charCodeAt(i);
  return u.buffer;
}
try {
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(bytes('mesh-positions')), 3));
  geom.setIndex(new THREE.BufferAttribute(new Uint32Array(bytes('mesh-indices')), 1));
  geom.computeVertexNormals();
  geom.computeBoundingSphere();
  const r = geom.boundingSphere.radius || 1, c = geom.boundingSphere.center;
  const w = view.clientWidth, h = view.clientHeight;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(w, h);
  view.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x202020);
  const camera = new THREE.PerspectiveCamera(35, w / h, r / 100, r * 100);
  camera.up.set(0, 0, 1);  // LPS: +z is superior
  camera.position.set(c.x + 2.6 * r, c.y - 2.6 * r, c.z + 1.2 * r);  // from the left, in front
  scene.add(new THREE.AmbientLight(0xffffff, 0.5));
  const light = new THREE.DirectionalLight(0xffffff, 2.0);
  light.position.set(0.3, 0.5, 1);
  camera.add(light);
  scene.add(camera);
  scene.add(new THREE.Mesh(geom, new THREE.MeshLambertMaterial({ color: 0xe8d8b0, side: THREE.DoubleSide })));
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(c);
  controls.update();
  const render = () => renderer.render(scene, camera);
  controls.addEventListener('change', render);
  window.addEventListener('resize', () => {
    camera.aspect = view.clientWidth / view.clientHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(view.clientWidth, view.clientHeight);
    render();
  });
  render();
  const rect = renderer.domElement.getBoundingClientRect();
  document.body.dataset.canvasRect = [rect.left, rect.top, rect.width, rect.height].map(Math.round).join(',');
  requestAnimationFrame(() => { document.body.dataset.rendered = 'ok'; });
} catch (e) {
  __endocastNote(e && e.stack || e);
  document.body.dataset.rendered = 'error';
  view.insertAdjacentHTML('beforeend', '<p class="note">3D view failed: ' + String(e && e.message || e) + '</p>');
}
)js";

}  // namespace

std::string base64(const std::string& bytes) {
    static const char* A = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((bytes.size() + 2) / 3 * 4);
    size_t i = 0;
    for (; i + 2 < bytes.size(); i += 3) {
        const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8 | uint8_t(bytes[i + 2]);
        out += A[v >> 18];
        out += A[(v >> 12) & 63];
        out += A[(v >> 6) & 63];
        out += A[v & 63];
    }
    if (i < bytes.size()) {
        const bool two = i + 1 < bytes.size();
        const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16 | (two ? uint32_t(uint8_t(bytes[i + 1])) << 8 : 0);
        out += A[v >> 18];
        out += A[(v >> 12) & 63];
        out += two ? A[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

bool write_html_report(const std::string& dir, const nlohmann::json& j, const std::string& qc_png,
                       const meshpost::TriangleMesh& mesh, const std::string& view_note) {
    std::error_code ec;
    std::filesystem::create_directory(dir, ec);
    if (ec || !std::filesystem::is_directory(dir))
        throw IoError("--html " + dir + ": cannot create the report directory (" +
                      (ec ? ec.message() : std::string("not a directory")) + "; does its parent exist?)");
    const bool have_three = !three_js_core().empty();
    const std::string name = specimen_name(j.value("/input/path"_json_pointer, std::string("endocast")));

    std::ostringstream h;
    h << "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
      << "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
      << "<title>endocast report: " << escape_markup(name) << "</title>\n<style>" << kStyle << "</style>\n"
      << "<script>" << kErrorCatcher << "</script>\n";
    if (have_three)
        h << "<script type=\"importmap\">{\"imports\": {\"three\": \"" << data_url(three_js_module())
          << "\", \"three/core\": \"" << data_url(three_js_core())
          << "\", \"three/addons/controls/OrbitControls.js\": \"" << data_url(three_js_orbit()) << "\"}}</script>\n";
    h << "</head>\n<body data-rendered=\"" << (have_three ? "pending" : "unavailable") << "\">\n";
    h << "<h1>Endocast of " << escape_markup(name) << "</h1>\n";
    h << "<p>" << cell(j.value("tool", "endocast extract")) << " " << cell(j.value("version", "")) << "; input <code>"
      << escape_markup(j.value("/input/path"_json_pointer, std::string())) << "</code></p>\n";

    const bool clean = j.value("closed_manifold", false);
    h << "<div class=\"columns\"><div>\n<h2>Result</h2>\n<table class=\"key\">\n";
    if (j.contains("bone_contact") && j["bone_contact"].is_number()) {
        // The first figure to check: a closed braincase lies on bone all round but for its openings.
        const double contact = j["bone_contact"].get<double>(), least = ExtractParams{}.min_bone_contact;
        const bool low = contact < least;
        h << "<tr><th>bone contact (share of the surface on bone, expected &ge; " << cell(least) << ")</th><td class=\""
          << (low ? "bad" : "ok") << "\">" << cell(j["bone_contact"])
          << (low ? " &mdash; below " + cell(least) + ": check the openings (orange in the QC picture)" : std::string())
          << "</td></tr>\n";
    }
    h << row("endocranial volume (mL)", j.value("ecv_ml", 0.0))
      << row("mask volume (mL)", j.value("mask_volume_ml", 0.0))
      << row("surface area (mm\u00b2)", j.value("surface_area_mm2", 0.0))
      << row("vertices", j.value("vertices", 0)) << row("triangles", j.value("faces", 0))
      << "<tr><th>closed 2-manifold</th><td class=\"" << (clean ? "ok\">yes" : "bad\">NO") << "</td></tr>\n"
      << row("genus", j.value("genus", 0)) << row("components", j.value("components", 0))
      << row("self-intersecting triangle pairs", j.value("self_intersections", 0))
      << row("enclosure by bone", j.value("enclosure", 0.0)) << "</table>\n";

    h << "<h2>Warnings</h2>\n";
    const nlohmann::json warnings = j.value("warnings", nlohmann::json::array());
    if (warnings.empty()) h << "<p class=\"ok\">none</p>\n";
    else {
        h << "<ul>\n";
        for (const auto& w : warnings) h << "<li class=\"bad\">" << cell(w) << "</li>\n";
        h << "</ul>\n";
    }

    h << "</div><div class=\"wide\">\n<h2>3D view</h2>\n<p>Drag to rotate, wheel to zoom, right-drag to pan. World mm (LPS: +x left, "
         "+y posterior, +z superior).</p>\n";
    if (!view_note.empty()) h << "<p class=\"note\">" << escape_markup(view_note) << "</p>\n";
    h << "<div id=\"view3d\">";
    if (!have_three)
        h << "<p class=\"note\">No 3D view: this endocast binary was built without three.js (npm was not "
             "available at build time). Run scripts/install-deps.sh and rebuild.</p>";
    h << "</div>\n</div></div>\n";

    if (!qc_png.empty())
        h << "<h2>Quality control</h2>\n<p>Green: the endocast's outline over the CT (planes through its "
             "centroid, then axial slices through its extent); below, the mesh rendered from the left, "
             "the top and the front, in orange where the surface is not on bone (closing surfaces across "
             "openings, leaks).</p>\n<img class=\"qc\" alt=\"QC picture\" src=\"data:image/png;base64,"
          << base64(qc_png) << "\">\n";

    h << "<div class=\"columns\"><div><h2>Input</h2>\n" << table_of(j.value("input", nlohmann::json::object()))
      << "</div><div><h2>Parameters</h2>\n" << table_of(j.value("parameters", nlohmann::json::object()))
      << "</div><div><h2>Stage timings (s)</h2>\n" << table_of(j.value("timings_s", nlohmann::json::object()))
      << row("peak memory (MB)", j.value("peak_memory_mb", 0.0)) << "</div></div>\n";

    if (have_three) {
        // Positions relative to the bounding-box centre keep float precision; the offset is shown.
        std::string pos, idx;
        pos.resize(mesh.vertices.size() * 3 * sizeof(float));
        idx.resize(mesh.faces.size() * 3 * sizeof(uint32_t));
        const meshpost::BoundingBox b = meshpost::bounding_box(mesh);
        const double c[3] = {0.5 * (b.min[0] + b.max[0]), 0.5 * (b.min[1] + b.max[1]), 0.5 * (b.min[2] + b.max[2])};
        for (size_t v = 0; v < mesh.vertices.size(); ++v)
            for (int k = 0; k < 3; ++k) {
                const float f = float(mesh.vertices[v][size_t(k)] - (mesh.faces.empty() ? 0.0 : c[k]));
                std::memcpy(&pos[(v * 3 + size_t(k)) * sizeof(float)], &f, sizeof f);
            }
        std::memcpy(idx.data(), mesh.faces.data(), idx.size());
        h << "<script id=\"mesh-positions\" type=\"application/octet-stream\">" << base64(pos) << "</script>\n"
          << "<script id=\"mesh-indices\" type=\"application/octet-stream\">" << base64(idx) << "</script>\n"
          << "<script type=\"module\">" << kViewer << "</script>\n";
    }
    if (have_three)
        h << "<p><small>three.js " << three_js_version() << " (MIT licence) is embedded in this page.</small></p>\n";
    h << "</body></html>\n";
    meshpost::write_file_atomic((std::filesystem::path(dir) / "index.html").string(), h.str());
    return have_three;
}

}  // namespace endocast::cli
