// `endocast batch`: a collection of phantoms plus a broken input, the summary table, skipping
// finished specimens on a re-run, the manifest, and --jobs.
#include <gtest/gtest.h>

#include <map>
#include <sstream>

#include "cli_helpers.h"

using namespace cli_test;

namespace {

const char* const kHeader =
    "specimen,input,isovalue,ecv_ml,surface_area_mm2,faces,closed_manifold,seconds,status,error,bone_contact";
// Small, quick phantoms: the human preset at 1.5 mm voxels (ECV within 1%; at 2 mm it is -1.5%).
const char* const kPhantomArgs = " --preset human --spacing 1.5 1.5 1.5";

/// Two human phantoms (seeds 1 and 2) and a garbage .nrrd, shared by the tests of this file.
const fs::path& inputs_dir() {
    static const fs::path d = [] {
        fs::path dir = temp_dir("batch_inputs");
        for (const char* seed : {"1", "2"}) {
            const std::string out = (dir / ("skull" + std::string(seed) + ".nrrd")).string();
            const CliRun r = run("phantom " + out + kPhantomArgs + " --seed " + seed);
            if (r.status != 0) throw std::runtime_error("phantom failed: " + r.output);
        }
        std::ofstream(dir / "broken.nrrd") << "NRRD0004\ntype: nonsense\n\ngarbage";
        return dir;
    }();
    return d;
}

/// Splits one CSV line (quoted fields may hold commas and doubled quotes).
std::vector<std::string> split_csv(const std::string& line) {
    std::vector<std::string> f(1);
    bool q = false;
    for (size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (q && c == '"' && i + 1 < line.size() && line[i + 1] == '"') f.back() += '"', ++i;
        else if (c == '"') q = !q;
        else if (c == ',' && !q) f.emplace_back();
        else f.back() += c;
    }
    return f;
}

struct Summary {
    std::string header;
    std::map<std::string, std::map<std::string, std::string>> rows;  ///< specimen -> column -> value
    size_t count = 0;
};

Summary read_summary(const fs::path& p) {
    std::ifstream in(p);
    Summary s;
    std::getline(in, s.header);
    const auto cols = split_csv(s.header);
    for (std::string line; std::getline(in, line);) {
        if (line.empty()) continue;
        const auto f = split_csv(line);
        EXPECT_EQ(f.size(), cols.size()) << line;
        for (size_t i = 0; i < cols.size() && i < f.size(); ++i) s.rows[f[0]][cols[i]] = f[i];
        ++s.count;
    }
    return s;
}

double true_ecv(const std::string& name) {
    return read_json(inputs_dir() / (name + ".json"))["true_ecv_ml"].get<double>();
}

std::string three_inputs() {
    const fs::path d = inputs_dir();
    return (d / "skull1.nrrd").string() + " " + (d / "broken.nrrd").string() + " " +
           (d / "skull2.nrrd").string();
}

}  // namespace

TEST(CliBatch, SummaryRecordsTwoGoodSpecimensAndOneFailureThenSkipsOnRerun) {
    const fs::path out = temp_dir("batch_out");
    const CliRun r = run("batch " + three_inputs() + " -o " + out.string());
    EXPECT_EQ(r.status, 1) << r.output;  // a specimen failed
    EXPECT_NE(r.output.find("[3/3]"), std::string::npos) << r.output;
    const Summary s = read_summary(out / "summary.csv");
    EXPECT_EQ(s.header, kHeader);
    ASSERT_EQ(s.count, 3u);
    for (const char* name : {"skull1", "skull2"}) {
        const auto& row = s.rows.at(name);
        EXPECT_EQ(row.at("status"), "ok") << name;
        EXPECT_TRUE(row.at("error").empty()) << name;
        EXPECT_EQ(row.at("closed_manifold"), "true") << name;
        EXPECT_NEAR(std::stod(row.at("ecv_ml")), true_ecv(name), 0.01 * true_ecv(name)) << name;
        EXPECT_GT(std::stol(row.at("faces")), 1000) << name;
        // bone_contact, the last column, from the specimen's report (4 decimals).
        const double contact = read_json(out / name / "report.json")["bone_contact"].get<double>();
        EXPECT_NEAR(std::stod(row.at("bone_contact")), contact, 5e-5) << name;
        EXPECT_GT(contact, 0.5) << name;
        for (const char* f : {"endocast.stl", "report.json", "log.txt"})
            EXPECT_TRUE(fs::exists(out / name / f)) << name << "/" << f;
    }
    const auto& bad = s.rows.at("broken");
    EXPECT_EQ(bad.at("status"), "failed");
    EXPECT_FALSE(bad.at("error").empty());
    EXPECT_NE(bad.at("error").find("exit 3"), std::string::npos) << bad.at("error");
    EXPECT_TRUE(bad.at("bone_contact").empty());
    EXPECT_FALSE(fs::exists(out / "broken" / "report.json"));
    EXPECT_TRUE(fs::exists(out / "broken" / "log.txt"));

    // Re-run: the finished specimens are skipped and their files left alone; the broken one is retried.
    const auto mesh_time = fs::last_write_time(out / "skull1" / "endocast.stl");
    const auto report_time = fs::last_write_time(out / "skull2" / "report.json");
    const CliRun again = run("batch " + three_inputs() + " -o " + out.string());
    EXPECT_EQ(again.status, 1) << again.output;
    EXPECT_NE(again.output.find("skull1: skipped (done)"), std::string::npos) << again.output;
    EXPECT_NE(again.output.find("skull2: skipped (done)"), std::string::npos) << again.output;
    EXPECT_EQ(fs::last_write_time(out / "skull1" / "endocast.stl"), mesh_time);
    EXPECT_EQ(fs::last_write_time(out / "skull2" / "report.json"), report_time);
    const Summary s2 = read_summary(out / "summary.csv");
    ASSERT_EQ(s2.count, 3u);
    for (const char* name : {"skull1", "skull2"})
        for (const char* col : {"ecv_ml", "surface_area_mm2", "faces", "isovalue", "status", "bone_contact"})
            EXPECT_EQ(s2.rows.at(name).at(col), s.rows.at(name).at(col)) << name << " " << col;
    EXPECT_EQ(s2.rows.at("broken").at("status"), "failed");

    // --force redoes a finished specimen.
    const CliRun forced = run("batch " + (inputs_dir() / "skull1.nrrd").string() + " -o " + out.string() + " --force");
    EXPECT_EQ(forced.status, 0) << forced.output;
    EXPECT_EQ(forced.output.find("skipped"), std::string::npos) << forced.output;
    EXPECT_NE(fs::last_write_time(out / "skull1" / "endocast.stl"), mesh_time);
}

TEST(CliBatch, ManifestWithQuotedFieldsPerSpecimenIsoAndNames) {
    const fs::path d = inputs_dir(), out = temp_dir("batch_manifest");
    // A folder name with a comma, so the input path must be quoted.
    const fs::path odd = out / "in, quoted";
    fs::create_directories(odd);
    fs::copy_file(d / "skull1.nrrd", odd / "skull1.nrrd");
    const double iso = read_json(d / "skull1.json")["suggested_iso"].get<double>();
    // iso and border-seed-scale: extract options per row; species: not an option, ignored.
    std::ofstream(out / "m.csv") << "specimen,input,iso,species,border-seed-scale\n"
                                 << "first,\"" << (odd / "skull1.nrrd").string() << "\"," << iso
                                 << ",\"Homo sapiens, phantom\",0.8\n"
                                 << ",skull_missing.nrrd,,,\n";
    const CliRun r = run("batch --manifest " + (out / "m.csv").string() + " -o " + (out / "res").string());
    EXPECT_EQ(r.status, 1) << r.output;
    const Summary s = read_summary(out / "res" / "summary.csv");
    ASSERT_EQ(s.count, 2u);
    const auto& first = s.rows.at("first");
    EXPECT_EQ(first.at("status"), "ok") << first.at("error");
    EXPECT_EQ(first.at("input"), (odd / "skull1.nrrd").string());
    EXPECT_NEAR(std::stod(first.at("isovalue")), iso, 1e-6);
    EXPECT_NEAR(std::stod(first.at("ecv_ml")), true_ecv("skull1"), 0.01 * true_ecv("skull1"));
    EXPECT_DOUBLE_EQ(read_json(out / "res" / "first" / "report.json")["border_seed_scale"].get<double>(), 0.8);
    EXPECT_NE(r.output.find("ignoring columns that are not extract options: species"), std::string::npos) << r.output;
    // The relative path is read relative to the manifest's folder, and the name defaults to its stem.
    const auto& missing = s.rows.at("skull_missing");
    EXPECT_EQ(missing.at("status"), "failed");
    EXPECT_EQ(missing.at("input"), (out / "skull_missing.nrrd").string());
    EXPECT_NE(missing.at("error").find("skull_missing.nrrd"), std::string::npos) << missing.at("error");
}

TEST(CliBatch, TwoJobsGiveTheSameSummaryAsOne) {
    const fs::path out = temp_dir("batch_jobs");
    const std::string args = "batch " + three_inputs() + " --seed-mode auto --void-radius 6";
    const CliRun one = run(args + " -o " + (out / "j1").string() + " --jobs 1");
    const CliRun two = run(args + " -o " + (out / "j2").string() + " --jobs 2");
    EXPECT_EQ(one.status, 1) << one.output;
    EXPECT_EQ(two.status, 1) << two.output;
    const Summary a = read_summary(out / "j1" / "summary.csv"), b = read_summary(out / "j2" / "summary.csv");
    ASSERT_EQ(a.count, 3u);
    ASSERT_EQ(b.count, 3u);
    for (const auto& [name, row] : a.rows)
        for (const auto& [col, value] : row)
            if (col != "seconds" && col != "input") EXPECT_EQ(b.rows.at(name).at(col), value) << name << " " << col;
    // The forwarded options reached extract.
    EXPECT_EQ(read_json(out / "j2" / "skull1" / "report.json")["seed_mode"], "auto");
}

TEST(CliBatch, DuplicateNamesAreMadeUniqueAndBadUsageIsRejected) {
    const fs::path d = inputs_dir(), out = temp_dir("batch_names");
    fs::create_directories(out / "a");
    fs::copy_file(d / "broken.nrrd", out / "a" / "broken.nrrd");
    // Both inputs are named "broken": the second becomes broken_2. Both fail quickly.
    const CliRun r = run("batch " + (d / "broken.nrrd").string() + " " + (out / "a" / "broken.nrrd").string() +
                         " -o " + (out / "res").string());
    EXPECT_EQ(r.status, 1) << r.output;
    const Summary s = read_summary(out / "res" / "summary.csv");
    EXPECT_EQ(s.rows.count("broken"), 1u);
    EXPECT_EQ(s.rows.count("broken_2"), 1u);
    EXPECT_EQ(run("batch -o " + (out / "none").string()).status, 4);  // no specimens
    EXPECT_EQ(run("batch " + (d / "skull1.nrrd").string()).status, 2);  // no -o
    EXPECT_EQ(run("batch --manifest " + (out / "nope.csv").string() + " -o " + (out / "x").string()).status, 3);
    std::ofstream(out / "noinput.csv") << "specimen,path\na,b\n";
    const CliRun m = run("batch --manifest " + (out / "noinput.csv").string() + " -o " + (out / "x").string());
    EXPECT_EQ(m.status, 3);
    EXPECT_NE(m.output.find("'input'"), std::string::npos) << m.output;
}
