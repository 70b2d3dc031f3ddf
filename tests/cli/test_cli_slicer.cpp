// `endocast --xml` / `endocast extract --xml`: the 3D Slicer Execution Model description, and the
// Slicer wrapper script scripts/slicer/endocast-extract run the way Slicer runs it.
#include <gtest/gtest.h>

#include <cctype>
#include <map>
#include <memory>
#include <stdexcept>
#include <vector>

#include "cli_helpers.h"

using namespace cli_test;

namespace {

/// A parsed XML element (the subset Slicer descriptions use: elements, attributes, text, the
/// declaration, comments, the five predefined entities).
struct XmlNode {
    std::string name;
    std::map<std::string, std::string> attrs;
    std::string text;
    std::vector<std::unique_ptr<XmlNode>> children;

    const XmlNode* child(const std::string& n) const {
        for (const auto& c : children)
            if (c->name == n) return c.get();
        return nullptr;
    }
    std::vector<const XmlNode*> all(const std::string& n) const {
        std::vector<const XmlNode*> out;
        for (const auto& c : children)
            if (c->name == n) out.push_back(c.get());
        return out;
    }
    std::string child_text(const std::string& n) const {
        const XmlNode* c = child(n);
        return c ? c->text : "";
    }
};

/// A strict well-formedness parser: throws std::runtime_error naming the offset of the problem.
class XmlParser {
public:
    explicit XmlParser(std::string s) : s_(std::move(s)) {}

    std::unique_ptr<XmlNode> parse() {
        skip_misc();
        if (s_.compare(i_, 5, "<?xml") == 0) {
            const auto e = s_.find("?>", i_);
            if (e == std::string::npos) fail("unterminated XML declaration");
            i_ = e + 2;
        }
        skip_misc();
        auto root = element();
        skip_misc();
        if (i_ != s_.size()) fail("content after the root element");
        return root;
    }

private:
    [[noreturn]] void fail(const std::string& what) const {
        throw std::runtime_error("XML offset " + std::to_string(i_) + ": " + what);
    }
    void skip_space() {
        while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
    }
    void skip_misc() {
        for (;;) {
            skip_space();
            if (s_.compare(i_, 4, "<!--") != 0) return;
            const auto e = s_.find("-->", i_);
            if (e == std::string::npos) fail("unterminated comment");
            i_ = e + 3;
        }
    }
    std::string name() {
        const size_t a = i_;
        while (i_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[i_])) || s_[i_] == '-' ||
                                  s_[i_] == '_' || s_[i_] == ':' || s_[i_] == '.'))
            ++i_;
        if (a == i_ || std::isdigit(static_cast<unsigned char>(s_[a])) || s_[a] == '-') fail("expected a name");
        return s_.substr(a, i_ - a);
    }
    std::string decode(const std::string& raw) const {
        static const std::map<std::string, char> ent = {
            {"amp", '&'}, {"lt", '<'}, {"gt", '>'}, {"quot", '"'}, {"apos", '\''}};
        std::string out;
        for (size_t k = 0; k < raw.size(); ++k) {
            if (raw[k] == '<') throw std::runtime_error("'<' in text or attribute");
            if (raw[k] != '&') {
                out += raw[k];
                continue;
            }
            const auto semi = raw.find(';', k);
            if (semi == std::string::npos || !ent.count(raw.substr(k + 1, semi - k - 1)))
                throw std::runtime_error("bad entity in '" + raw + "'");
            out += ent.at(raw.substr(k + 1, semi - k - 1));
            k = semi;
        }
        return out;
    }
    std::unique_ptr<XmlNode> element() {
        if (i_ >= s_.size() || s_[i_] != '<') fail("expected '<'");
        ++i_;
        auto node = std::make_unique<XmlNode>();
        node->name = name();
        for (;;) {
            skip_space();
            if (i_ >= s_.size()) fail("unterminated start tag <" + node->name + ">");
            if (s_.compare(i_, 2, "/>") == 0) {
                i_ += 2;
                return node;
            }
            if (s_[i_] == '>') {
                ++i_;
                break;
            }
            const std::string a = name();
            skip_space();
            if (i_ >= s_.size() || s_[i_] != '=') fail("expected '=' after attribute " + a);
            ++i_;
            skip_space();
            const char q = i_ < s_.size() ? s_[i_] : 0;
            if (q != '"' && q != '\'') fail("expected a quoted value for " + a);
            const auto e = s_.find(q, i_ + 1);
            if (e == std::string::npos) fail("unterminated attribute " + a);
            if (node->attrs.count(a)) fail("attribute " + a + " given twice");
            node->attrs[a] = decode(s_.substr(i_ + 1, e - i_ - 1));
            i_ = e + 1;
        }
        for (;;) {
            const auto lt = s_.find('<', i_);
            if (lt == std::string::npos) fail("unterminated element <" + node->name + ">");
            node->text += decode(s_.substr(i_, lt - i_));
            i_ = lt;
            if (s_.compare(i_, 4, "<!--") == 0) {
                skip_misc();
            } else if (s_.compare(i_, 2, "</") == 0) {
                i_ += 2;
                const std::string n = name();
                if (n != node->name) fail("</" + n + "> closes <" + node->name + ">");
                skip_space();
                if (i_ >= s_.size() || s_[i_] != '>') fail("expected '>'");
                ++i_;
                const auto b = node->text.find_first_not_of(" \t\r\n");
                node->text = b == std::string::npos
                                 ? ""
                                 : node->text.substr(b, node->text.find_last_not_of(" \t\r\n") - b + 1);
                return node;
            } else {
                node->children.push_back(element());
            }
        }
    }

    std::string s_;
    size_t i_ = 0;
};

std::string wrapper() {
    return "ENDOCAST_BIN=" + std::string(ENDOCAST_CLI) + " bash " + std::string(ENDOCAST_SOURCE_DIR) +
           "/scripts/slicer/endocast-extract";
}

bool valid_identifier(const std::string& s) {
    if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
    for (char c : s)
        if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
    return true;
}

const XmlNode* find_param(const XmlNode& exe, const std::string& tag, const std::string& name) {
    for (const XmlNode* g : exe.all("parameters"))
        for (const XmlNode* p : g->all(tag))
            if (p->child_text("name") == name) return p;
    return nullptr;
}

}  // namespace

TEST(CliSlicer, ExtractXmlIsAWellFormedDescription) {
    const CliRun r = run_shell(std::string(ENDOCAST_CLI) + " extract --xml");  // no INPUT needed
    ASSERT_EQ(r.status, 0) << r.output;
    std::unique_ptr<XmlNode> exe;
    ASSERT_NO_THROW(exe = XmlParser(r.output).parse()) << r.output;
    ASSERT_EQ(exe->name, "executable");
    for (const char* k : {"category", "title", "description", "version", "documentation-url", "license",
                          "contributor", "acknowledgements"})
        EXPECT_FALSE(exe->child_text(k).empty()) << k;
    EXPECT_EQ(exe->child_text("title"), "Endocast extraction");
    EXPECT_EQ(exe->child_text("category"), "Segmentation");
    ASSERT_GE(exe->all("parameters").size(), 2u);

    const XmlNode* input = find_param(*exe, "image", "inputVolume");
    ASSERT_NE(input, nullptr);
    EXPECT_EQ(input->child_text("channel"), "input");
    EXPECT_EQ(input->child_text("index"), "0");
    const XmlNode* mesh = find_param(*exe, "geometry", "output");
    ASSERT_NE(mesh, nullptr);
    EXPECT_EQ(mesh->attrs.at("type"), "model");
    EXPECT_EQ(mesh->attrs.at("fileExtensions").rfind(".stl", 0), 0u);
    EXPECT_EQ(mesh->child_text("channel"), "output");
    EXPECT_EQ(mesh->child_text("longflag"), "--output");
    const XmlNode* mask = find_param(*exe, "image", "mask");
    ASSERT_NE(mask, nullptr);
    EXPECT_EQ(mask->attrs.at("type"), "label");
    EXPECT_EQ(mask->child_text("channel"), "output");
    const XmlNode* report = find_param(*exe, "file", "report");
    ASSERT_NE(report, nullptr);
    EXPECT_EQ(report->attrs.at("fileExtensions"), ".json");
    const XmlNode* mode = find_param(*exe, "string-enumeration", "seedMode");
    ASSERT_NE(mode, nullptr);
    std::vector<std::string> elements;
    for (const XmlNode* e : mode->all("element")) elements.push_back(e->text);
    EXPECT_EQ(elements, (std::vector<std::string>{"auto", "auto-largest", "distance", "point"}));
    EXPECT_EQ(mode->child_text("default"), "auto");
    const XmlNode* scale = find_param(*exe, "double", "seedScale");
    ASSERT_NE(scale, nullptr);
    ASSERT_NE(scale->child("constraints"), nullptr);
    EXPECT_EQ(std::stod(scale->child("constraints")->child_text("minimum")), 0.0);
    EXPECT_EQ(std::stod(scale->child("constraints")->child_text("maximum")), 1.0);
    EXPECT_EQ(std::stod(scale->child_text("default")), 0.9);
    const XmlNode* iso = find_param(*exe, "string", "iso");
    ASSERT_NE(iso, nullptr);
    EXPECT_NE(iso->child_text("description").find("scan's units"), std::string::npos);
    const XmlNode* point = find_param(*exe, "point", "seedPoint");
    ASSERT_NE(point, nullptr);
    EXPECT_EQ(point->attrs.at("coordinateSystem"), "lps");
    const XmlNode* keep = find_param(*exe, "boolean", "noCloseOpenings");
    ASSERT_NE(keep, nullptr);
    EXPECT_EQ(keep->child_text("default"), "false");
    EXPECT_EQ(std::stod(find_param(*exe, "double", "voidRadius")->child_text("default")), 6.0);
}

TEST(CliSlicer, EveryLongflagIsARealExtractOption) {
    const CliRun xml = run_shell(std::string(ENDOCAST_CLI) + " extract --xml");
    ASSERT_EQ(xml.status, 0);
    const auto exe = XmlParser(xml.output).parse();
    const CliRun help = run("extract --help");
    ASSERT_EQ(help.status, 0);
    size_t params = 0;
    for (const XmlNode* g : exe->all("parameters")) {
        EXPECT_FALSE(g->child_text("label").empty());
        for (const auto& p : g->children) {
            if (p->name == "label" || p->name == "description") continue;
            ++params;
            const std::string n = p->child_text("name");
            EXPECT_TRUE(valid_identifier(n)) << n;
            EXPECT_FALSE(p->child_text("label").empty()) << n;
            EXPECT_FALSE(p->child_text("description").empty()) << n;
            const std::string flag = p->child_text("longflag");
            if (flag.empty()) {
                EXPECT_EQ(p->child_text("index"), "0") << n << ": neither a long flag nor an index";
                continue;
            }
            ASSERT_EQ(flag.rfind("--", 0), 0u) << flag;
            // Slicer allows letters, digits and '_' only; the wrapper maps '_' back to '-'.
            EXPECT_TRUE(valid_identifier(flag.substr(2))) << flag;
            std::string option = flag;
            for (char& c : option)
                if (c == '_') c = '-';
            const bool listed = help.output.find("  " + option + " ") != std::string::npos ||
                                help.output.find("," + option + " ") != std::string::npos;
            EXPECT_TRUE(listed) << flag << " -> " << option << " is not an option of `endocast extract`";
        }
    }
    EXPECT_GE(params, 10u);
}

TEST(CliSlicer, TopLevelXmlAndWrapperPrintTheSameDescription) {
    const CliRun sub = run_shell(std::string(ENDOCAST_CLI) + " extract --xml");
    const CliRun top = run_shell(std::string(ENDOCAST_CLI) + " --xml");
    const CliRun wrap = run_shell(wrapper() + " --xml");
    ASSERT_EQ(sub.status, 0);
    EXPECT_EQ(top.status, 0);
    EXPECT_EQ(wrap.status, 0);
    EXPECT_EQ(top.output, sub.output);
    EXPECT_EQ(wrap.output, sub.output);
    // --xml describes extract only; on another subcommand it is a usage error.
    const CliRun other = run("phantom --xml");
    EXPECT_EQ(other.status, 2) << other.output;
    EXPECT_NE(other.output.find("extract"), std::string::npos) << other.output;
    EXPECT_NE(run("--help").output.find("--xml"), std::string::npos);
    EXPECT_NE(run("extract --help").output.find("--xml"), std::string::npos);
}

TEST(CliSlicer, WrapperRunsExtractWithSlicerStyleArguments) {
    const fs::path d = temp_dir("slicer");
    const std::string ph = (d / "mq.nrrd").string();
    const CliRun p = run("phantom " + ph + " --preset macaque --seed 3 -q");
    ASSERT_EQ(p.status, 0) << p.output;
    const auto truth = read_json(d / "mq.json");
    const auto& c = truth["cavity_centre_mm"];
    std::ostringstream point;
    point << c[0].get<double>() << "," << c[1].get<double>() << "," << c[2].get<double>();
    // As Slicer builds it: flags first (underscored long flags, a point as X,Y,Z), then the input.
    const std::string iso = std::to_string(truth["suggested_iso"].get<double>());
    const std::string args = " --iso " + iso + " --void_radius 6 --seed_mode auto --seed_scale 0.9"
                             " --distance_threshold 0 --opening_radius_mm 0 --seed_point " + point.str() +
                             " --output " + (d / "e.stl").string() + " --mask " + (d / "m.nrrd").string() +
                             " --report " + (d / "r.json").string() + " " + ph;
    const CliRun r = run_shell(wrapper() + args + " 2>&1");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto rep = read_json(d / "r.json");
    EXPECT_EQ(rep["parameters"]["seed_mode"], "point");
    EXPECT_DOUBLE_EQ(rep["parameters"]["isovalue"].get<double>(), std::stod(iso));
    EXPECT_TRUE(rep["closed_manifold"].get<bool>());
    EXPECT_TRUE(fs::exists(d / "e.stl"));
    EXPECT_TRUE(fs::exists(d / "m.nrrd"));
}

TEST(CliSlicer, SeedPointTakesSpacesOrCommas) {
    // A point outside the volume is rejected the same way in both spellings (before any work).
    const fs::path d = temp_dir("slicerpt");
    const std::string ph = (d / "mq.nrrd").string();
    ASSERT_EQ(run("phantom " + ph + " --preset macaque --seed 3 -q").status, 0);
    const CliRun a = run("extract " + ph + " --seed-point 1e6 0 0 -q");
    const CliRun b = run("extract " + ph + " --seed-point 1e6,0,0 -q");
    EXPECT_EQ(a.status, 4) << a.output;
    EXPECT_EQ(b.status, 4) << b.output;
    const CliRun bad = run("extract " + ph + " --seed-point 1,2 -q");
    EXPECT_EQ(bad.status, 2) << bad.output;
}
