#pragma once
// The offline HTML report of `endocast extract --html DIR`: one self-contained DIR/index.html.
#include <nlohmann/json.hpp>
#include <string>

#include "meshpost/mesh.h"

namespace endocast::cli {

/// three.js embedded at build time (apps/html/embed_three.cmake); empty strings / "" version when
/// npm was not available then.
const char* three_js_version();
const std::string& three_js_core();
const std::string& three_js_module();
const std::string& three_js_orbit();

/// Standard base64 (RFC 4648, with padding).
std::string base64(const std::string& bytes);

/// Writes DIR/index.html (creating DIR if its parent exists): specimen, input, parameters, ECV,
/// area, mesh checks, timings and warnings from `report` (the --report JSON), the QC picture
/// `qc_png` (PNG bytes, inlined; empty = none) and an interactive three.js view of `mesh` (vertex
/// positions as Float32 and indices as Uint32, inlined as base64). Nothing is loaded from the
/// network. Without embedded three.js the page says so in place of the 3D view, and the function
/// returns false (true otherwise). `view_note` (may be empty) is printed under the 3D view's
/// caption (e.g. that the view shows a simplified copy of a large mesh). Throws IoError when DIR
/// cannot be created or written.
bool write_html_report(const std::string& dir, const nlohmann::json& report, const std::string& qc_png,
                       const meshpost::TriangleMesh& mesh, const std::string& view_note = "");

}  // namespace endocast::cli
