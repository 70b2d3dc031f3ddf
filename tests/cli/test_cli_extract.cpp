#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>

#include "cli_helpers.h"
#include "endocast/io.h"
#include "meshpost/io.h"
#include "meshpost/measure.h"
#include "meshpost/topology.h"

using namespace cli_test;

namespace {

// One small phantom shared by the tests of this file (macaque: small and quick).
const fs::path& phantom_dir() {
    static const fs::path d = [] {
        fs::path dir = temp_dir("phantom");
        const CliRun r = run("phantom " + (dir / "mq.nrrd").string() + " --preset macaque --seed 3");
        if (r.status != 0) throw std::runtime_error("phantom failed: " + r.output);
        return dir;
    }();
    return d;
}

}  // namespace

TEST(CliPhantom, WritesVolumeAndGroundTruth) {
    const fs::path d = phantom_dir();
    ASSERT_TRUE(fs::exists(d / "mq.nrrd"));
    const auto j = read_json(d / "mq.json");
    EXPECT_NEAR(j["true_ecv_ml"].get<double>(), 88.87, 0.1);
    EXPECT_EQ(j["preset"], "macaque");
    EXPECT_GT(j["suggested_iso"].get<double>(), 0.0);
}

TEST(CliPhantom, FeatureFlagsAndEvaluationKeysInTheSidecar) {
    const fs::path out = temp_dir("phantomfull");
    const CliRun r = run("phantom " + (out / "f.nrrd").string() +
                         " --preset macaque --spine --sinus --orbits --crop-base 6 --tilt 10 --no-noise");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "f.json");
    const auto& f = j["features"];
    EXPECT_TRUE(f["spine"].get<bool>());
    EXPECT_TRUE(f["frontal_sinus"].get<bool>());
    EXPECT_TRUE(f["orbits"].get<bool>());
    EXPECT_FALSE(f["body"].get<bool>());
    EXPECT_DOUBLE_EQ(f["crop_base_mm"].get<double>(), 6.0);
    EXPECT_DOUBLE_EQ(f["optic_canal_radius_mm"].get<double>(), 3.5);
    for (const char* k : {"foramen_magnum_mm", "foramen_magnum_axis", "cavity_rotation", "openings",
                          "crop_plane_z_mm", "true_ecv_slice_centres_ml", "spinal_canal_radius_mm"})
        EXPECT_TRUE(j.contains(k)) << k;
    EXPECT_TRUE(j["cropped"].get<bool>());
    EXPECT_LT(j["true_ecv_ml"].get<double>(), 88.0);
    EXPECT_EQ(j["openings"].size(), 9u);
    EXPECT_EQ(j["openings"][0]["name"], "foramen_magnum");
    EXPECT_EQ(j["cavity_rotation"].size(), 3u);
    // human-full is the human study case.
    const CliRun h = run("phantom " + (out / "h.nrrd").string() + " --preset human-full --size 180 260 280");
    ASSERT_EQ(h.status, 0) << h.output;
    const auto jh = read_json(out / "h.json");
    EXPECT_EQ(jh["preset"], "human");
    EXPECT_EQ(jh["preset_name"], "human-full");
    EXPECT_TRUE(jh["features"]["spine"].get<bool>() && jh["features"]["orbits"].get<bool>());
    // body needs soft tissue.
    EXPECT_NE(run("phantom " + (out / "d.nrrd").string() + " --preset dry --body").status, 0);
}

TEST(CliPhantom, MouseSidecarHasTheLandmarks) {
    const fs::path out = temp_dir("phantommouse");
    const CliRun r = run("phantom " + (out / "m.nrrd").string() + " --preset rodent --spacing 0.2 0.2 0.2 --no-noise");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "m.json");
    EXPECT_EQ(j["preset"], "mouse");
    EXPECT_EQ(j["preset_name"], "rodent");
    EXPECT_NEAR(j["true_ecv_ml"].get<double>(), 0.4488, 0.001);
    EXPECT_TRUE(j["features"]["spine"].get<bool>());
    const auto& l = j["landmarks"];
    for (const char* k : {"basion_mm", "opisthion_mm", "cribriform_plate_centre_mm"}) EXPECT_EQ(l[k].size(), 3u) << k;
    const auto p = l["foramen_magnum_plane"]["point_mm"], n = l["foramen_magnum_plane"]["normal"];
    for (const char* k : {"basion_mm", "opisthion_mm"}) {
        double d = 0;
        for (int a = 0; a < 3; ++a) d += (l[k][a].get<double>() - p[a].get<double>()) * n[a].get<double>();
        EXPECT_NEAR(d, 0.0, 1e-9) << k;
    }
    EXPECT_EQ(l["symmetry_plane"]["normal"], nlohmann::json::array({1.0, 0.0, 0.0}));
    EXPECT_EQ(j["openings"].back()["name"], "cribriform_plate");
    // A window: --size with --grid-centre; the other phantoms' sidecars have no landmarks.
    const CliRun w = run("phantom " + (out / "w.nrrd").string() +
                         " --preset mouse --spacing 0.05 0.05 0.05 --size 20 20 20 --grid-centre 0 7.7 -0.35");
    ASSERT_EQ(w.status, 0) << w.output;
    EXPECT_EQ(read_json(out / "w.json")["dims"], nlohmann::json::array({20, 20, 20}));
    EXPECT_FALSE(read_json(phantom_dir() / "mq.json").contains("landmarks"));
}

TEST(CliExtract, WritesMeshMaskAndReportWithTheContractKeys) {
    const fs::path d = phantom_dir(), out = temp_dir("extract");
    const auto truth = read_json(d / "mq.json");
    const CliRun r = run("extract " + (d / "mq.nrrd").string() + " -o " + (out / "e.stl").string() +
                      " --mask " + (out / "e_mask.nii.gz").string() + " --report " +
                      (out / "e.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("ECV"), std::string::npos);
    const auto j = read_json(out / "e.json");
    for (const char* k : {"input", "ecv_ml", "mask_volume_ml", "surface_area_mm2", "vertices", "faces",
                          "closed_manifold", "self_intersections", "timings_s", "peak_memory_mb",
                          "isovalue", "void_radius_voxels", "void_radius_mm", "seed_mode",
                          "seed_scale", "seed_points_mm", "parameters"})
        EXPECT_TRUE(j.contains(k)) << k;
    for (const char* k : {"path", "dims", "spacing", "voxel_type"}) EXPECT_TRUE(j["input"].contains(k)) << k;
    for (const char* k : {"binarize", "void_fill", "distance", "seeds", "watershed", "polygonize", "total"})
        EXPECT_TRUE(j["timings_s"].contains(k)) << k;
    EXPECT_TRUE(j["closed_manifold"].get<bool>());
    EXPECT_EQ(j["self_intersections"].get<int>(), 0);
    ASSERT_TRUE(j.contains("huge_pages"));
    EXPECT_TRUE(j["huge_pages"].is_boolean());
    EXPECT_EQ(j["self_intersection_check"]["faces"], "moved after marching cubes");
    EXPECT_EQ(j["ct_storage"], "int16");  // an int16 phantom: held as int16 (the same result)
    EXPECT_LE(j["self_intersection_check"]["faces_tested"].get<size_t>(), j["faces"].get<size_t>());
    EXPECT_EQ(j["seed_mode"], "auto");
    EXPECT_NEAR(j["ecv_ml"].get<double>() / truth["true_ecv_ml"].get<double>(), 1.0, 0.01);
    EXPECT_EQ(j["input"]["dims"], truth["dims"]);

    // The mesh file holds the same closed surface.
    const auto mesh = meshpost::read_mesh((out / "e.stl").string());
    EXPECT_EQ(mesh.faces.size(), j["faces"].get<size_t>());
    EXPECT_TRUE(meshpost::is_closed_manifold(meshpost::analyze_topology(mesh)));
    EXPECT_NEAR(meshpost::signed_volume_mm3(mesh) / 1000.0, j["ecv_ml"].get<double>(), 0.01 * j["ecv_ml"].get<double>());

    // The mask has the input's geometry and the reported volume.
    const auto mask = endocast::read_volume({(out / "e_mask.nii.gz").string()}).volume;
    const auto ct = endocast::read_volume({(d / "mq.nrrd").string()}).volume;
    EXPECT_EQ(mask.dims(), ct.dims());
    for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(mask.geometry().spacing[a], ct.geometry().spacing[a], 1e-6);
        EXPECT_NEAR(mask.geometry().origin[a], ct.geometry().origin[a], 1e-6);
    }
    double n = 0;
    for (size_t i = 0; i < mask.size(); ++i) n += mask[i] > 0;
    EXPECT_NEAR(n * mask.geometry().voxel_volume_mm3() / 1000.0, j["mask_volume_ml"].get<double>(), 1e-6);
}

TEST(CliExtract, EveryMeshFormatOpensAgain) {
    const fs::path d = phantom_dir(), out = temp_dir("formats");
    for (const char* ext : {".stl", ".ply", ".obj", ".off"}) {
        const fs::path m = out / (std::string("m") + ext);
        const CliRun r = run("extract " + (d / "mq.nrrd").string() + " -q -o " + m.string());
        ASSERT_EQ(r.status, 0) << ext << ": " << r.output;
        const auto mesh = meshpost::read_mesh(m.string());
        EXPECT_TRUE(meshpost::is_closed_manifold(meshpost::analyze_topology(mesh))) << ext;
    }
}

TEST(CliExtract, SeedModesDistanceAndPoint) {
    const fs::path d = phantom_dir(), out = temp_dir("seedmodes");
    const auto truth = read_json(d / "mq.json");
    const auto c = truth["cavity_centre_mm"];
    CliRun r = run("extract " + (d / "mq.nrrd").string() + " --seed-mode distance --distance-threshold 8 --report " +
                (out / "dist.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_NEAR(read_json(out / "dist.json")["ecv_ml"].get<double>() / truth["true_ecv_ml"].get<double>(), 1.0, 0.01);
    r = run("extract " + (d / "mq.nrrd").string() + " --seed-point " + std::to_string(c[0].get<double>()) + " " +
            std::to_string(c[1].get<double>()) + " " + std::to_string(c[2].get<double>()) + " --report " +
            (out / "pt.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "pt.json");
    EXPECT_EQ(j["seed_mode"], "point");
    EXPECT_NEAR(j["seed_points_mm"][0][0].get<double>(), c[0].get<double>(), 0.5);
    EXPECT_NEAR(j["ecv_ml"].get<double>() / truth["true_ecv_ml"].get<double>(), 1.0, 0.01);
}

TEST(CliExtract, HelpExplainsUnitsDefaultsAndExitCodes) {
    const CliRun r = run("extract --help");
    EXPECT_EQ(r.status, 0);
    for (const char* s : {"--iso", "--void-radius", "--seed-mode", "--seed-scale", "--raw-size",
                          "--mask", "--report", "mm", "0.9", "6"})
        EXPECT_NE(r.output.find(s), std::string::npos) << s;
    const CliRun top = run("--help");
    EXPECT_NE(top.output.find("Exit status"), std::string::npos);
}

TEST(CliExtract, BadInputGivesAClearErrorAndWritesNothing) {
    const fs::path d = phantom_dir(), out = temp_dir("bad");
    CliRun r = run("extract " + (out / "missing.nrrd").string() + " -o " + (out / "x.stl").string());
    EXPECT_EQ(r.status, 3) << r.output;
    EXPECT_NE(r.output.find("missing.nrrd"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "x.stl"));

    r = run("extract " + (d / "mq.nrrd").string() + " -o " + (out / "x.xyz").string());
    EXPECT_EQ(r.status, 4) << r.output;
    EXPECT_FALSE(fs::exists(out / "x.xyz"));

    r = run("extract " + (d / "mq.nrrd").string() + " --iso 100000 -o " + (out / "x.stl").string() +
            " --report " + (out / "x.json").string());
    EXPECT_EQ(r.status, 5) << r.output;
    EXPECT_NE(r.output.find("100000"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "x.stl"));
    EXPECT_FALSE(fs::exists(out / "x.json"));

    r = run("extract " + (d / "mq.nrrd").string() + " --seed-scale 1.5");
    EXPECT_EQ(r.status, 2) << r.output;
    r = run("extract");
    EXPECT_EQ(r.status, 2) << r.output;
    // An existing output survives a failed run.
    {
        std::ofstream keep(out / "keep.stl");
        keep << "precious";
    }
    r = run("extract " + (d / "mq.nrrd").string() + " --iso 100000 -o " + (out / "keep.stl").string());
    EXPECT_EQ(r.status, 5);
    std::ifstream in(out / "keep.stl");
    std::string s;
    in >> s;
    EXPECT_EQ(s, "precious");
}

// The mesh is written during the check; an error after that (here the mask's target is a directory:
// its rename fails) leaves no mesh behind, with one thread and with two.
TEST(CliExtract, AnErrorAfterTheMeshIsWrittenRemovesIt) {
    const fs::path d = phantom_dir(), out = temp_dir("late_error");
    fs::create_directories(out / "mask.nrrd");
    for (const char* threads : {"1", "2"}) {
        const CliRun r = run(std::string("--threads ") + threads + " extract " + (d / "mq.nrrd").string() + " -o " +
                             (out / "m.ply").string() + " --mask " + (out / "mask.nrrd").string() + " -q");
        EXPECT_EQ(r.status, 3) << r.output;
        EXPECT_NE(r.output.find("mask.nrrd"), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out / "m.ply")) << threads << " threads";
    }
}

TEST(CliExtract, CropAndDownsampleKeepTheWorldPlacement) {
    const fs::path d = phantom_dir(), out = temp_dir("shrink");
    const auto dims = read_json(d / "mq.json")["dims"];
    const int64_t nx = dims[0], ny = dims[1], nz = dims[2];
    struct Run {
        std::string args;
        double ecv_tol;  ///< relative to the full-resolution ECV
        double centroid_tol_mm;
    };
    // The head has a 10 mm (20 voxel) margin: crop 7..13 voxels off each side, uneven on purpose.
    const std::string box = "7 9 11 " + std::to_string(nx - 13) + " " + std::to_string(ny - 8) + " " +
                            std::to_string(nz - 10);
    const Run runs[] = {{"", 0, 0}, {"--crop " + box, 0.002, 0.05}, {"--downsample 2", 0.02, 0.25},
                        {"--crop " + box + " --downsample 2", 0.02, 0.25}};
    double ecv0 = 0;
    meshpost::Point c0{};
    for (size_t i = 0; i < std::size(runs); ++i) {
        SCOPED_TRACE(runs[i].args);
        const fs::path mesh = out / ("m" + std::to_string(i) + ".stl"), rep = out / ("r" + std::to_string(i) + ".json");
        const CliRun r = run("extract " + (d / "mq.nrrd").string() + " -q " + runs[i].args + " -o " + mesh.string() +
                             " --report " + rep.string());
        ASSERT_EQ(r.status, 0) << r.output;
        const auto j = read_json(rep);
        const auto m = meshpost::read_mesh(mesh.string());
        const meshpost::Point c = meshpost::volume_centroid(m);
        const double ecv = j["ecv_ml"].get<double>();
        if (i == 0) {
            ecv0 = ecv;
            c0 = c;
            EXPECT_TRUE(j["parameters"]["crop"].is_null());
            EXPECT_EQ(j["parameters"]["downsample"], 1);
            continue;
        }
        EXPECT_NEAR(ecv / ecv0, 1.0, runs[i].ecv_tol);
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(c[a], c0[a], runs[i].centroid_tol_mm) << "axis " << a;
        EXPECT_TRUE(j["closed_manifold"].get<bool>());
        EXPECT_EQ(j["input"]["dims"], dims);  // the input as read; the grid worked on is separate
        if (runs[i].args.find("--crop") != std::string::npos)
            EXPECT_EQ(j["parameters"]["crop"], nlohmann::json({7, 9, 11, nx - 13, ny - 8, nz - 10}));
        const int f = runs[i].args.find("--downsample 2") != std::string::npos ? 2 : 1;
        EXPECT_EQ(j["parameters"]["downsample"], f);
        EXPECT_DOUBLE_EQ(j["parameters"]["work_grid"]["spacing"][0].get<double>(),
                         j["input"]["spacing"][0].get<double>() * f);
    }
}

TEST(CliExtract, CavityCutByTheVolumeBorderKeepsItsVolumeWithBorderSeedScaleZero) {
    // The macaque phantom with its base cut 6 mm above the bottom of the cavity: border balls of
    // the seed scale eat into the cavity; --border-seed-scale 0 seeds only the face voxels, and so
    // does the default once it sees the chosen cavity poorly enclosed (with a warning).
    const fs::path out = temp_dir("cropped");
    CliRun r = run("phantom " + (out / "c.nrrd").string() + " --preset macaque --crop-base 6 -q");
    ASSERT_EQ(r.status, 0) << r.output;
    const double truth = read_json(out / "c.json")["true_ecv_ml"].get<double>();
    r = run("extract " + (out / "c.nrrd").string() + " -q --report " + (out / "a.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    r = run("extract " + (out / "c.nrrd").string() + " -q --border-seed-scale 0 --report " +
            (out / "b.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto a = read_json(out / "a.json"), b = read_json(out / "b.json");
    EXPECT_NEAR(a["ecv_ml"].get<double>() / truth, 1.0, 0.02);
    EXPECT_EQ(a["parameters"]["border_seed_scale"].get<double>(), 0.0);
    EXPECT_NE(a["warnings"].dump().find("cropped through the braincase"), std::string::npos);
    r = run("extract " + (out / "c.nrrd").string() + " -q --border-seed-scale 0.9 --report " +
            (out / "s.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_LT(read_json(out / "s.json")["ecv_ml"].get<double>() / truth, 0.9);  // the failure this is for
    EXPECT_NEAR(b["ecv_ml"].get<double>() / truth, 1.0, 0.02);
    EXPECT_TRUE(b["closed_manifold"].get<bool>());
    EXPECT_EQ(b["parameters"]["border_seed_scale"].get<double>(), 0.0);
}

TEST(CliExtract, TiffStackMultiPageAndNrrdOfTheSameVoxelsGiveTheSameMesh) {
    // The phantom of phantom_dir() written again as a folder of TIFF slices and as one multi-page
    // TIFF (the generator is deterministic): the same voxels, so the same mesh bytes and ECV.
    const fs::path d = phantom_dir(), out = temp_dir("tiff");
    fs::create_directories(out / "stack");
    ASSERT_EQ(run("phantom " + (out / "stack/slice%04d.tif").string() + " --preset macaque --seed 3 -q").status, 0);
    ASSERT_EQ(run("phantom " + (out / "mq.tif").string() + " --preset macaque --seed 3 -q").status, 0);
    EXPECT_TRUE(fs::exists(out / "stack/slice0000.tif"));
    EXPECT_TRUE(fs::exists(out / "stack/slice.json"));  // the sidecar, named without the number
    EXPECT_TRUE(fs::exists(out / "mq.json"));
    auto extract = [&](const std::string& in, const std::string& name, const std::string& extra = "") {
        const CliRun r = run("extract " + in + " -o " + (out / (name + ".ply")).string() + " --report " +
                             (out / (name + ".json")).string() + " " + extra);
        EXPECT_EQ(r.status, 0) << r.output;
        return r;
    };
    extract((d / "mq.nrrd").string(), "nrrd");
    const CliRun folder = extract((out / "stack").string(), "folder");
    EXPECT_NE(folder.output.find("voxel size: ImageJ description"), std::string::npos) << folder.output;
    extract("'" + (out / "stack/slice%04d.tif").string() + "'", "pattern");
    extract((out / "mq.tif").string(), "multipage");
    const auto nrrd = read_json(out / "nrrd.json");
    const std::string mesh = [&] {
        std::ifstream in(out / "nrrd.ply", std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    }();
    for (const char* name : {"folder", "pattern", "multipage"}) {
        SCOPED_TRACE(name);
        const auto j = read_json(out / (std::string(name) + ".json"));
        EXPECT_EQ(j["input"]["format"], "tiff");
        EXPECT_EQ(j["input"]["voxel_type"], "int16");
        EXPECT_EQ(j["input"]["spacing"], nrrd["input"]["spacing"]);
        EXPECT_EQ(j["input"]["origin"], nrrd["input"]["origin"]);
        EXPECT_NE(j["input"]["spacing_source"].get<std::string>().find("ImageJ"), std::string::npos);
        EXPECT_EQ(j["ecv_ml"], nrrd["ecv_ml"]);
        std::ifstream in(out / (std::string(name) + ".ply"), std::ios::binary);
        EXPECT_TRUE(std::string(std::istreambuf_iterator<char>(in), {}) == mesh) << "mesh bytes differ";
    }
    EXPECT_EQ(read_json(out / "folder.json")["input"]["files_read"], 155);

    // --spacing replaces the files' voxel size, with a warning; it is refused for a format with its own.
    const CliRun given = extract((out / "stack").string(), "given", "--spacing 0.5 0.5 0.6");
    EXPECT_NE(given.output.find("replaces the files'"), std::string::npos) << given.output;
    const auto g = read_json(out / "given.json");
    EXPECT_EQ(g["input"]["spacing_source"], "given (--spacing)");
    EXPECT_DOUBLE_EQ(g["input"]["spacing"][2].get<double>(), 0.6);
    const CliRun refused = run("extract " + (d / "mq.nrrd").string() + " --spacing 1 1 1 -o " + (out / "r.ply").string());
    EXPECT_EQ(refused.status, 4) << refused.output;
    EXPECT_NE(refused.output.find("TIFF"), std::string::npos) << refused.output;
    EXPECT_FALSE(fs::exists(out / "r.ply"));
}

TEST(CliPhantom, StreamedSlabBySlabGivesTheSameVoxelsTruthAndMesh) {
    // phantom --stream renders and writes a slab at a time (what a microCT-size phantom does on its
    // own): the same voxels as the whole volume of phantom_dir(), so the same sidecar and mesh.
    const fs::path d = phantom_dir(), out = temp_dir("stream");
    const CliRun w = run("phantom " + (out / "s.nrrd").string() + " --preset macaque --seed 3 --stream");
    ASSERT_EQ(w.status, 0) << w.output;
    EXPECT_NE(w.output.find("slab by slab"), std::string::npos) << w.output;
    EXPECT_NE(w.output.find("slices,"), std::string::npos) << w.output;  // progress
    auto side = read_json(out / "s.json"), whole = read_json(d / "mq.json");
    EXPECT_EQ(side, whole);
    for (const char* name : {"s", "mq"}) {
        const fs::path in = std::string(name) == "s" ? out / "s.nrrd" : d / "mq.nrrd";
        const CliRun r = run("extract " + in.string() + " -q -o " + (out / (std::string(name) + ".ply")).string() +
                             " --report " + (out / (std::string(name) + "_report.json")).string());
        ASSERT_EQ(r.status, 0) << r.output;
    }
    const auto bytes = [](const fs::path& f) {
        std::ifstream in(f, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_TRUE(bytes(out / "s.ply") == bytes(out / "mq.ply")) << "mesh bytes differ";
    EXPECT_EQ(read_json(out / "s_report.json")["ecv_ml"], read_json(out / "mq_report.json")["ecv_ml"]);
    // A format that cannot be written a slab at a time: refused, nothing written.
    const CliRun bad = run("phantom " + (out / "s.nii.gz").string() + " --preset macaque --stream");
    EXPECT_NE(bad.status, 0);
    EXPECT_NE(bad.output.find("slab by slab"), std::string::npos) << bad.output;
    EXPECT_FALSE(fs::exists(out / "s.nii.gz"));
    EXPECT_FALSE(fs::exists(out / "s.nii.json"));
}

TEST(CliExtract, CropAndDownsampleReadNrrdInSlabsWithTheSameMeshAsAWholeRead) {
    // The raw NRRD that phantom --stream writes, an uncompressed MetaImage header over its voxels and
    // the gzip NRRD of phantom_dir() are read a slab at a time and shrunk on the way; the compressed
    // MetaImage of the same voxels is read whole and then shrunk: the same mesh bytes, and the log
    // and the report say which way each was read.
    const fs::path d = phantom_dir(), out = temp_dir("slabs");
    ASSERT_EQ(run("phantom " + (out / "s.nrrd").string() + " --preset macaque --seed 3 --stream -q").status, 0);
    ASSERT_EQ(run("phantom " + (out / "w.mha").string() + " --preset macaque --seed 3 -q").status, 0);
    const std::string shrink = " --crop 4 6 2 160 190 150 --downsample 2";
    const auto extract = [&](const fs::path& in, const std::string& name) {
        const CliRun r = run("extract " + in.string() + shrink + " -o " + (out / (name + ".ply")).string() +
                             " --report " + (out / (name + ".json")).string());
        EXPECT_EQ(r.status, 0) << r.output;
        return r;
    };
    // An uncompressed MetaImage header over the same voxels (the raw NRRD's data are its last bytes).
    std::ofstream(out / "s.mhd") << "ObjectType = Image\nNDims = 3\nDimSize = 163 195 155\n"
                                    "ElementSpacing = 0.5 0.5 0.5\nOffset = 0 0 0\nElementType = MET_SHORT\n"
                                    "HeaderSize = -1\nElementDataFile = s.nrrd\n";
    const CliRun raw = extract(out / "s.nrrd", "raw");
    const CliRun mhd = extract(out / "s.mhd", "mhd");
    const CliRun gz = extract(d / "mq.nrrd", "gz");
    const CliRun whole = extract(out / "w.mha", "whole");
    EXPECT_NE(raw.output.find("read in slabs"), std::string::npos) << raw.output;
    EXPECT_NE(gz.output.find("read in slabs"), std::string::npos) << gz.output;
    EXPECT_NE(whole.output.find("read whole, then cropped/downsampled"), std::string::npos) << whole.output;
    const auto jw = read_json(out / "whole.json");
    EXPECT_EQ(jw["input"]["read_path"], "whole");
    EXPECT_EQ(jw["work_grid"]["dims"][0], 78);
    const auto bytes = [](const fs::path& f) {
        std::ifstream in(f, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    for (const char* name : {"raw", "gz", "mhd"}) {
        SCOPED_TRACE(name);
        const auto j = read_json(out / (std::string(name) + ".json"));
        EXPECT_EQ(j["input"]["read_path"], "slabs");
        EXPECT_EQ(j["input"]["dims"], jw["input"]["dims"]);  // the input's own grid
        EXPECT_EQ(j["work_grid"], jw["work_grid"]);
        EXPECT_EQ(j["ecv_ml"], jw["ecv_ml"]);
        EXPECT_TRUE(bytes(out / (std::string(name) + ".ply")) == bytes(out / "whole.ply")) << "mesh bytes differ";
    }
}

TEST(CliExtract, CoarseToFineMeshesTheInputsGridFromATiffStackOrNrrdAlikeAndIsChosenWhenTheGridDoesNotFit) {
    // The coarse-to-fine path (--refine F; refine.h) on the macaque phantom at 0.5 mm: the method on
    // the 1 mm grid, the mesh on the 0.5 mm one. Its ECV is within 1 % of the truth (the coarse grid
    // is 1 mm here; a microCT's is 0.22 mm: docs/benchmarks.md), it is a closed genus-0 manifold whose
    // vertices lie on the input's grid edges, and a TIFF stack of the same voxels gives the same mesh.
    const fs::path d = phantom_dir(), out = temp_dir("refine");
    const auto truth = read_json(d / "mq.json")["true_ecv_ml"].get<double>();
    auto extract = [&](const std::string& in, const std::string& name, const std::string& extra) {
        const CliRun r = run("extract " + in + " -o " + (out / (name + ".ply")).string() + " --report " +
                             (out / (name + ".json")).string() + " " + extra);
        EXPECT_EQ(r.status, 0) << r.output;
        return r;
    };
    const CliRun nrrd = extract((d / "mq.nrrd").string(), "nrrd", "--refine 2 --refine-slab 16");
    EXPECT_NE(nrrd.output.find("path: coarse-to-fine"), std::string::npos) << nrrd.output;
    const auto j = read_json(out / "nrrd.json");
    EXPECT_EQ(j["path_plan"]["taken"], "coarse-to-fine");
    EXPECT_EQ(j["parameters"]["path"], "coarse-to-fine");
    EXPECT_EQ(j["path"], "coarse-to-fine");
    EXPECT_EQ(j["refine"], 2);
    EXPECT_EQ(j["refinement"]["factor"], 2);
    EXPECT_GT(j["refinement"]["slabs"].get<int>(), 5);
    EXPECT_GT(j["refinement"]["changed_voxels"].get<int>(), 0);
    EXPECT_EQ(j["parameters"]["work_grid"]["dims"], read_json(d / "mq.json")["dims"]);  // the mesh's grid
    EXPECT_EQ(j["refinement"]["coarse_grid"]["dims"][0], (j["input"]["dims"][0].get<int>() + 1) / 2);
    EXPECT_EQ(j["mask_grid"], j["refinement"]["coarse_grid"]);
    EXPECT_NEAR(j["ecv_ml"].get<double>() / truth, 1.0, 0.01);
    EXPECT_TRUE(j["closed_manifold"].get<bool>());
    EXPECT_EQ(j["genus"], 0);
    EXPECT_EQ(j["self_intersections"], 0);
    EXPECT_GT(j["timings_s"]["refine"].get<double>(), 0.0);
    // Every vertex lies on an edge of the 0.5 mm grid's Freudenthal triangulation (origin 0, unit
    // direction: index = mm / 0.5): base + t x (a 0/1 direction), so its non-integer index
    // coordinates share one fractional part. The coarse grid's vertices (origin 0.25 mm) would not.
    const auto m = meshpost::read_mesh((out / "nrrd.ply").string());
    size_t on_edges = 0;
    for (const auto& v : m.vertices) {
        std::vector<double> fractions;
        for (int a = 0; a < 3; ++a) {
            const double i = v[size_t(a)] / 0.5, f = i - std::floor(i);
            if (f > 1e-4 && f < 1 - 1e-4) fractions.push_back(f);
        }
        bool same = !fractions.empty();
        for (double f : fractions) same = same && std::fabs(f - fractions[0]) < 1e-4;
        on_edges += same;
    }
    EXPECT_EQ(on_edges, m.vertices.size());

    // A TIFF stack of the same voxels: the same mesh bytes.
    fs::create_directories(out / "stack");
    ASSERT_EQ(run("phantom " + (out / "stack/s%04d.tif").string() + " --preset macaque --seed 3 -q").status, 0);
    extract((out / "stack").string(), "tiff", "--refine 2 --refine-slab 16");
    const auto read_bytes = [](const fs::path& p) {
        std::ifstream in(p, std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(in), {});
    };
    EXPECT_EQ(read_json(out / "tiff.json")["ecv_ml"], j["ecv_ml"]);
    EXPECT_TRUE(read_bytes(out / "tiff.ply") == read_bytes(out / "nrrd.ply")) << "mesh bytes differ";
    // 1 and 2 threads: the same bytes; one slab or many: the same bytes.
    extract((d / "mq.nrrd").string(), "one_thread", "--refine 2 --refine-slab 16 --threads 1");
    EXPECT_TRUE(read_bytes(out / "one_thread.ply") == read_bytes(out / "nrrd.ply")) << "mesh bytes differ";
    extract((d / "mq.nrrd").string(), "one_slab", "--refine 2 --refine-slab 4096");
    EXPECT_TRUE(read_bytes(out / "one_slab.ply") == read_bytes(out / "nrrd.ply")) << "mesh bytes differ";

    // With --crop: the crop box's grid, in the scan's world coordinates (the same surface).
    extract((d / "mq.nrrd").string(), "crop", "--refine 2 --crop 7 9 11 150 187 145");
    const auto c = read_json(out / "crop.json");
    EXPECT_EQ(c["work_grid"]["dims"], nlohmann::json({143, 178, 134}));
    EXPECT_NEAR(c["ecv_ml"].get<double>() / j["ecv_ml"].get<double>(), 1.0, 0.005);
    const meshpost::Point c0 = meshpost::volume_centroid(m), c1 = meshpost::volume_centroid(
        meshpost::read_mesh((out / "crop.ply").string()));
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(c1[size_t(a)], c0[size_t(a)], 0.1) << "axis " << a;

    // Automatic: taken when the whole grid does not fit (below its estimate, above the path's).
    const auto whole = j["path_plan"]["whole_grid_estimate_mb"].get<double>();
    const CliRun aut = extract((d / "mq.nrrd").string(), "auto",
                               "--max-memory " + std::to_string(int(whole) - 1) + " --refine-slab 16");
    const auto a = read_json(out / "auto.json");
    EXPECT_EQ(a["path_plan"]["taken"], "coarse-to-fine") << aut.output;
    EXPECT_NE(a["path_plan"]["reason"].get<std::string>().find("more than"), std::string::npos);
    EXPECT_TRUE(read_bytes(out / "auto.ply") == read_bytes(out / "nrrd.ply")) << "mesh bytes differ";
    // When nothing fits, the message says what each path needs, and nothing is written.
    const CliRun none = run("extract " + (d / "mq.nrrd").string() + " --max-memory 100 -o " + (out / "none.ply").string());
    EXPECT_EQ(none.status, 6) << none.output;
    EXPECT_NE(none.output.find("coarse-to-fine path (--refine 2) would need about"), std::string::npos) << none.output;
    EXPECT_FALSE(fs::exists(out / "none.ply"));

    // Refused: with --downsample, --surface half-max, or an input read whole (MetaImage).
    const CliRun ds = run("extract " + (d / "mq.nrrd").string() + " --refine 2 --downsample 2 -o " + (out / "x.ply").string());
    EXPECT_EQ(ds.status, 4) << ds.output;
    const CliRun hm = run("extract " + (d / "mq.nrrd").string() + " --refine 2 --surface half-max -o " + (out / "x.ply").string());
    EXPECT_EQ(hm.status, 4) << hm.output;
    EXPECT_NE(hm.output.find("coarse-to-fine"), std::string::npos) << hm.output;
    ASSERT_EQ(run("phantom " + (out / "mq.mha").string() + " --preset macaque --seed 3 -q").status, 0);
    const CliRun mha = run("extract " + (out / "mq.mha").string() + " --refine 2 -o " + (out / "x.ply").string());
    EXPECT_EQ(mha.status, 4) << mha.output;
    EXPECT_NE(mha.output.find("read in slabs"), std::string::npos) << mha.output;
    EXPECT_FALSE(fs::exists(out / "x.ply"));
}
