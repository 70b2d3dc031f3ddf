// `endocast inspect`, `simplify` and `compare` run as a user would.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include "../meshpost/test_meshes.h"
#include "cli_helpers.h"
#include "meshpost/io.h"
#include "meshpost/topology.h"

using namespace cli_test;
using meshpost::TriangleMesh;
namespace mt = meshpost::test;

namespace {

const fs::path& dir() {
    static const fs::path d = temp_dir("mesh");
    return d;
}

std::string save(const TriangleMesh& m, const std::string& name) {
    const fs::path p = dir() / name;
    meshpost::write_mesh(m, p.string());
    return p.string();
}

/// A closed mesh with one zero-area face: a cube edge split at its midpoint m on one side only,
/// closed by the collinear triangle (b, m, a).
TriangleMesh cube_with_degenerate_face() {
    TriangleMesh m = mt::cube(10.0);
    // Edge 0-1 is shared by faces {0,3,1} (0->3->1: traverses 1->0) and {0,1,5} (traverses 0->1).
    const uint32_t mid = static_cast<uint32_t>(m.vertices.size());
    m.vertices.push_back({5.0, 0.0, 0.0});
    for (auto& f : m.faces)
        if (f == meshpost::Face{0, 1, 5}) f = {0, mid, 5};
    m.faces.push_back({mid, 1, 5});
    m.faces.push_back({1, mid, 0});  // collinear: 1 -> mid -> 0 closes both sides
    return m;
}

struct Broken {
    const char* name;
    TriangleMesh mesh;
    const char* code;  ///< expected in JSON "defects"
    const char* text;  ///< expected in the human output
};

std::vector<Broken> broken_meshes() {
    std::vector<Broken> v;
    TriangleMesh hole = mt::icosphere(20.0, 3);
    hole.faces.pop_back();
    v.push_back({"hole.ply", hole, "hole", "hole"});
    TriangleMesh fin;  // two tetrahedra sharing an edge: four faces on edge 0-1
    fin.vertices = {{0, 0, 0}, {10, 0, 0}, {0, 10, 0}, {0, 0, 10}, {0, -10, 0}, {0, 0, -10}};
    fin.faces = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {0, 4, 1}, {0, 1, 5}, {0, 5, 4}, {1, 4, 5}};
    v.push_back({"nm_edge.off", fin, "nonmanifold_edge", "non-manifold edge"});
    // Two tetrahedra sharing only vertex 0 (the second is the first mirrored through the origin,
    // with its faces reversed to stay outward).
    TriangleMesh bowtie = mt::tetrahedron(10.0);
    bowtie.vertices.insert(bowtie.vertices.end(), {{-10, 0, 0}, {0, -10, 0}, {0, 0, -10}});
    for (const auto& f : mt::tetrahedron(10.0).faces) {
        auto map = [](uint32_t i) { return i == 0 ? 0u : i + 3; };
        bowtie.faces.push_back({map(f[0]), map(f[2]), map(f[1])});
    }
    v.push_back({"nm_vertex.obj", bowtie, "nonmanifold_vertex", "non-manifold vertex"});
    TriangleMesh flip = mt::icosphere(20.0, 3);
    std::swap(flip.faces[7][1], flip.faces[7][2]);
    v.push_back({"flipped.ply", flip, "flipped_face", "flipped face"});
    v.push_back({"two_spheres.stl", mt::merged(mt::icosphere(20.0, 3), mt::icosphere(20.0, 3, {15, 0, 0})),
                 "self_intersection", "self-intersection"});
    v.push_back({"degenerate.obj", cube_with_degenerate_face(), "degenerate_face", "degenerate face"});
    v.push_back({"inward.ply", mt::flipped(mt::icosphere(20.0, 3)), "inward", "inward orientation"});
    return v;
}

bool has(const nlohmann::json& arr, const std::string& s) {
    for (const auto& x : arr)
        if (x == s) return true;
    return false;
}

}  // namespace

TEST(CliInspect, CleanMeshExitsZeroWithEveryKey) {
    const std::string m = save(mt::icosphere(50.0, 4), "clean.stl");
    const fs::path js = dir() / "clean.json";
    const CliRun r = run("inspect " + m + " --json " + js.string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("clean closed 2-manifold"), std::string::npos) << r.output;
    const auto j = read_json(js);
    for (const char* k : {"closed", "manifold", "oriented", "outward", "components", "genus", "degenerate_faces",
                          "self_intersections", "volume_ml", "area_mm2", "bbox_mm"})
        EXPECT_TRUE(j.contains(k)) << k;
    EXPECT_TRUE(j["closed"].get<bool>());
    EXPECT_TRUE(j["manifold"].get<bool>());
    EXPECT_TRUE(j["oriented"].get<bool>());
    EXPECT_TRUE(j["outward"].get<bool>());
    EXPECT_EQ(j["components"].get<int>(), 1);
    EXPECT_EQ(j["genus"].get<int>(), 0);
    EXPECT_EQ(j["degenerate_faces"].get<int>(), 0);
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    const double sphere_ml = 4.0 / 3.0 * std::acos(-1.0) * 125000.0 / 1000.0;
    EXPECT_NEAR(j["volume_ml"].get<double>(), sphere_ml, 0.01 * sphere_ml);
    EXPECT_NEAR(j["bbox_mm"]["max"][0].get<double>(), 50.0, 1e-3);
    EXPECT_TRUE(j["defects"].empty());
}

TEST(CliInspect, TorusHasGenusOne) {
    const std::string m = save(mt::torus(30.0, 10.0, 48, 24), "torus.off");
    const fs::path js = dir() / "torus.json";
    ASSERT_EQ(run("inspect " + m + " -q --json " + js.string()).status, 0);
    EXPECT_EQ(read_json(js)["genus"].get<int>(), 1);
}

TEST(CliInspect, FindsEachCraftedDefect) {
    for (const Broken& b : broken_meshes()) {
        SCOPED_TRACE(b.name);
        const std::string m = save(b.mesh, b.name);
        const fs::path js = dir() / (std::string(b.name) + ".json");
        const CliRun r = run("inspect " + m + " --json " + js.string());
        EXPECT_EQ(r.status, 1) << r.output;
        EXPECT_NE(r.output.find("DEFECTS"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(b.text), std::string::npos) << r.output;
        ASSERT_TRUE(fs::exists(js));
        const auto j = read_json(js);
        EXPECT_TRUE(has(j["defects"], b.code)) << j["defects"].dump();
        EXPECT_FALSE(j["clean"].get<bool>());
    }
}

TEST(CliInspect, DefectDetailsInJson) {
    auto inspect = [](const std::string& name) {
        const fs::path js = dir() / (name + ".detail.json");
        run("inspect " + (dir() / name).string() + " -q --json " + js.string());
        return read_json(js);
    };
    for (const Broken& b : broken_meshes()) save(b.mesh, b.name);
    EXPECT_FALSE(inspect("hole.ply")["closed"].get<bool>());
    EXPECT_FALSE(inspect("nm_edge.off")["manifold"].get<bool>());
    EXPECT_FALSE(inspect("nm_vertex.obj")["manifold"].get<bool>());
    EXPECT_FALSE(inspect("flipped.ply")["oriented"].get<bool>());
    EXPECT_GT(inspect("two_spheres.stl")["self_intersections"].get<int>(), 0);
    EXPECT_EQ(inspect("two_spheres.stl")["components"].get<int>(), 2);
    EXPECT_EQ(inspect("degenerate.obj")["degenerate_faces"].get<int>(), 1);
    const auto in = inspect("inward.ply");
    EXPECT_FALSE(in["outward"].get<bool>());
    EXPECT_TRUE(in["oriented"].get<bool>());
    EXPECT_LT(in["volume_ml"].get<double>(), 0.0);
}

TEST(CliMesh, BadInputFailsCleanlyAndWritesNothing) {
    const fs::path d = temp_dir("mesh_bad");
    {  // truncated binary STL: header says 10 triangles, data for 2
        std::ofstream f(d / "trunc.stl", std::ios::binary);
        std::string header(80, ' ');
        f.write(header.data(), 80);
        const uint32_t n = 10;
        f.write(reinterpret_cast<const char*>(&n), 4);
        std::string data(100, '\0');
        f.write(data.data(), data.size());
    }
    {
        std::ofstream f(d / "range.ply");
        f << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
    }
    {
        std::ofstream f(d / "nan.obj");
        f << "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n";
    }
    { std::ofstream f(d / "empty.off"); }
    { std::ofstream f(d / "empty.stl"); }
    {
        std::ofstream f(d / "badnum.stl");
        f << "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 zero\nvertex 0 1 0\n"
             "endloop\nendfacet\nendsolid x\n";
    }
    {
        std::ofstream f(d / "prop.ply");
        f << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float128 x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    }
    {
        std::ofstream f(d / "zero.obj");
        f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n";
    }
    {
        std::ofstream f(d / "negative.obj");
        f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n";
    }
    const std::vector<std::string> inputs = {"trunc.stl", "range.ply", "nan.obj", "empty.off", "empty.stl",
                                             "badnum.stl", "prop.ply", "zero.obj", "negative.obj"};
    const std::string good = save(mt::icosphere(10.0, 2), "good.ply");
    std::vector<std::string> names = inputs;
    names.push_back("missing.stl");
    for (const std::string& name : names) {
        SCOPED_TRACE(name);
        const std::string in = (d / name).string();
        const fs::path out = d / (std::string(name) + ".out");
        CliRun r = run("inspect " + in + " --json " + out.string() + ".json");
        EXPECT_EQ(r.status, 3) << r.output;
        EXPECT_NE(r.output.find("error"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(name), std::string::npos) << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        r = run("simplify " + in + " -o " + out.string() + ".ply --ratio 0.5 --report " + out.string() + ".s.json");
        EXPECT_EQ(r.status, 3) << r.output;
        r = run("compare " + in + " " + good + " --report " + out.string() + ".c.json --colored " + out.string() +
                ".c.ply --histogram " + out.string() + ".png");
        EXPECT_EQ(r.status, 3) << r.output;
        r = run("compare " + good + " " + in + " --report " + out.string() + ".c2.json");
        EXPECT_EQ(r.status, 3) << r.output;
    }
    // Nothing but the inputs is left in the directory (no output, no temporary file).
    size_t files = 0;
    for (const auto& e : fs::directory_iterator(d)) {
        ++files;
        const std::string n = e.path().filename().string();
        EXPECT_NE(std::find(inputs.begin(), inputs.end(), n), inputs.end()) << n;
    }
    EXPECT_EQ(files, inputs.size());
}

TEST(CliSimplify, ReportKeysAndACleanResult) {
    const std::string in = save(mt::torus(30.0, 10.0, 120, 60), "torus_fine.ply");
    const fs::path out = dir() / "torus_s.obj", js = dir() / "torus_s.json";
    const CliRun r = run("simplify " + in + " -o " + out.string() + " --ratio 0.1 --report " + js.string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(js);
    for (const char* k : {"faces_before", "faces_after", "volume_change_pct", "hausdorff_mm"})
        EXPECT_TRUE(j.contains(k)) << k;
    EXPECT_EQ(j["faces_before"].get<int>(), 14400);
    EXPECT_NEAR(j["faces_after"].get<double>(), 1440.0, 2.0);
    EXPECT_LT(std::fabs(j["volume_change_pct"].get<double>()), 2.0);
    EXPECT_LT(j["hausdorff_mm"].get<double>(), 1.0);
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    EXPECT_EQ(j["max_error_mm"].get<double>(), 0.35);  // the default distance bound
    EXPECT_GE(j["max_error_used_mm"].get<double>(), 0.35);
    const auto t = meshpost::analyze_topology(meshpost::read_mesh(out.string()));
    EXPECT_TRUE(meshpost::is_closed_manifold(t));
    EXPECT_EQ(t.genus, 1);
    EXPECT_EQ(run("inspect " + out.string() + " -q").status, 0);
}

TEST(CliSimplify, ParameterErrors) {
    const std::string in = save(mt::icosphere(10.0, 3), "s3.ply");
    const std::string out = (dir() / "s3_out.ply").string();
    EXPECT_EQ(run("simplify " + in + " -o " + out + " --faces 100 --ratio 0.5").status, 2);  // excludes
    EXPECT_EQ(run("simplify " + in + " -o " + out).status, 4);                              // neither
    EXPECT_EQ(run("simplify " + in + " -o " + out + " --ratio 1.5").status, 2);
    EXPECT_EQ(run("simplify " + in + " -o " + out + " --ratio 0.5 --max-error -1").status, 2);
    EXPECT_EQ(run("simplify " + in + " -o " + (dir() / "x.xyz").string() + " --ratio 0.5").status, 4);
    const std::string bad = save(broken_meshes()[1].mesh, "nm_for_simplify.off");
    EXPECT_EQ(run("simplify " + bad + " -o " + out + " --ratio 0.5").status, 3);
    EXPECT_FALSE(fs::exists(out));
}

TEST(CliCompare, ConcentricSpheresReportAndOutputs) {
    const std::string a = save(mt::icosphere(50.0, 5), "r50.ply"), b = save(mt::icosphere(51.0, 5), "r51.ply");
    const fs::path js = dir() / "cmp.json", col = dir() / "cmp_col.ply", png = dir() / "cmp.png";
    const CliRun r = run("compare " + a + " " + b + " --report " + js.string() + " --colored " + col.string() +
                      " --histogram " + png.string() + " --scale 2");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(js);
    for (const char* dirn : {"a_to_b", "b_to_a"}) {
        for (const char* k : {"mean", "rms", "median", "p95", "max"}) EXPECT_TRUE(j[dirn].contains(k)) << dirn << k;
        EXPECT_NEAR(j[dirn]["mean"].get<double>(), 1.0, 0.01);
    }
    EXPECT_TRUE(j.contains("hausdorff"));
    EXPECT_TRUE(j.contains("samples"));
    EXPECT_TRUE(j.contains("sampling_error_bound_mm"));
    EXPECT_FALSE(j.contains("alignment"));
    EXPECT_GT(j["samples"].get<size_t>(), 2u * 20480u);
    // The coloured mesh reads back as A; every vertex is 1 mm away: half the scale -> green.
    const TriangleMesh c = meshpost::read_mesh(col.string());
    EXPECT_EQ(c.faces.size(), 20480u);
    std::ifstream f(col, std::ios::binary);
    std::string head, line;
    while (std::getline(f, line) && line != "end_header") head += line + "\n";
    EXPECT_NE(head.find("property uchar red"), std::string::npos);
    char rec[19];
    f.read(rec, 19);
    EXPECT_LE(static_cast<unsigned char>(rec[12]), 5);    // red
    EXPECT_GE(static_cast<unsigned char>(rec[13]), 250);  // green
    EXPECT_LE(static_cast<unsigned char>(rec[14]), 5);    // blue
    // A PNG that another decoder reads: a colour picture of the plot's size, not blank.
    const cv::Mat img = cv::imread(png.string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty());
    EXPECT_EQ(img.type(), CV_8UC3);
    EXPECT_GE(img.cols, 400);
    double lo = 0, hi = 0;
    cv::minMaxLoc(img.reshape(1), &lo, &hi);
    EXPECT_LT(lo, hi);
}

TEST(CliCompare, RigidAlignmentRecoversAKnownMotion) {
    TriangleMesh b = mt::icosphere(1.0, 4);
    for (auto& p : b.vertices) p = {40 * p[0] + 4 * p[1] * p[1], 28 * p[1], 20 * p[2] + 3 * p[0] * p[0]};
    // A = B rotated 20 deg about z and moved 15 mm along x.
    TriangleMesh a = b;
    const double th = 20.0 * std::acos(-1.0) / 180.0;
    for (auto& p : a.vertices) p = {std::cos(th) * p[0] - std::sin(th) * p[1] + 15.0, std::sin(th) * p[0] + std::cos(th) * p[1], p[2]};
    const std::string pa = save(a, "moved.ply"), pb = save(b, "fixed.ply");
    const fs::path js = dir() / "align.json";
    CliRun r = run("compare " + pa + " " + pb + " --align rigid --report " + js.string());
    ASSERT_EQ(r.status, 0) << r.output;
    auto j = read_json(js);
    ASSERT_TRUE(j.contains("alignment"));
    for (const char* k : {"rotation", "translation", "rmse"}) EXPECT_TRUE(j["alignment"].contains(k)) << k;
    EXPECT_NEAR(j["alignment"]["rotation_deg"].get<double>(), 20.0, 0.1);
    // Inverse motion: R^T (x - t), so the translation is -R^T (15, 0, 0).
    EXPECT_NEAR(j["alignment"]["translation"][0].get<double>(), -15.0 * std::cos(th), 0.05);
    EXPECT_NEAR(j["alignment"]["translation"][1].get<double>(), 15.0 * std::sin(th), 0.05);
    EXPECT_NEAR(j["alignment"]["translation"][2].get<double>(), 0.0, 0.05);
    EXPECT_LT(j["a_to_b"]["mean"].get<double>(), 0.01);
    EXPECT_LT(j["b_to_a"]["mean"].get<double>(), 0.01);
    // Without alignment the same pair is far apart.
    r = run("compare " + pa + " " + pb + " --report " + js.string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_GT(read_json(js)["a_to_b"]["mean"].get<double>(), 1.0);
}

TEST(CliCompare, ParameterErrors) {
    const std::string a = save(mt::icosphere(10.0, 2), "pa.ply");
    EXPECT_EQ(run("compare " + a + " " + a + " --align affine").status, 2);
    EXPECT_EQ(run("compare " + a + " " + a + " --scale 0").status, 2);
    EXPECT_EQ(run("compare " + a + " " + a + " --colored " + (dir() / "c.stl").string()).status, 4);
    EXPECT_EQ(run("compare " + a + " " + a + " --histogram " + (dir() / "h.jpg").string()).status, 4);
}

TEST(CliMeshRealData, CtheadEndocastSimplifiedToTenPercent) {
    if (!fs::exists(shared("cthead/cthead.nhdr")))
        GTEST_SKIP() << "../shared/data/cthead/cthead.nhdr not found: real-data test skipped";
    const fs::path d = temp_dir("cthead_simplify");
    CliRun r = run("extract " + shared("cthead/cthead.nhdr") + " --iso 1300 -q -o " + (d / "c.ply").string());
    ASSERT_EQ(r.status, 0) << r.output;
    r = run("simplify " + (d / "c.ply").string() + " -o " + (d / "s.ply").string() + " --ratio 0.1 --report " +
            (d / "s.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    std::cout << r.output;
    const auto j = read_json(d / "s.json");
    EXPECT_NEAR(j["faces_after"].get<double>(), 0.1 * j["faces_before"].get<double>(), 2.0);
    EXPECT_LT(std::fabs(j["volume_change_pct"].get<double>()), 0.3);
    EXPECT_TRUE(j["closed"].get<bool>());
    EXPECT_TRUE(j["manifold"].get<bool>());
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    EXPECT_EQ(j["degenerate_faces"].get<int>(), 0);
    EXPECT_EQ(j["genus"], j["genus_before"]);
    // The bar, met with the default distance bound (0.35 mm; 1.27 mm without it).
    EXPECT_LT(j["hausdorff_mm"].get<double>(), 0.5);
    EXPECT_EQ(j["max_error_used_mm"].get<double>(), 0.35);
    r = run("inspect " + (d / "s.ply").string() + " -q");
    EXPECT_EQ(r.status, 0) << r.output;
}
