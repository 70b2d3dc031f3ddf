// PLY: reading ascii, binary_little_endian and binary_big_endian (any elements and properties,
// skipped by type), writing binary little-endian with float x, y, z and int vertex indices.
#include "formats.h"

#include <algorithm>
#include <limits>
#include <utility>

namespace meshpost::io {
namespace {

enum class PlyType { I8, U8, I16, U16, I32, U32, F32, F64 };

bool ply_type_from_name(std::string_view name, PlyType& t) {
    static const std::pair<std::string_view, PlyType> names[] = {
        {"char", PlyType::I8},     {"int8", PlyType::I8},    {"uchar", PlyType::U8},   {"uint8", PlyType::U8},
        {"short", PlyType::I16},   {"int16", PlyType::I16},  {"ushort", PlyType::U16}, {"uint16", PlyType::U16},
        {"int", PlyType::I32},     {"int32", PlyType::I32},  {"uint", PlyType::U32},   {"uint32", PlyType::U32},
        {"float", PlyType::F32},   {"float32", PlyType::F32}, {"double", PlyType::F64}, {"float64", PlyType::F64},
    };
    for (const auto& [n, type] : names) {
        if (n == name) {
            t = type;
            return true;
        }
    }
    return false;
}

int ply_size(PlyType t) {
    switch (t) {
        case PlyType::I8:
        case PlyType::U8: return 1;
        case PlyType::I16:
        case PlyType::U16: return 2;
        case PlyType::I32:
        case PlyType::U32:
        case PlyType::F32: return 4;
        case PlyType::F64: return 8;
    }
    return 1;
}

bool ply_is_integer(PlyType t) { return t != PlyType::F32 && t != PlyType::F64; }

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::F32;        ///< value type (element type for lists)
    bool is_list = false;
    PlyType count_type = PlyType::U8;   ///< for lists
};

struct PlyElement {
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> props;
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

/// Binary record reader with bounds checks.
class BinaryCursor {
public:
    BinaryCursor(const std::string& path, std::string_view data, size_t pos, bool big_endian)
        : path_(path), p_(reinterpret_cast<const unsigned char*>(data.data())), size_(data.size()), pos_(pos),
          big_(big_endian) {}

    void need(uint64_t n, const std::string& what) {
        if (n > size_ - pos_)
            fail(path_, "binary PLY is truncated: " + what + " ends past the end of the file (" +
                            std::to_string(size_) + " bytes)");
    }
    double number(PlyType t, const std::string& what) {
        need(static_cast<uint64_t>(ply_size(t)), what);
        const unsigned char* q = p_ + pos_;
        pos_ += static_cast<size_t>(ply_size(t));
        switch (t) {
            case PlyType::F32: return load_f32(q, big_);
            case PlyType::F64: return load_f64(q, big_);
            default: return static_cast<double>(integer_at(q, t));
        }
    }
    int64_t integer(PlyType t, const std::string& what) {
        need(static_cast<uint64_t>(ply_size(t)), what);
        const unsigned char* q = p_ + pos_;
        pos_ += static_cast<size_t>(ply_size(t));
        return integer_at(q, t);
    }
    void skip(uint64_t n, const std::string& what) {
        need(n, what);
        pos_ += static_cast<size_t>(n);
    }

private:
    int64_t integer_at(const unsigned char* q, PlyType t) const {
        const uint64_t u = load_uint(q, ply_size(t), big_);
        switch (t) {
            case PlyType::I8: return static_cast<int8_t>(static_cast<uint8_t>(u));
            case PlyType::I16: return static_cast<int16_t>(static_cast<uint16_t>(u));
            case PlyType::I32: return static_cast<int32_t>(static_cast<uint32_t>(u));
            default: return static_cast<int64_t>(u);
        }
    }
    const std::string& path_;
    const unsigned char* p_;
    size_t size_;
    size_t pos_;
    bool big_;
};

/// ASCII record reader.
class AsciiCursor {
public:
    AsciiCursor(const std::string& path, std::string_view body) : path_(path), tr_(body) {}
    std::string_view token(const std::string& what) {
        std::string_view tok;
        if (!tr_.next(tok)) fail(path_, "ASCII PLY data ends early, expected " + what);
        return tok;
    }
    double number(const std::string& what) { return value<double>(parse_double, "number", what); }
    int64_t integer(const std::string& what) { return value<int64_t>(parse_int64, "integer", what); }

private:
    /// The next token parsed by `parse`; `kind` names what it must be in the error message.
    template <class T>
    T value(bool (*parse)(std::string_view, T&), const char* kind, const std::string& what) {
        const std::string_view tok = token(what);
        T v;
        if (!parse(tok, v))
            fail(path_, "ASCII PLY data line " + std::to_string(tr_.line()) + ": bad " + kind + " " + quoted(tok) +
                            ", expected " + what);
        return v;
    }
    const std::string& path_;
    TokenReader tr_;
};

struct PlyHeader {
    PlyFormat format = PlyFormat::Ascii;
    std::vector<PlyElement> elements;
    size_t data_start = 0;
};

PlyHeader parse_ply_header(const std::string& path, std::string_view data) {
    PlyHeader h;
    LineReader lr(data);
    std::string_view line;
    std::vector<std::string_view> tok;
    if (!lr.next(line)) fail(path, "file is empty");
    split_tokens(line, tok);
    if (tok.size() != 1 || tok[0] != "ply") fail(path, "not a PLY file: first line must be 'ply'");
    bool have_format = false;
    bool ended = false;
    while (lr.next(line)) {
        split_tokens(line, tok);
        const std::string at = "PLY header line " + std::to_string(lr.line_no()) + ": ";
        if (tok.empty()) continue;
        if (tok[0] == "comment" || tok[0] == "obj_info") continue;
        if (tok[0] == "end_header") {
            ended = true;
            break;
        }
        if (tok[0] == "format") {
            if (tok.size() < 2) fail(path, at + "'format' needs a format name");
            if (tok[1] == "ascii") h.format = PlyFormat::Ascii;
            else if (tok[1] == "binary_little_endian") h.format = PlyFormat::BinaryLE;
            else if (tok[1] == "binary_big_endian") h.format = PlyFormat::BinaryBE;
            else
                fail(path, at + "unsupported PLY format " + quoted(tok[1]) +
                               ", expected ascii, binary_little_endian or binary_big_endian");
            have_format = true;
        } else if (tok[0] == "element") {
            if (tok.size() != 3) fail(path, at + "expected 'element <name> <count>'");
            PlyElement e;
            e.name = std::string(tok[1]);
            if (!parse_uint64(tok[2], e.count))
                fail(path, at + "element count " + quoted(tok[2]) + " is not a valid non-negative 64-bit count");
            h.elements.push_back(std::move(e));
        } else if (tok[0] == "property") {
            if (h.elements.empty()) fail(path, at + "'property' before any 'element'");
            PlyProperty prop;
            if (tok.size() >= 2 && tok[1] == "list") {
                if (tok.size() != 5) fail(path, at + "expected 'property list <count type> <index type> <name>'");
                if (!ply_type_from_name(tok[2], prop.count_type))
                    fail(path, at + "unsupported property type " + quoted(tok[2]));
                if (!ply_type_from_name(tok[3], prop.type))
                    fail(path, at + "unsupported property type " + quoted(tok[3]));
                if (!ply_is_integer(prop.count_type))
                    fail(path, at + "list count type " + quoted(tok[2]) + " is unsupported, expected an integer type");
                prop.is_list = true;
                prop.name = std::string(tok[4]);
            } else {
                if (tok.size() != 3) fail(path, at + "expected 'property <type> <name>'");
                if (!ply_type_from_name(tok[1], prop.type))
                    fail(path, at + "unsupported property type " + quoted(tok[1]) +
                                   ", expected char, uchar, short, ushort, int, uint, float or double");
                prop.name = std::string(tok[2]);
            }
            h.elements.back().props.push_back(std::move(prop));
        } else {
            fail(path, at + "unknown keyword " + quoted(tok[0]));
        }
    }
    if (!ended) fail(path, "PLY header has no 'end_header' line");
    if (!have_format) fail(path, "PLY header has no 'format' line");
    h.data_start = std::min(lr.position(), data.size());
    return h;
}

/// Where the mesh is in a PLY file: the vertex and face elements, their x, y, z and index properties.
struct PlyLayout {
    int vertex_el = -1, face_el = -1;
    int xyz[3] = {-1, -1, -1};
    int index_prop = -1;
};

/// Finds the x, y, z properties of the vertex element `el` (the last of each name) into `xyz`.
void locate_ply_xyz(const std::string& path, const PlyElement& el, int xyz[3]) {
    for (size_t p = 0; p < el.props.size(); ++p) {
        for (int a = 0; a < 3; ++a) {
            if (el.props[p].name == std::string(1, static_cast<char>('x' + a))) {
                if (el.props[p].is_list) fail(path, "PLY vertex property '" + el.props[p].name + "' is a list, expected a number");
                xyz[a] = static_cast<int>(p);
            }
        }
    }
    if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
        fail(path, "PLY vertex element lacks one of the properties x, y, z");
    if (el.count > kMaxVertices)
        fail(path, "PLY declares " + std::to_string(el.count) +
                       " vertices, more than 32-bit indices can address");
}

/// The vertex index list of the face element `el`: the last property named vertex_indices or vertex_index.
int locate_ply_face_indices(const std::string& path, const PlyElement& el) {
    int index_prop = -1;
    for (size_t p = 0; p < el.props.size(); ++p) {
        if (el.props[p].name == "vertex_indices" || el.props[p].name == "vertex_index") {
            if (!el.props[p].is_list) fail(path, "PLY face property '" + el.props[p].name + "' is not a list");
            if (!ply_is_integer(el.props[p].type))
                fail(path, "PLY face index type is unsupported, expected an integer type");
            index_prop = static_cast<int>(p);
        }
    }
    if (index_prop < 0) fail(path, "PLY face element has no 'vertex_indices' list property");
    return index_prop;
}

/// Smallest possible size of one record of `el`; `index_prop` is its face index list (-1: none).
uint64_t ply_min_record_size(const PlyElement& el, bool binary, int index_prop) {
    uint64_t record = 0;
    for (size_t p = 0; p < el.props.size(); ++p) {
        const PlyProperty& prop = el.props[p];
        const bool index_list = prop.is_list && index_prop == static_cast<int>(p);
        uint64_t s;
        if (!binary) s = index_list ? 8 : 2;  // each value one character and a separator: "3 0 1 2 "
        else if (!prop.is_list) s = static_cast<uint64_t>(ply_size(prop.type));
        else s = static_cast<uint64_t>(ply_size(prop.count_type)) +
                 (index_list ? 3 * static_cast<uint64_t>(ply_size(prop.type)) : 0);
        record += s;
    }
    return record;
}

/// Locates the vertex and face elements and their properties, and checks the declared element
/// counts against the `body_size` bytes after the header before anything is allocated (guards
/// against hostile counts).
PlyLayout locate_ply_mesh(const std::string& path, const PlyHeader& h, uint64_t body_size) {
    const bool binary = h.format != PlyFormat::Ascii;
    PlyLayout layout;
    uint64_t min_total = 0;
    for (size_t e = 0; e < h.elements.size(); ++e) {
        const PlyElement& el = h.elements[e];
        if (el.name == "vertex" && layout.vertex_el < 0) {
            layout.vertex_el = static_cast<int>(e);
            locate_ply_xyz(path, el, layout.xyz);
        } else if (el.name == "face" && layout.face_el < 0) {
            layout.face_el = static_cast<int>(e);
            layout.index_prop = locate_ply_face_indices(path, el);
        }
        const int index_prop = layout.face_el == static_cast<int>(e) ? layout.index_prop : -1;
        uint64_t bytes;
        if (mul_overflows(el.count, ply_min_record_size(el, binary, index_prop), bytes) ||
            add_overflows(min_total, bytes, min_total))
            fail(path, "PLY header declares " + std::to_string(el.count) + " '" + el.name +
                           "' elements: their size overflows 64 bits");
        if (min_total > body_size + (binary ? 0 : 1))  // ASCII: the last value needs no separator
            fail(path, "PLY header declares " + std::to_string(el.count) + " '" + el.name +
                           "' elements; the data up to and including them needs at least " +
                           std::to_string(min_total) + " bytes but only " + std::to_string(body_size) +
                           " bytes follow the header");
    }
    if (layout.vertex_el < 0) fail(path, "PLY file has no 'vertex' element");
    return layout;
}

/// The mesh as the records are read: face indices are checked against the declared vertex count.
struct PlyMesh {
    const std::string& path;
    uint64_t nv;                ///< declared vertex count
    TriangleMesh& mesh;
    std::vector<uint32_t> idx;  ///< the face being read

    void check_count(int64_t n, uint64_t face) const {
        if (n < 3)
            fail(path, "PLY face " + std::to_string(face) + " has " + std::to_string(n) +
                           " vertices, expected at least 3");
    }
    void use_index(int64_t v, uint64_t face) {
        if (v < 0 || static_cast<uint64_t>(v) >= nv)
            fail(path, "PLY face " + std::to_string(face) + " references vertex " + std::to_string(v) +
                           ", expected an index in [0, " + std::to_string(nv) + ")");
        idx.push_back(static_cast<uint32_t>(v));
    }
};

/// Walks the records of every element in file order: `read_record(el, r, is_vertex, is_face, pt)`
/// reads record r of `el` (the vertex's x, y, z into pt); vertices are then checked and kept.
template <class ReadRecord>
void read_ply_records(const PlyHeader& h, const PlyLayout& layout, PlyMesh& m, ReadRecord read_record) {
    for (size_t e = 0; e < h.elements.size(); ++e) {
        const PlyElement& el = h.elements[e];
        const bool is_vertex = static_cast<int>(e) == layout.vertex_el, is_face = static_cast<int>(e) == layout.face_el;
        if (el.props.empty()) continue;  // records without properties occupy no data
        if (is_vertex) m.mesh.vertices.reserve(static_cast<size_t>(el.count));
        if (is_face) m.mesh.faces.reserve(static_cast<size_t>(el.count));
        for (uint64_t r = 0; r < el.count; ++r) {
            Point pt{0, 0, 0};
            read_record(el, r, is_vertex, is_face, pt);
            if (is_vertex) {
                check_finite(m.path, pt, "PLY vertex " + std::to_string(r));
                m.mesh.vertices.push_back(pt);
            }
        }
    }
}

void read_ply_binary(std::string_view data, const PlyHeader& h, const PlyLayout& layout, PlyMesh& m) {
    const int* xyz = layout.xyz;
    BinaryCursor cur(m.path, data, h.data_start, h.format == PlyFormat::BinaryBE);
    read_ply_records(h, layout, m, [&](const PlyElement& el, uint64_t r, bool is_vertex, bool is_face, Point& pt) {
        const std::string what = "'" + el.name + "' element " + std::to_string(r);
        for (size_t p = 0; p < el.props.size(); ++p) {
            const PlyProperty& prop = el.props[p];
            if (is_vertex && !prop.is_list) {
                const int axis = (static_cast<int>(p) == xyz[0]) ? 0 : (static_cast<int>(p) == xyz[1]) ? 1
                               : (static_cast<int>(p) == xyz[2]) ? 2 : -1;
                if (axis >= 0) pt[static_cast<size_t>(axis)] = cur.number(prop.type, what);
                else cur.skip(static_cast<uint64_t>(ply_size(prop.type)), what);
            } else if (is_face && static_cast<int>(p) == layout.index_prop) {
                const int64_t n = cur.integer(prop.count_type, what);
                m.check_count(n, r);
                cur.need(static_cast<uint64_t>(n) * static_cast<uint64_t>(ply_size(prop.type)), what);
                m.idx.clear();
                for (int64_t k = 0; k < n; ++k) m.use_index(cur.integer(prop.type, what), r);
                add_polygon(m.mesh, m.idx);
            } else if (prop.is_list) {
                const int64_t n = cur.integer(prop.count_type, what);
                if (n < 0) fail(m.path, "PLY " + what + " has a negative list length");
                cur.skip(static_cast<uint64_t>(n) * static_cast<uint64_t>(ply_size(prop.type)), what);
            } else {
                cur.skip(static_cast<uint64_t>(ply_size(prop.type)), what);
            }
        }
    });
}

void read_ply_ascii(std::string_view data, const PlyHeader& h, const PlyLayout& layout, PlyMesh& m) {
    AsciiCursor cur(m.path, data.substr(std::min(data.size(), h.data_start)));
    read_ply_records(h, layout, m, [&](const PlyElement& el, uint64_t r, bool is_vertex, bool is_face, Point& pt) {
        const std::string what = "a value of '" + el.name + "' element " + std::to_string(r);
        for (size_t p = 0; p < el.props.size(); ++p) {
            const PlyProperty& prop = el.props[p];
            if (is_vertex && !prop.is_list) {
                const double v = cur.number(what);
                for (int a = 0; a < 3; ++a)
                    if (static_cast<int>(p) == layout.xyz[a]) pt[static_cast<size_t>(a)] = v;
            } else if (prop.is_list) {
                const int64_t n = cur.integer("a list length of '" + el.name + "' element " + std::to_string(r));
                const bool indices = is_face && static_cast<int>(p) == layout.index_prop;
                if (indices) m.check_count(n, r);
                if (n < 0) fail(m.path, "PLY " + what + " has a negative list length");
                m.idx.clear();
                for (int64_t k = 0; k < n; ++k) {
                    if (indices) m.use_index(cur.integer("a vertex index of face " + std::to_string(r)), r);
                    else cur.token(what);
                }
                if (indices) add_polygon(m.mesh, m.idx);
            } else {
                cur.token(what);
            }
        }
    });
}

}  // namespace

TriangleMesh read_ply(const std::string& path, std::string_view data) {
    const PlyHeader h = parse_ply_header(path, data);
    const uint64_t body_size = data.size() - std::min(data.size(), h.data_start);
    const PlyLayout layout = locate_ply_mesh(path, h, body_size);
    TriangleMesh mesh;
    PlyMesh m{path, h.elements[static_cast<size_t>(layout.vertex_el)].count, mesh, {}};
    if (h.format != PlyFormat::Ascii) read_ply_binary(data, h, layout, m);
    else read_ply_ascii(data, h, layout, m);
    return mesh;
}

void write_ply(const TriangleMesh& mesh, const std::string& path, Writer& w) {
    if (mesh.vertices.size() > static_cast<size_t>(std::numeric_limits<int32_t>::max()))
        fail(path, "cannot write: PLY 'int' indices address at most 2^31-1 vertices");
    w.text("ply\nformat binary_little_endian 1.0\ncomment written by endocast meshpost\ncomment SPACE=LPS\nelement vertex ");
    w.integer(mesh.vertices.size());
    w.text("\nproperty float x\nproperty float y\nproperty float z\nelement face ");
    w.integer(mesh.faces.size());
    w.text("\nproperty list uchar int vertex_indices\nend_header\n");
    for (const Point& p : mesh.vertices) {
        for (double x : p) w.f32le(static_cast<float>(x));
        w.maybe_flush();
    }
    for (const Face& f : mesh.faces) {
        w.u8(3);
        for (uint32_t v : f) w.u32le(v);
        w.maybe_flush();
    }
}

}  // namespace meshpost::io
