// STL: binary and ASCII reading (vertices welded by exact position), binary writing.
#include "formats.h"

#include "meshpost/measure.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

namespace meshpost::io {
namespace {

/// Welds vertices by exact position (bit pattern, with -0 treated as +0).
class Welder {
public:
    explicit Welder(TriangleMesh& mesh) : mesh_(mesh) {}
    /// Returns false when the vertex count would overflow 32-bit indices.
    bool add(const Point& p, uint32_t& index) {
        Key key;
        for (int i = 0; i < 3; ++i) {
            const double v = p[i] + 0.0;  // -0.0 + 0.0 == +0.0
            std::memcpy(&key[i], &v, sizeof v);
        }
        const auto it = map_.find(key);
        if (it != map_.end()) {
            index = it->second;
            return true;
        }
        if (mesh_.vertices.size() >= kMaxVertices) return false;
        index = static_cast<uint32_t>(mesh_.vertices.size());
        mesh_.vertices.push_back({p[0] + 0.0, p[1] + 0.0, p[2] + 0.0});
        map_.emplace(key, index);
        return true;
    }
    void reserve(size_t n) { map_.reserve(n); }

private:
    using Key = std::array<uint64_t, 3>;
    struct KeyHash {
        size_t operator()(const Key& k) const {
            uint64_t h = 0x9E3779B97F4A7C15ull;
            for (uint64_t v : k) {
                h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
                h *= 0xBF58476D1CE4E5B9ull;
                h ^= h >> 31;
            }
            return static_cast<size_t>(h);
        }
    };
    TriangleMesh& mesh_;
    std::unordered_map<Key, uint32_t, KeyHash> map_;
};

bool looks_like_ascii_stl(std::string_view data) {
    size_t i = 0;
    while (i < data.size() && is_space(data[i])) ++i;
    if (data.substr(i, 5) != "solid") return false;
    // Binary files may start with "solid" too: their triangle data holds control bytes.
    const size_t n = std::min<size_t>(data.size(), 4096);
    for (size_t k = 0; k < n; ++k) {
        const unsigned char c = static_cast<unsigned char>(data[k]);
        if (c < 32 && !is_space(static_cast<char>(c))) return false;
    }
    return true;
}

TriangleMesh read_binary_stl(const std::string& path, std::string_view data, uint32_t count) {
    TriangleMesh mesh;
    Welder welder(mesh);
    mesh.faces.reserve(count);
    welder.reserve(static_cast<size_t>(count) / 2 + 4);
    mesh.vertices.reserve(static_cast<size_t>(count) / 2 + 4);
    const auto* p = reinterpret_cast<const unsigned char*>(data.data()) + 84;
    for (uint32_t t = 0; t < count; ++t, p += 50) {
        Face f;
        for (int k = 0; k < 3; ++k) {
            const unsigned char* q = p + 12 + 12 * k;
            const Point pt{load_f32(q, false), load_f32(q + 4, false), load_f32(q + 8, false)};
            check_finite(path, pt, "triangle " + std::to_string(t));
            if (!welder.add(pt, f[k])) fail(path, "too many distinct vertices for 32-bit indices");
        }
        mesh.faces.push_back(f);
    }
    return mesh;
}

TriangleMesh read_ascii_stl(const std::string& path, std::string_view data) {
    TriangleMesh mesh;
    Welder welder(mesh);
    TokenReader tr(data);
    std::string_view tok;
    auto where = [&]() { return "ASCII STL line " + std::to_string(tr.line()) + ": "; };
    auto expect = [&](std::string_view word) {
        if (!tr.next(tok)) fail(path, where() + "file ends early, expected '" + std::string(word) + "'");
        if (tok != word)
            fail(path, where() + "found " + quoted(tok) + ", expected '" + std::string(word) + "'");
    };
    auto number = [&](const char* what) {
        if (!tr.next(tok)) fail(path, where() + "file ends early, expected " + what);
        double v;
        if (!parse_double(tok, v)) fail(path, where() + "bad number " + quoted(tok) + ", expected " + what);
        return v;
    };

    expect("solid");
    tr.skip_line();
    std::vector<uint32_t> idx;
    size_t facet = 0;
    while (true) {
        if (!tr.next(tok)) fail(path, where() + "file ends early, expected 'facet' or 'endsolid'");
        if (tok == "endsolid") {
            tr.skip_line();
            if (!tr.next(tok)) break;
            if (tok != "solid")
                fail(path, where() + "found " + quoted(tok) + " after 'endsolid', expected end of file or 'solid'");
            tr.skip_line();
            continue;
        }
        if (tok != "facet") fail(path, where() + "found " + quoted(tok) + ", expected 'facet' or 'endsolid'");
        expect("normal");
        for (int i = 0; i < 3; ++i) number("a normal component");
        expect("outer");
        expect("loop");
        idx.clear();
        while (true) {
            if (!tr.next(tok)) fail(path, where() + "file ends early, expected 'vertex' or 'endloop'");
            if (tok == "endloop") break;
            if (tok != "vertex") fail(path, where() + "found " + quoted(tok) + ", expected 'vertex' or 'endloop'");
            Point p;
            for (int i = 0; i < 3; ++i) p[i] = number("a vertex coordinate");
            check_finite(path, p, where() + "vertex");
            uint32_t v;
            if (!welder.add(p, v)) fail(path, "too many distinct vertices for 32-bit indices");
            idx.push_back(v);
        }
        if (idx.size() < 3)
            fail(path, where() + "facet " + std::to_string(facet) + " has " + std::to_string(idx.size()) +
                           " vertices, expected at least 3");
        expect("endfacet");
        add_polygon(mesh, idx);
        ++facet;
    }
    return mesh;
}

}  // namespace

TriangleMesh read_stl(const std::string& path, std::string_view data) {
    const bool ascii = looks_like_ascii_stl(data);
    if (data.size() >= 84) {
        const auto* p = reinterpret_cast<const unsigned char*>(data.data());
        const uint32_t count = static_cast<uint32_t>(load_uint(p + 80, 4, false));
        const uint64_t expected = 84 + 50 * static_cast<uint64_t>(count);
        if (expected == data.size()) return read_binary_stl(path, data, count);
        if (!ascii)
            fail(path, "binary STL declares " + std::to_string(count) + " triangles (" + std::to_string(expected) +
                           " bytes) but the file holds " + std::to_string(data.size()) + " bytes");
    } else if (!ascii) {
        fail(path, "file holds " + std::to_string(data.size()) +
                       " bytes: too short for a binary STL (at least 84 bytes) and not an ASCII STL "
                       "(no leading 'solid')");
    }
    return read_ascii_stl(path, data);
}

void write_stl(const TriangleMesh& mesh, const std::string& path, Writer& w) {
    if (mesh.faces.size() > std::numeric_limits<uint32_t>::max())
        fail(path, "cannot write: binary STL holds at most 2^32-1 triangles");
    char header[80] = {};
    // Must not start with "solid". SPACE=LPS tells 3D Slicer (and other readers that look for it)
    // that the coordinates are LPS, as every coordinate in endocast is (docs/slicer.md).
    const char title[] = "binary STL written by endocast meshpost SPACE=LPS";
    std::memcpy(header, title, sizeof title - 1);
    w.text(std::string_view(header, sizeof header));
    w.u32le(static_cast<uint32_t>(mesh.faces.size()));
    for (const Face& f : mesh.faces) {
        Point n = face_cross(mesh, f);
        const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (double& x : n) x = (len > 0 && std::isfinite(len)) ? x / len : 0.0;
        for (double x : n) w.f32le(static_cast<float>(x));
        for (uint32_t vi : f)
            for (double x : mesh.vertices[vi]) w.f32le(static_cast<float>(x));
        w.u16le(0);
        w.maybe_flush();
    }
}

}  // namespace meshpost::io
