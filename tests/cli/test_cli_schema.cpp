// docs/report.schema.json against real `endocast extract` reports: every report validates, and
// every key a report has is documented in the schema.
//
// Debian packages no C++ JSON Schema validator, so this file holds a small one for the subset the
// schema uses: type, const, enum, required, properties, additionalProperties (boolean or schema),
// items, minItems, maxItems, minimum, maximum, and $ref to a JSON pointer inside the schema.
// Any other keyword that constrains values is reported as unsupported, so the schema cannot
// silently rely on something this validator ignores.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <set>
#include <stdexcept>

#include "../common/dicom_study.h"
#include "cli_helpers.h"

using namespace cli_test;
using nlohmann::json;

namespace {

class MiniValidator {
public:
    explicit MiniValidator(json schema) : root_(std::move(schema)) {}

    /// Problems found, one per line ("" when `doc` is valid).
    std::string validate(const json& doc) {
        errors_.clear();
        check(doc, root_, "");
        return errors_;
    }

    /// Keys of `doc`'s objects that the schema does not name in a `properties`.
    std::string undocumented(const json& doc) {
        errors_.clear();
        walk_keys(doc, root_, "");
        return errors_;
    }

private:
    const json& resolve(const json& s) const {
        if (!s.contains("$ref")) return s;
        const std::string ref = s["$ref"].get<std::string>();
        if (ref.rfind("#", 0) != 0) throw std::runtime_error("unsupported $ref " + ref);
        return resolve(root_.at(json::json_pointer(ref.substr(1))));
    }

    void fail(const std::string& where, const std::string& what) {
        errors_ += (where.empty() ? "(root)" : where) + ": " + what + "\n";
    }

    static bool has_type(const json& v, const std::string& t) {
        if (t == "object") return v.is_object();
        if (t == "array") return v.is_array();
        if (t == "string") return v.is_string();
        if (t == "boolean") return v.is_boolean();
        if (t == "null") return v.is_null();
        if (t == "number") return v.is_number();
        if (t == "integer") return v.is_number_integer();
        throw std::runtime_error("unknown type " + t);
    }

    void check(const json& v, const json& schema, const std::string& at) {
        const json& s = resolve(schema);
        static const std::set<std::string> known = {
            "$schema", "$defs", "$ref", "title", "description", "type", "const", "enum", "required",
            "properties", "additionalProperties", "items", "minItems", "maxItems", "minimum", "maximum"};
        for (auto it = s.begin(); it != s.end(); ++it)
            if (!known.count(it.key())) fail(at, "schema keyword '" + it.key() + "' is not supported by the test");
        if (s.contains("type")) {
            const json types = s["type"].is_array() ? s["type"] : json::array({s["type"]});
            bool ok = false;
            for (const auto& t : types) ok = ok || has_type(v, t.get<std::string>());
            if (!ok) fail(at, "is " + v.dump() + ", expected type " + s["type"].dump());
            if (!ok) return;
        }
        if (s.contains("const") && v != s["const"]) fail(at, "is " + v.dump() + ", expected " + s["const"].dump());
        if (s.contains("enum") && std::find(s["enum"].begin(), s["enum"].end(), v) == s["enum"].end())
            fail(at, "is " + v.dump() + ", expected one of " + s["enum"].dump());
        if (v.is_number()) {
            if (s.contains("minimum") && v.get<double>() < s["minimum"].get<double>())
                fail(at, "is " + v.dump() + ", below the minimum " + s["minimum"].dump());
            if (s.contains("maximum") && v.get<double>() > s["maximum"].get<double>())
                fail(at, "is " + v.dump() + ", above the maximum " + s["maximum"].dump());
        }
        if (v.is_array()) {
            if (s.contains("minItems") && v.size() < s["minItems"].get<size_t>())
                fail(at, "has " + std::to_string(v.size()) + " items, expected at least " + s["minItems"].dump());
            if (s.contains("maxItems") && v.size() > s["maxItems"].get<size_t>())
                fail(at, "has " + std::to_string(v.size()) + " items, expected at most " + s["maxItems"].dump());
            if (s.contains("items"))
                for (size_t i = 0; i < v.size(); ++i) check(v[i], s["items"], at + "/" + std::to_string(i));
        }
        if (v.is_object()) {
            if (s.contains("required"))
                for (const auto& k : s["required"])
                    if (!v.contains(k.get<std::string>())) fail(at, "lacks the required key " + k.dump());
            for (auto it = v.begin(); it != v.end(); ++it) {
                const std::string child = at + "/" + it.key();
                if (s.contains("properties") && s["properties"].contains(it.key()))
                    check(it.value(), s["properties"][it.key()], child);
                else if (s.contains("additionalProperties")) {
                    const json& extra = s["additionalProperties"];
                    if (extra.is_boolean()) {
                        if (!extra.get<bool>()) fail(child, "is not allowed (additionalProperties false)");
                    } else {
                        check(it.value(), extra, child);
                    }
                }
            }
        }
    }

    void walk_keys(const json& v, const json& schema, const std::string& at) {
        const json& s = resolve(schema);
        if (v.is_array() && s.contains("items"))
            for (size_t i = 0; i < v.size(); ++i) walk_keys(v[i], s["items"], at + "/" + std::to_string(i));
        if (!v.is_object()) return;
        for (auto it = v.begin(); it != v.end(); ++it) {
            if (s.contains("properties") && s["properties"].contains(it.key()))
                walk_keys(it.value(), s["properties"][it.key()], at + "/" + it.key());
            else
                fail(at + "/" + it.key(), "is not documented in the schema");
        }
    }

    json root_;
    std::string errors_;
};

json schema() {
    std::ifstream in(ENDOCAST_REPORT_SCHEMA);
    if (!in) throw std::runtime_error("cannot open " + std::string(ENDOCAST_REPORT_SCHEMA));
    return json::parse(in);
}

/// Reports of two extracts on one phantom: the default settings (every list filled) and the
/// optional keys (distance seeds, a cut plane, openings kept). Written once per process.
const std::vector<json>& reports() {
    static const std::vector<json> r = [] {
        const fs::path d = temp_dir("schema");
        const std::string ph = (d / "p.nrrd").string();
        CliRun p = run("phantom " + ph + " --preset human -q");
        if (p.status != 0) throw std::runtime_error("phantom failed: " + p.output);
        std::vector<json> out;
        const std::vector<std::string> variants = {
            "-o " + (d / "a.stl").string() + " --mask " + (d / "a.nrrd").string(),
            "--seed-mode distance --distance-threshold 20 --cut-plane 0 0 0.5 0 0 -1 --no-close-openings",
            "--surface half-max",
        };
        for (size_t i = 0; i < variants.size(); ++i) {
            const fs::path rep = d / ("r" + std::to_string(i) + ".json");
            const CliRun e = run("extract " + ph + " " + variants[i] + " --report " + rep.string() + " -q");
            if (e.status != 0) throw std::runtime_error("extract " + variants[i] + " failed: " + e.output);
            out.push_back(read_json(rep));
        }
        return out;
    }();
    return r;
}

}  // namespace

TEST(CliSchema, SchemaIsWellFormedAndRequiresTheCoreKeys) {
    const json s = schema();
    EXPECT_EQ(s["$schema"], "https://json-schema.org/draft/2020-12/schema");
    EXPECT_EQ(s["type"], "object");
    const auto& req = s["required"];
    for (const char* k : {"tool", "version", "input", "parameters", "isovalue", "ecv_ml", "surface_area_mm2",
                          "vertices", "faces", "closed_manifold", "self_intersections", "genus",
                          "timings_s", "peak_memory_mb", "warnings", "outputs"}) {
        EXPECT_NE(std::find(req.begin(), req.end(), k), req.end()) << k;
        EXPECT_TRUE(s["properties"].contains(k)) << k;
    }
    // Every documented key says what it is (units in the text).
    std::function<void(const json&, const std::string&)> described = [&](const json& node, const std::string& at) {
        if (!node.is_object()) return;
        if (node.contains("properties"))
            for (auto it = node["properties"].begin(); it != node["properties"].end(); ++it) {
                EXPECT_TRUE(it.value().contains("description")) << at << "/" << it.key();
                described(it.value(), at + "/" + it.key());
            }
        if (node.contains("items")) described(node["items"], at + "/items");
        if (node.contains("$defs"))
            for (auto it = node["$defs"].begin(); it != node["$defs"].end(); ++it)
                described(it.value(), "$defs/" + it.key());
    };
    described(s, "");
}

// One test, so the two extracts run once (ctest runs each test in its own process).
TEST(CliSchema, ExtractReportsValidateAndEveryKeyIsDocumented) {
    MiniValidator v(schema());
    for (const json& r : reports()) {
        EXPECT_EQ(v.validate(r), "") << r.dump(2).substr(0, 3000);
        EXPECT_EQ(v.undocumented(r), "");
    }
    // The optional keys were exercised.
    EXPECT_TRUE(reports()[1]["parameters"].contains("distance_threshold_mm"));
    EXPECT_FALSE(reports()[0]["cavity_candidates"].empty());
    EXPECT_FALSE(reports()[1]["cut_planes"].empty());
    EXPECT_EQ(reports()[0]["parameters"]["surface"], "iso");
    EXPECT_FALSE(reports()[0].contains("half_max"));
    EXPECT_EQ(reports()[2]["surface"], "half-max");
    EXPECT_TRUE(reports()[2].contains("half_max"));
    // The version is the build's (CMake's project version), not a literal in the code.
    EXPECT_EQ(reports()[0]["version"], ENDOCAST_VERSION);

    // The validator does reject what the schema forbids.
    const json& r = reports()[0];
    json bad = r;
    bad["ecv_ml"] = "large";
    EXPECT_NE(v.validate(bad).find("/ecv_ml"), std::string::npos);
    bad = r;
    bad.erase("genus");
    EXPECT_NE(v.validate(bad).find("required key \"genus\""), std::string::npos);
    bad = r;
    bad["parameters"]["seed_mode"] = "guess";
    EXPECT_NE(v.validate(bad).find("/parameters/seed_mode"), std::string::npos);
    bad = r;
    bad["input"]["spacing"] = {1, 2};
    EXPECT_NE(v.validate(bad).find("/input/spacing"), std::string::npos);
    bad = r;
    bad["enclosure"] = 1.5;
    EXPECT_NE(v.validate(bad).find("maximum"), std::string::npos);
    bad = r;
    bad["timings_s"]["new_stage"] = 1.0;
    EXPECT_NE(v.undocumented(bad).find("/timings_s/new_stage"), std::string::npos);
}

// A study folder's report: input.series_found (every series with its verdict) is documented.
TEST(CliSchema, DicomStudySeriesFoundValidates) {
    const fs::path d = temp_dir("schema_study");
    endocast::testing::write_phantom_dicom_study((d / "STUDY").string());
    const CliRun e = run("extract " + (d / "STUDY").string() + " --report " + (d / "r.json").string() + " -q");
    ASSERT_EQ(e.status, 0) << e.output;
    const json r = read_json(d / "r.json");
    ASSERT_EQ(r["input"]["series_found"].size(), 5u);
    MiniValidator v(schema());
    EXPECT_EQ(v.validate(r), "") << r["input"].dump(2);
    EXPECT_EQ(v.undocumented(r), "");
    // The schema's checks bite: a series without its verdict is caught.
    json bad = r;
    bad["input"]["series_found"][0].erase("is_volume");
    EXPECT_NE(v.validate(bad).find("is_volume"), std::string::npos);
}

// A TIFF stack's report: format "tiff" and input.spacing_source are documented.
TEST(CliSchema, TiffStackReportValidates) {
    const fs::path d = temp_dir("schema_tiff");
    fs::create_directories(d / "stack");
    ASSERT_EQ(run("phantom " + (d / "stack/s%03d.tif").string() + " --preset macaque -q").status, 0);
    const CliRun e = run("extract " + (d / "stack").string() + " --report " + (d / "r.json").string() + " -q");
    ASSERT_EQ(e.status, 0) << e.output;
    const json r = read_json(d / "r.json");
    EXPECT_EQ(r["input"]["format"], "tiff");
    ASSERT_TRUE(r["input"].contains("spacing_source"));
    MiniValidator v(schema());
    EXPECT_EQ(v.validate(r), "") << r["input"].dump(2);
    EXPECT_EQ(v.undocumented(r), "");
}
