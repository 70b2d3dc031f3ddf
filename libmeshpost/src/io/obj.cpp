// OBJ: reading "v" and "f" lines (1-based and negative relative indices), writing v/f text.
#include "formats.h"

namespace meshpost::io {

TriangleMesh read_obj(const std::string& path, std::string_view data) {
    TriangleMesh mesh;
    LineReader lr(data);
    std::string_view line;
    std::vector<std::string_view> tok;
    std::vector<uint32_t> idx;
    while (lr.next(line)) {
        const size_t hash = line.find('#');
        if (hash != std::string_view::npos) line = line.substr(0, hash);
        split_tokens(line, tok);
        if (tok.empty()) continue;
        const std::string at = "OBJ line " + std::to_string(lr.line_no()) + ": ";
        if (tok[0] == "v") {
            if (tok.size() < 4) fail(path, at + "vertex has " + std::to_string(tok.size() - 1) +
                                               " values, expected at least 3 coordinates");
            Point p;
            for (int i = 0; i < 3; ++i)
                if (!parse_double(tok[static_cast<size_t>(i) + 1], p[static_cast<size_t>(i)]))
                    fail(path, at + "bad number " + quoted(tok[static_cast<size_t>(i) + 1]) + ", expected a coordinate");
            check_finite(path, p, at + "vertex");
            if (mesh.vertices.size() >= kMaxVertices) fail(path, at + "too many vertices for 32-bit indices");
            mesh.vertices.push_back(p);
        } else if (tok[0] == "f") {
            if (tok.size() < 4)
                fail(path, at + "face has " + std::to_string(tok.size() - 1) + " vertices, expected at least 3");
            idx.clear();
            for (size_t k = 1; k < tok.size(); ++k) {
                const std::string_view ref = tok[k].substr(0, tok[k].find('/'));
                int64_t i;
                if (!parse_int64(ref, i)) fail(path, at + "bad vertex index " + quoted(tok[k]));
                if (i == 0)
                    fail(path, at + "vertex index 0 is invalid, expected 1-based (or negative relative) indices");
                const int64_t n = static_cast<int64_t>(mesh.vertices.size());
                const int64_t resolved = i > 0 ? i - 1 : n + i;
                if (resolved < 0 || resolved >= n)
                    fail(path, at + "vertex index " + std::to_string(i) + " is out of range, " +
                                   std::to_string(n) + " vertices are defined so far");
                idx.push_back(static_cast<uint32_t>(resolved));
            }
            add_polygon(mesh, idx);
        }
        // Other statements (vn, vt, g, o, s, usemtl, mtllib, l, p, ...) carry nothing we need.
    }
    return mesh;
}

void write_obj(const TriangleMesh& mesh, Writer& w) {
    w.text("# written by endocast meshpost\n# SPACE=LPS\n");
    write_text_lines(mesh, w, "v ", "f ", 1);
}

}  // namespace meshpost::io
