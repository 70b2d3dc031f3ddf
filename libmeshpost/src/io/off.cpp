// OFF: reading (OFF/COFF/NOFF/CNOFF headers, '#' comments, extra values ignored), writing text.
#include "formats.h"

namespace meshpost::io {

TriangleMesh read_off(const std::string& path, std::string_view data) {
    TriangleMesh mesh;
    LineReader lr(data);
    std::string_view line;
    std::vector<std::string_view> tok;
    // Next non-empty line (comments stripped) as tokens; false at end of file.
    auto next_tokens = [&]() {
        while (lr.next(line)) {
            const size_t hash = line.find('#');
            if (hash != std::string_view::npos) line = line.substr(0, hash);
            split_tokens(line, tok);
            if (!tok.empty()) return true;
        }
        return false;
    };
    if (!next_tokens()) fail(path, "OFF file has no header, expected 'OFF'");
    if (tok[0] != "OFF" && tok[0] != "COFF" && tok[0] != "NOFF" && tok[0] != "CNOFF")
        fail(path, "OFF header is " + quoted(tok[0]) + ", expected 'OFF'");
    std::vector<std::string_view> counts(tok.begin() + 1, tok.end());
    if (counts.empty()) {
        if (!next_tokens()) fail(path, "OFF file ends before the vertex/face counts");
        counts = tok;
    }
    if (counts.size() < 2) fail(path, "OFF counts line needs '<vertices> <faces> [<edges>]'");
    uint64_t nv = 0, nf = 0;
    if (!parse_uint64(counts[0], nv)) fail(path, "OFF vertex count " + quoted(counts[0]) + " is not a valid count");
    if (!parse_uint64(counts[1], nf)) fail(path, "OFF face count " + quoted(counts[1]) + " is not a valid count");
    if (nv > kMaxVertices) fail(path, "OFF declares " + std::to_string(nv) + " vertices, more than 32-bit indices can address");
    // Each vertex line needs at least 6 bytes ("0 0 0\n"), each face line 8 ("3 0 1 2\n").
    uint64_t need_v, need_f, need;
    if (mul_overflows(nv, 6, need_v) || mul_overflows(nf, 8, need_f) || add_overflows(need_v, need_f, need) ||
        need > data.size())
        fail(path, "OFF declares " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                       " faces, more than the " + std::to_string(data.size()) + "-byte file can hold");
    mesh.vertices.reserve(static_cast<size_t>(nv));
    mesh.faces.reserve(static_cast<size_t>(nf));
    for (uint64_t i = 0; i < nv; ++i) {
        if (!next_tokens())
            fail(path, "OFF file ends after " + std::to_string(i) + " of " + std::to_string(nv) + " vertices");
        const std::string at = "OFF line " + std::to_string(lr.line_no()) + ": ";
        if (tok.size() < 3) fail(path, at + "vertex needs 3 coordinates");
        Point p;
        for (size_t k = 0; k < 3; ++k)
            if (!parse_double(tok[k], p[k])) fail(path, at + "bad number " + quoted(tok[k]) + ", expected a coordinate");
        check_finite(path, p, at + "vertex");
        mesh.vertices.push_back(p);
    }
    std::vector<uint32_t> idx;
    for (uint64_t f = 0; f < nf; ++f) {
        if (!next_tokens())
            fail(path, "OFF file ends after " + std::to_string(f) + " of " + std::to_string(nf) + " faces");
        const std::string at = "OFF line " + std::to_string(lr.line_no()) + ": ";
        uint64_t n;
        if (!parse_uint64(tok[0], n)) fail(path, at + "bad face vertex count " + quoted(tok[0]));
        if (n < 3) fail(path, at + "face has " + std::to_string(n) + " vertices, expected at least 3");
        if (n > tok.size() - 1)
            fail(path, at + "face declares " + std::to_string(n) + " vertices but lists " +
                           std::to_string(tok.size() - 1));
        idx.clear();
        for (size_t k = 1; k <= n; ++k) {
            uint64_t v;
            if (!parse_uint64(tok[k], v) || v >= nv)
                fail(path, at + "vertex index " + quoted(tok[k]) + " is invalid, expected an index in [0, " +
                               std::to_string(nv) + ")");
            idx.push_back(static_cast<uint32_t>(v));
        }
        add_polygon(mesh, idx);
    }
    return mesh;
}

void write_off(const TriangleMesh& mesh, Writer& w) {
    w.text("OFF\n");
    w.integer(mesh.vertices.size());
    w.text(" ");
    w.integer(mesh.faces.size());
    w.text(" 0\n");
    write_text_lines(mesh, w, "", "3 ", 0);
}

}  // namespace meshpost::io
