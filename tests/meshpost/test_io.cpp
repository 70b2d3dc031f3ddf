#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "meshpost/io.h"
#include "meshpost/topology.h"
#include "test_meshes.h"

using namespace meshpost;
using namespace meshpost::test;
namespace fs = std::filesystem;

namespace {

class MeshIo : public ::testing::Test {
protected:
    void SetUp() override {
        std::string tmpl = (fs::temp_directory_path() / "meshpost_io_XXXXXX").string();
        ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
        dir_ = tmpl;
    }
    void TearDown() override {
        std::error_code ec;
        fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add, ec);
        fs::remove_all(dir_, ec);
    }
    std::string path(const std::string& name) const { return (fs::path(dir_) / name).string(); }

    void write_bytes(const std::string& name, const std::string& bytes) const {
        std::ofstream out(path(name), std::ios::binary);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    }
    static std::string read_bytes(const std::string& p) {
        std::ifstream in(p, std::ios::binary);
        std::ostringstream s;
        s << in.rdbuf();
        return s.str();
    }
    std::vector<std::string> entries() const {
        std::vector<std::string> names;
        for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }
    /// Reads `name` (written from `content`), expects a MeshIoError whose message names the file and
    /// contains `fragment`.
    void expect_read_error(const std::string& name, const std::string& content, const std::string& fragment) {
        write_bytes(name, content);
        try {
            read_mesh(path(name));
            ADD_FAILURE() << name << ": no MeshIoError, expected one mentioning '" << fragment << "'";
        } catch (const MeshIoError& e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(path(name)), std::string::npos) << msg;
            EXPECT_NE(msg.find(fragment), std::string::npos) << "message: " << msg << "\nexpected: " << fragment;
        }
    }

    std::string dir_;
};

/// A mesh whose coordinates are not exactly representable in float or short decimal text.
TriangleMesh awkward_sphere() {
    TriangleMesh m = icosphere(7.0 / 3.0, 2, {0.1, -1e-7, 12345.678901234567});
    m.vertices[3][0] = 1e-300;
    m.vertices[4][1] = -0.0;
    return m;
}

void put_u32(std::string& s, uint32_t v) {
    for (int i = 0; i < 4; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_f32(std::string& s, float f) {
    uint32_t bits;
    std::memcpy(&bits, &f, 4);
    put_u32(s, bits);
}
void put_u32_be(std::string& s, uint32_t v) {
    for (int i = 3; i >= 0; --i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_f64_be(std::string& s, double d) {
    uint64_t bits;
    std::memcpy(&bits, &d, 8);
    for (int i = 7; i >= 0; --i) s.push_back(static_cast<char>((bits >> (8 * i)) & 0xFF));
}

/// Binary STL of the given triangles (9 floats each) with a chosen header start.
std::string binary_stl(const std::vector<std::array<float, 9>>& tris, const std::string& header,
                       uint32_t declared = UINT32_MAX) {
    std::string s = header;
    s.resize(80, ' ');
    put_u32(s, declared == UINT32_MAX ? static_cast<uint32_t>(tris.size()) : declared);
    for (const auto& t : tris) {
        for (int i = 0; i < 3; ++i) put_f32(s, 0.0f);
        for (float v : t) put_f32(s, v);
        s.push_back(0);
        s.push_back(0);
    }
    return s;
}

const std::vector<std::array<float, 9>> kTetraTris = {
    {0, 0, 0, 0, 1, 0, 1, 0, 0}, {0, 0, 0, 1, 0, 0, 0, 0, 1}, {0, 0, 0, 0, 0, 1, 0, 1, 0}, {1, 0, 0, 0, 1, 0, 0, 0, 1}};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Round trips

TEST_F(MeshIo, ObjAndOffRoundTripExactly) {
    const TriangleMesh m = awkward_sphere();
    for (const char* name : {"a.obj", "b.off", "c.OBJ", "d.Off"}) {
        write_mesh(m, path(name));
        const TriangleMesh r = read_mesh(path(name));
        ASSERT_EQ(r.vertices.size(), m.vertices.size()) << name;
        ASSERT_EQ(r.faces, m.faces) << name;
        for (size_t i = 0; i < m.vertices.size(); ++i) EXPECT_EQ(r.vertices[i], m.vertices[i]) << name << " vertex " << i;
        EXPECT_TRUE(is_closed_manifold(analyze_topology(r))) << name;
    }
}

TEST_F(MeshIo, StlAndPlyRoundTripWithinFloatPrecision) {
    const TriangleMesh m = awkward_sphere();
    for (const char* name : {"a.stl", "b.ply", "c.STL", "d.PlY"}) {
        write_mesh(m, path(name));
        const TriangleMesh r = read_mesh(path(name));
        ASSERT_EQ(r.vertices.size(), m.vertices.size()) << name;  // STL: welded back to the same count
        ASSERT_EQ(r.faces.size(), m.faces.size()) << name;
        for (size_t f = 0; f < m.faces.size(); ++f) {
            for (int k = 0; k < 3; ++k) {
                const Point& a = m.vertices[m.faces[f][k]];
                const Point& b = r.vertices[r.faces[f][k]];
                for (int i = 0; i < 3; ++i) {
                    EXPECT_EQ(b[i], static_cast<double>(static_cast<float>(a[i])));  // float32 storage
                    EXPECT_NEAR(b[i], a[i], std::fabs(a[i]) * 1e-7 + 1e-30);
                }
            }
        }
        EXPECT_TRUE(is_closed_manifold(analyze_topology(r))) << name;
    }
    // PLY keeps the vertex order.
    write_mesh(m, path("order.ply"));
    EXPECT_EQ(read_mesh(path("order.ply")).faces, m.faces);
}

TEST_F(MeshIo, CubeRoundTripsInEveryFormat) {
    const TriangleMesh m = cube(2.5, {-1, 0, 3});
    for (const char* name : {"c.stl", "c.ply", "c.obj", "c.off"}) {
        write_mesh(m, path(name));
        const TriangleMesh r = read_mesh(path(name));
        EXPECT_EQ(r.vertices.size(), 8u) << name;
        EXPECT_EQ(r.faces.size(), 12u) << name;
        EXPECT_TRUE(is_closed_manifold(analyze_topology(r))) << name;
    }
    // No temporary files are left behind.
    EXPECT_EQ(entries(), (std::vector<std::string>{"c.obj", "c.off", "c.ply", "c.stl"}));
}

TEST_F(MeshIo, StlPlyAndObjDeclareLpsInTheirHeaders) {
    // 3D Slicer reads SPACE=LPS / SPACE=RAS from a mesh file's header (docs/slicer.md).
    const TriangleMesh m = icosphere(1.0, 1);
    write_mesh(m, path("a.stl"));
    write_mesh(m, path("a.ply"));
    write_mesh(m, path("a.obj"));
    const std::string stl = read_bytes(path("a.stl"));
    ASSERT_GE(stl.size(), 84u);
    EXPECT_NE(stl.substr(0, 80).find("SPACE=LPS"), std::string::npos);
    EXPECT_NE(stl.compare(0, 5, "solid"), 0);  // binary STL must not look like ASCII
    const std::string ply = read_bytes(path("a.ply"));
    EXPECT_NE(ply.substr(0, ply.find("end_header")).find("\ncomment SPACE=LPS\n"), std::string::npos);
    EXPECT_EQ(read_bytes(path("a.obj")).rfind("# written by endocast meshpost\n# SPACE=LPS\n", 0), 0u);
}

TEST_F(MeshIo, EmptyMeshRoundTrips) {
    for (const char* name : {"e.stl", "e.ply", "e.obj", "e.off"}) {
        write_mesh(TriangleMesh{}, path(name));
        const TriangleMesh r = read_mesh(path(name));
        EXPECT_EQ(r.faces.size(), 0u) << name;
    }
}

TEST_F(MeshIo, OverwritesExistingFile) {
    write_mesh(cube(), path("m.off"));
    write_mesh(tetrahedron(), path("m.off"));
    EXPECT_EQ(read_mesh(path("m.off")).faces.size(), 4u);
    EXPECT_EQ(entries(), (std::vector<std::string>{"m.off"}));
}

// ---------------------------------------------------------------------------------------------
// Reading other writers' files

TEST_F(MeshIo, ReadsAsciiStl) {
    write_bytes("a.stl",
                "solid my part\n"
                "  facet normal 0 0 -1\n    outer loop\n      vertex 0 0 0\n      vertex 0 1 0\n      vertex 1 0 0\n"
                "    endloop\n  endfacet\n"
                "  facet normal 0 -1 0\n    outer loop\n      vertex 0 0 0\n      vertex 1 0 0\n      vertex 0 0 1\n"
                "    endloop\n  endfacet\n"
                "  facet normal -1 0 0\n    outer loop\n      vertex 0 0 0\n      vertex 0 0 1\n      vertex 0 1 0\n"
                "    endloop\n  endfacet\n"
                "  facet normal 1 1 1\n    outer loop\n      vertex 1 0 0\n      vertex 0 1 0\n      vertex 0 0 1E0\n"
                "    endloop\n  endfacet\n"
                "endsolid my part\n");
    const TriangleMesh m = read_mesh(path("a.stl"));
    EXPECT_EQ(m.vertices.size(), 4u);
    EXPECT_EQ(m.faces.size(), 4u);
    EXPECT_TRUE(is_closed_manifold(analyze_topology(m)));
}

TEST_F(MeshIo, BinaryStlStartingWithSolidIsReadAsBinary) {
    write_bytes("b.stl", binary_stl(kTetraTris, "solid exported by a CAD tool"));
    const TriangleMesh m = read_mesh(path("b.stl"));
    EXPECT_EQ(m.vertices.size(), 4u);
    EXPECT_EQ(m.faces.size(), 4u);
    EXPECT_TRUE(is_closed_manifold(analyze_topology(m)));
}

TEST_F(MeshIo, StlWeldsSignedZero) {
    auto tris = kTetraTris;
    tris[1][0] = -0.0f;  // same point as +0
    write_bytes("z.stl", binary_stl(tris, "meshpost test"));
    EXPECT_EQ(read_mesh(path("z.stl")).vertices.size(), 4u);
}

TEST_F(MeshIo, ReadsAsciiPlyWithExtraPropertiesAndQuads) {
    write_bytes("a.ply",
                "ply\r\nformat ascii 1.0\ncomment made by hand\nobj_info x\n"
                "element vertex 4\nproperty float x\nproperty float nx\nproperty double y\nproperty float z\n"
                "property uchar red\nproperty list uchar int tags\n"
                "element face 2\nproperty uchar flags\nproperty list uchar uint vertex_indices\nproperty float q\n"
                "element edge 1\nproperty int vertex1\nproperty int vertex2\n"
                "end_header\n"
                "0 9 0 0 255 0\n1 9 0 0 255 2 7 8\n1 9 1 0 255 1 5\n0 9 1 0.5e0 255 0\n"
                "1 4 0 1 2 3 0.5\n7 3 0 2 1 1.5\n"
                "0 1\n");
    const TriangleMesh m = read_mesh(path("a.ply"));
    ASSERT_EQ(m.vertices.size(), 4u);
    EXPECT_EQ(m.vertices[3], (Point{0, 1, 0.5}));
    ASSERT_EQ(m.faces.size(), 3u);  // the quad fan-triangulated
    EXPECT_EQ(m.faces[0], (Face{0, 1, 2}));
    EXPECT_EQ(m.faces[1], (Face{0, 2, 3}));
    EXPECT_EQ(m.faces[2], (Face{0, 2, 1}));
}

TEST_F(MeshIo, ReadsBinaryBigEndianPlyWithDoubles) {
    std::string s =
        "ply\nformat binary_big_endian 1.0\n"
        "element vertex 4\nproperty double x\nproperty double y\nproperty double z\nproperty short extra\n"
        "element face 4\nproperty list uint uint vertex_indices\nproperty list ushort double normals\n"
        "end_header\n";
    const double pts[4][3] = {{0, 0, 0}, {1.0 / 3.0, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (const auto& p : pts) {
        for (double c : p) put_f64_be(s, c);
        s += std::string("\x12\x34", 2);
    }
    const uint32_t faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    for (const auto& f : faces) {
        put_u32_be(s, 3);
        for (uint32_t v : f) put_u32_be(s, v);
        s += std::string("\x00\x01", 2);
        put_f64_be(s, 42.0);
    }
    write_bytes("be.ply", s);
    const TriangleMesh m = read_mesh(path("be.ply"));
    ASSERT_EQ(m.vertices.size(), 4u);
    EXPECT_EQ(m.vertices[1][0], 1.0 / 3.0);
    ASSERT_EQ(m.faces.size(), 4u);
    EXPECT_EQ(m.faces[3], (Face{1, 2, 3}));
    EXPECT_TRUE(is_closed_manifold(analyze_topology(m)));
}

TEST_F(MeshIo, ReadsBinaryLittleEndianPlyWithIntCounts) {
    std::string s =
        "ply\nformat binary_little_endian 1.0\n"
        "element vertex 3\nproperty uchar flag\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list int int vertex_indices\n"
        "end_header\n";
    for (int i = 0; i < 3; ++i) {
        s.push_back(1);
        put_f32(s, i == 1 ? 1.0f : 0.0f);
        put_f32(s, i == 2 ? 1.0f : 0.0f);
        put_f32(s, 0.25f);
    }
    put_u32(s, 3);
    put_u32(s, 0);
    put_u32(s, 1);
    put_u32(s, 2);
    write_bytes("le.ply", s);
    const TriangleMesh m = read_mesh(path("le.ply"));
    ASSERT_EQ(m.vertices.size(), 3u);
    EXPECT_EQ(m.vertices[2], (Point{0, 1, 0.25}));
    EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}}));
}

TEST_F(MeshIo, ReadsObjWithSlashesNegativeIndicesAndPolygons) {
    write_bytes("a.obj",
                "# comment\nmtllib x.mtl\no thing\n"
                "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0\nv 0 1 0   # trailing comment\n"
                "vt 0 0\nvn 0 0 1\n"
                "g group\nusemtl m\ns off\n"
                "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
                "v 0 0 1\n"
                "f -5//1 -1//1 -4//1\n"
                "f 1/2 5/2 4/2\r\n");
    const TriangleMesh m = read_mesh(path("a.obj"));
    ASSERT_EQ(m.vertices.size(), 5u);
    EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}, {0, 2, 3}, {0, 4, 1}, {0, 4, 3}}));
}

TEST_F(MeshIo, ReadsOffWithCommentsAndQuads) {
    write_bytes("a.off",
                "OFF # header\n# a comment\n\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
                "0.5 0.5 1  # apex\n4 0 1 2 3\n3 0 1 4 255 0 0\n");
    const TriangleMesh m = read_mesh(path("a.off"));
    EXPECT_EQ(m.vertices.size(), 5u);
    EXPECT_EQ(m.faces, (std::vector<Face>{{0, 1, 2}, {0, 2, 3}, {0, 1, 4}}));
    write_bytes("b.off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_EQ(read_mesh(path("b.off")).faces.size(), 1u);
}

// ---------------------------------------------------------------------------------------------
// Bad input

TEST_F(MeshIo, MissingEmptyAndUnknown) {
    try {
        read_mesh(path("nothing.stl"));
        ADD_FAILURE();
    } catch (const MeshIoError& e) {
        EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
    }
    expect_read_error("empty.ply", "", "empty");
    expect_read_error("mesh.xyz", "v 0 0 0\n", "unknown mesh file extension '.xyz'");
    expect_read_error("noext", "v 0 0 0\n", "unknown mesh file extension");
    EXPECT_THROW(read_mesh(dir_ + "/"), MeshIoError);
    fs::create_directory(path("dir.stl"));
    EXPECT_THROW(read_mesh(path("dir.stl")), MeshIoError);
}

TEST_F(MeshIo, BadStl) {
    std::string full = binary_stl(std::vector<std::array<float, 9>>(60, kTetraTris[0]), "meshpost");
    std::string truncated = full.substr(0, 3000);
    expect_read_error("t.stl", truncated,
                      "binary STL declares 60 triangles (3084 bytes) but the file holds 3000 bytes");
    expect_read_error("h.stl", binary_stl(kTetraTris, "x", 1000),
                      "binary STL declares 1000 triangles (50084 bytes) but the file holds 284 bytes");
    expect_read_error("s.stl", "abc", "too short for a binary STL");
    expect_read_error("a.stl",
                      "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 zero 0\nvertex 0 1 0\n"
                      "endloop\nendfacet\nendsolid x\n",
                      "line 5: bad number 'zero', expected a vertex coordinate");
    expect_read_error("u.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", "ends early");
    expect_read_error("two.stl",
                      "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\n"
                      "endsolid\n",
                      "has 2 vertices, expected at least 3");
    auto nan_tris = kTetraTris;
    nan_tris[2][4] = std::numeric_limits<float>::quiet_NaN();
    expect_read_error("nan.stl", binary_stl(nan_tris, "meshpost"), "triangle 2 has a non-finite coordinate");
    expect_read_error("inf.stl",
                      "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 inf\nvertex 0 1 0\n"
                      "endloop\nendfacet\nendsolid x\n",
                      "non-finite");
    // A binary STL whose header says "solid" but that is truncated is still reported as binary.
    expect_read_error("st.stl", binary_stl(kTetraTris, "solid x").substr(0, 200), "binary STL declares 4 triangles");
}

TEST_F(MeshIo, BadPly) {
    const std::string head =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    expect_read_error("r.ply", head + "3 0 1 3\n", "references vertex 3, expected an index in [0, 3)");
    expect_read_error("n.ply", head + "3 0 -1 2\n", "references vertex -1");
    expect_read_error("f.ply", head + "2 0 1       \n", "has 2 vertices, expected at least 3");
    expect_read_error("fmt.ply", "ply\nformat binary_middle_endian 1.0\nelement vertex 0\nend_header\n",
                      "unsupported PLY format 'binary_middle_endian'");
    expect_read_error("typ.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n0\n",
                      "unsupported property type 'float128'");
    expect_read_error("lt.ply",
                      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 0\nproperty list float int vertex_indices\nend_header\n",
                      "list count type 'float' is unsupported");
    expect_read_error("nh.ply", "ply\nformat ascii 1.0\nelement vertex 0\n", "no 'end_header'");
    expect_read_error("nx.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
                      "lacks one of the properties x, y, z");
    expect_read_error("bn.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                      "end_header\n0 1,5 0\n",
                      "bad number '1,5'");
    expect_read_error("nan.ply",
                      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                      "end_header\n0 nan 0\n",
                      "vertex 0 has a non-finite coordinate");
    expect_read_error("nf.ply", "hello\n", "first line must be 'ply'");
    // Truncated binary data.
    std::string bin =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    for (int i = 0; i < 9; ++i) put_f32(bin, 0.0f);
    std::string bad_face = bin;
    bad_face.push_back(static_cast<char>(200));  // 200 indices declared, file ends after 13 bytes
    for (int i = 0; i < 3; ++i) put_u32(bad_face, 0);
    expect_read_error("tr.ply", bad_face, "truncated");
    expect_read_error("tr2.ply", bin.substr(0, bin.size() - 5), "3 'vertex' elements; the data up to and including them needs at least 36 bytes but only 31 bytes follow");
}

TEST_F(MeshIo, HostilePlyCountsAreRejectedBeforeAllocating) {
    expect_read_error("huge.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
                      "property float y\nproperty float z\nend_header\n0000",
                      "declares 1000000000000");
    expect_read_error("huge2.ply",
                      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 4000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n0 0 1\n0 1 0\n",
                      "4000000000 'face' elements");
    expect_read_error("ovf.ply",
                      "ply\nformat ascii 1.0\nelement vertex 18446744073709551617\nproperty float x\nend_header\n",
                      "is not a valid non-negative 64-bit count");
    expect_read_error("ovf2.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty double x\n"
                      "property double y\nproperty double z\nend_header\n",
                      "more than 32-bit indices can address");
    expect_read_error("ovf3.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty double x\nproperty double y\n"
                      "property double z\nelement junk 4611686018427387904\nproperty double a\nproperty double b\n"
                      "end_header\n",
                      "'junk' elements");
}

TEST_F(MeshIo, BadObj) {
    const std::string v = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    expect_read_error("z.obj", v + "f 0 1 2\n", "line 4: vertex index 0 is invalid");
    expect_read_error("r.obj", v + "f 1 2 4\n", "line 4: vertex index 4 is out of range, 3 vertices are defined so far");
    expect_read_error("n.obj", v + "f -1 -2 -4\n", "vertex index -4 is out of range");
    expect_read_error("two.obj", v + "f 1 2\n", "face has 2 vertices, expected at least 3");
    expect_read_error("bn.obj", "v 0 0 x\n", "line 1: bad number 'x'");
    expect_read_error("short.obj", "v 0 0\n", "expected at least 3 coordinates");
    expect_read_error("nan.obj", "v 0 NaN 0\n", "non-finite");
    expect_read_error("inf.obj", "v 0 1e999 0\n", "bad number '1e999'");
    expect_read_error("ovf.obj", v + "f 1 2 99999999999999999999\n", "bad vertex index");
    expect_read_error("bi.obj", v + "f 1 2 x/1\n", "bad vertex index 'x/1'");
}

TEST_F(MeshIo, BadOff) {
    expect_read_error("h.off", "PFF\n3 1 0\n", "OFF header is 'PFF', expected 'OFF'");
    expect_read_error("c.off", "OFF\n3\n", "counts line");
    expect_read_error("ovf.off", "OFF\n99999999999999999999999 1 0\n", "not a valid count");
    expect_read_error("big.off", "OFF\n4000000000 1 0\n0 0 0\n", "more than the");
    expect_read_error("big2.off", "OFF\n3 1000000000000000 0\n0 0 0\n", "more than the");
    expect_read_error("neg.off", "OFF\n-3 1 0\n", "not a valid count");
    const std::string v = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
    expect_read_error("r.off", v + "3 0 1 3\n", "vertex index '3' is invalid, expected an index in [0, 3)");
    expect_read_error("two.off", v + "2 0 1\n", "face has 2 vertices, expected at least 3");
    expect_read_error("few.off", v + "4 0 1 2\n", "declares 4 vertices but lists 3");
    expect_read_error("tv.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n                   \n", "ends after 2 of 3 vertices");
    expect_read_error("tf.off", v + "\n\n\n\n\n\n", "ends after 0 of 1 faces");
    expect_read_error("inf.off", "OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n", "non-finite");
}

// ---------------------------------------------------------------------------------------------
// Writing failures: no partial file, an existing file survives

TEST_F(MeshIo, UnknownExtensionOnWriteCreatesNothing) {
    EXPECT_THROW(write_mesh(cube(), path("m.stlx")), MeshIoError);
    EXPECT_THROW(write_mesh(cube(), path("m")), MeshIoError);
    EXPECT_TRUE(entries().empty());
}

TEST_F(MeshIo, InvalidMeshOnWriteKeepsExistingFile) {
    write_mesh(cube(), path("m.obj"));
    const std::string before = read_bytes(path("m.obj"));
    TriangleMesh bad = cube();
    bad.faces.push_back({0, 1, 8});
    EXPECT_THROW(write_mesh(bad, path("m.obj")), MeshIoError);
    TriangleMesh nan = cube();
    nan.vertices[2][1] = std::nan("");
    EXPECT_THROW(write_mesh(nan, path("m.obj")), MeshIoError);
    TriangleMesh huge = cube();
    huge.vertices[0][0] = 1e300;  // fine as text, not as float32
    EXPECT_THROW(write_mesh(huge, path("m.stl")), MeshIoError);
    EXPECT_THROW(write_mesh(huge, path("m.ply")), MeshIoError);
    write_mesh(huge, path("h.off"));
    EXPECT_EQ(read_mesh(path("h.off")).vertices[0][0], 1e300);
    EXPECT_EQ(read_bytes(path("m.obj")), before);
    EXPECT_EQ(entries(), (std::vector<std::string>{"h.off", "m.obj"}));
}

TEST_F(MeshIo, MissingDirectory) {
    try {
        write_mesh(cube(), path("no/such/dir/m.stl"));
        ADD_FAILURE();
    } catch (const MeshIoError& e) {
        EXPECT_NE(std::string(e.what()).find("no/such/dir/m.stl"), std::string::npos) << e.what();
    }
    EXPECT_TRUE(entries().empty());
}

TEST_F(MeshIo, FailedRenameRemovesTemporaryAndKeepsTarget) {
    // The target is a non-empty directory: the rename fails after the data was written.
    fs::create_directory(path("m.stl"));
    write_bytes("m.stl/keep", "x");
    EXPECT_THROW(write_mesh(cube(), path("m.stl")), MeshIoError);
    EXPECT_EQ(entries(), (std::vector<std::string>{"m.stl"}));
    EXPECT_EQ(read_bytes(path("m.stl/keep")), "x");
}

TEST_F(MeshIo, UnwritableDirectoryKeepsExistingFile) {
    write_mesh(cube(), path("m.ply"));
    const std::string before = read_bytes(path("m.ply"));
    fs::permissions(dir_, fs::perms::owner_read | fs::perms::owner_exec);
    if (::access(dir_.c_str(), W_OK) == 0) {
        fs::permissions(dir_, fs::perms::owner_all);
        GTEST_SKIP() << "running with privileges that ignore directory permissions";
    }
    EXPECT_THROW(write_mesh(tetrahedron(), path("m.ply")), MeshIoError);
    fs::permissions(dir_, fs::perms::owner_all);
    EXPECT_EQ(read_bytes(path("m.ply")), before);
    EXPECT_EQ(entries(), (std::vector<std::string>{"m.ply"}));
}

// ---------------------------------------------------------------------------------------------
// Robustness: corrupted files either read into a valid mesh or throw MeshIoError, never crash.

TEST_F(MeshIo, CorruptedFilesNeverCrash) {
    std::mt19937 rng(12345);
    const TriangleMesh m = icosphere(3.0, 1);
    for (const char* ext : {".stl", ".ply", ".obj", ".off"}) {
        const std::string clean_path = path(std::string("clean") + ext);
        write_mesh(m, clean_path);
        const std::string clean = read_bytes(clean_path);
        std::vector<std::string> variants;
        // ASCII variants of the binary formats, so that text parsing is fuzzed for every format.
        if (std::string(ext) == ".stl") {
            std::string a = "solid s\n";
            for (const Face& f : m.faces) {
                a += "facet normal 0 0 0\nouter loop\n";
                for (uint32_t v : f)
                    a += "vertex " + std::to_string(m.vertices[v][0]) + " " + std::to_string(m.vertices[v][1]) + " " +
                         std::to_string(m.vertices[v][2]) + "\n";
                a += "endloop\nendfacet\n";
            }
            variants.push_back(a + "endsolid s\n");
        }
        if (std::string(ext) == ".ply") {
            std::string a = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(m.vertices.size()) +
                            "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                            std::to_string(m.faces.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
            for (const Point& p : m.vertices)
                a += std::to_string(p[0]) + " " + std::to_string(p[1]) + " " + std::to_string(p[2]) + "\n";
            for (const Face& f : m.faces)
                a += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
            variants.push_back(a);
        }
        variants.push_back(clean);
        for (const std::string& base : variants) {
            for (int iter = 0; iter < 400; ++iter) {
                std::string s = base;
                const int kind = static_cast<int>(rng() % 4);
                if (kind == 0) {
                    s.resize(rng() % (s.size() + 1));
                } else if (kind == 1) {
                    for (int k = 0, n = 1 + static_cast<int>(rng() % 8); k < n; ++k)
                        s[rng() % s.size()] = static_cast<char>(rng() & 0xFF);
                } else if (kind == 2) {
                    const char* pieces[] = {"9", "-", "99999999999", " ", "\n", "nan", "1e400", "/", "#", "0"};
                    for (int k = 0, n = 1 + static_cast<int>(rng() % 4); k < n; ++k)
                        s.insert(rng() % (s.size() + 1), pieces[rng() % 10]);
                } else {
                    const size_t a = rng() % s.size(), len = rng() % 64;
                    s.erase(a, len);
                }
                const std::string name = std::string("fuzz") + ext;
                write_bytes(name, s);
                try {
                    const TriangleMesh r = read_mesh(path(name));
                    for (const Face& f : r.faces)
                        for (uint32_t v : f) ASSERT_LT(v, r.vertices.size()) << ext << " iteration " << iter;
                    for (const Point& p : r.vertices)
                        for (double c : p) ASSERT_TRUE(std::isfinite(c)) << ext << " iteration " << iter;
                } catch (const MeshIoError&) {
                    // expected for most corruptions
                }
            }
        }
    }
}

TEST_F(MeshIo, PlyElementsWithoutPropertiesAndHeaderAtEndOfFile) {
    // A huge property-less element occupies no data and must not make the reader loop.
    write_bytes("e.ply",
                "ply\nformat binary_little_endian 1.0\nelement empty 1000000000000000000\nelement vertex 0\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n");
    EXPECT_EQ(read_mesh(path("e.ply")).vertices.size(), 0u);
    // Header without a final newline, declaring data that is not there.
    expect_read_error("n.ply",
                      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                      "property float z\nend_header",
                      "needs at least 12 bytes but only 0 bytes follow the header");
}

TEST_F(MeshIo, MinimalTextFilesWithoutFinalNewline) {
    write_bytes("m.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2");
    EXPECT_EQ(read_mesh(path("m.ply")).faces.size(), 1u);
    write_bytes("m.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2");
    EXPECT_EQ(read_mesh(path("m.off")).faces.size(), 1u);
    write_bytes("m.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3");
    EXPECT_EQ(read_mesh(path("m.obj")).faces.size(), 1u);
    write_bytes("m.stl", "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
                         "endfacet\nendsolid");
    EXPECT_EQ(read_mesh(path("m.stl")).faces.size(), 1u);
}

// read_mesh_from_memory (the parser the fuzz targets drive) agrees with read_mesh on a file.
TEST_F(MeshIo, FromMemoryMatchesFileAndRejectsLikeIt) {
    const std::string off = "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n3 0 2 3\n";
    { std::ofstream(path("q.off"), std::ios::binary) << off; }
    const TriangleMesh from_file = read_mesh(path("q.off"));
    for (const char* ext : {".off", "off", ".OFF"}) {
        const TriangleMesh m = read_mesh_from_memory(off, ext);
        EXPECT_EQ(m.vertices, from_file.vertices) << ext;
        EXPECT_EQ(m.faces, from_file.faces) << ext;
        EXPECT_EQ(m.faces.size(), 3u) << ext;
    }
    EXPECT_THROW(read_mesh_from_memory(off, ".xyz"), MeshIoError);
    EXPECT_THROW(read_mesh_from_memory("", ".stl"), MeshIoError);
    EXPECT_THROW(read_mesh_from_memory("OFF\n4 2 0\n0 0 0\n", ".off"), MeshIoError);
    try {
        read_mesh_from_memory("v 0 0 0\nf 1 2 3\n", "obj");
        FAIL() << "expected MeshIoError";
    } catch (const MeshIoError& e) {
        EXPECT_NE(std::string(e.what()).find("<memory>.obj"), std::string::npos) << e.what();
    }
}

TEST_F(MeshIo, WriteFileAtomicReplacesWholeOrNotAtAll) {
    const std::string p = path("report.json");
    write_file_atomic(p, "first");
    EXPECT_EQ(read_bytes(p), "first");
    const std::string binary("a\0b\xff", 4);  // any bytes, not only text
    write_file_atomic(p, binary);
    EXPECT_EQ(read_bytes(p), binary);
    EXPECT_EQ(entries(), std::vector<std::string>{"report.json"});  // no temporary file left
    // A directory that does not exist: an error naming the path, nothing written.
    const std::string missing = path("no/such/dir/r.json");
    try {
        write_file_atomic(missing, "x");
        ADD_FAILURE() << "no error";
    } catch (const MeshIoError& e) {
        EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
    }
    EXPECT_EQ(entries(), std::vector<std::string>{"report.json"});
}
