// `endocast --xml` / `endocast extract --xml`: the 3D Slicer Execution Model description of
// `extract`, so the command runs as a Slicer "CLI module" (docs/slicer.md).
//
// The XML is generated from the extract subcommand's CLI11 options: each parameter's flag,
// description and default come from the option itself, and the choices of an enumeration and the
// range of a bounded number from its validators. A small table adds what CLI11 does not know (the
// Slicer widget type, a label, the group). Options that are not in the table (raw input, DICOM
// series, cut planes) are not offered in Slicer; a table entry that names no option throws, so the
// table cannot drift from the options unnoticed.
//
// Slicer long flags may hold only letters, digits and underscores, so `--void-radius` is described
// as `--void_radius`; scripts/slicer/endocast-extract turns the underscores back into hyphens.
#include <cctype>
#include <cstdint>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.h"
#include "meshpost/text.h"

namespace endocast::cli {
namespace {

using meshpost::text::split;

/// How one extract option appears in Slicer.
struct SlicerParam {
    const char* option;      ///< CLI11 name: "INPUT" or a long flag
    const char* tag;         ///< Slicer element: image, geometry, file, double, string, ...
    const char* attributes;  ///< extra XML attributes of the element ("" for none)
    const char* label;       ///< shown in Slicer's GUI
    const char* channel;     ///< "input" / "output" for data, "" for a setting
    const char* fallback_default;  ///< used when the option has no captured default (nullptr: none)
    const char* note;        ///< appended to the option's description ("" for none)
    const char* step;        ///< slider step: emit <constraints> from the option's Range (nullptr: none)
};

struct SlicerGroup {
    const char* label;
    const char* description;
    std::vector<SlicerParam> params;
};

const std::vector<SlicerGroup>& slicer_groups() {
    static const std::vector<SlicerGroup> groups = {
        {"Input and output",
         "The CT volume and what to write. Meshes and masks are in the scan's world coordinates "
         "(LPS, mm), so they overlay the input.",
         {
             {"INPUT", "image", "", "Input CT volume", "input", nullptr, "", nullptr},
             {"--output", "geometry", R"(type="model" fileExtensions=".stl,.ply,.obj")", "Endocast model",
              "output", nullptr, "", nullptr},
             {"--mask", "image", R"(type="label" fileExtensions=".nrrd")", "Endocast label map", "output",
              nullptr, "", nullptr},
             {"--report", "file", R"(fileExtensions=".json")", "Report (JSON)", "output", nullptr,
              "Keys are documented in docs/report.schema.json.", nullptr},
         }},
        {"Method",
         "Parameters of the method (Michikawa et al. 2017). The defaults suit most skull CTs.",
         {
             {"--iso", "string", "", "Bone isovalue", "", nullptr,
              "Leave empty for the automatic isovalue.", nullptr},
             {"--void-radius", "double", "", "Void radius (voxels)", "", nullptr, "", nullptr},
             {"--void-radius-mm", "string", "", "Void radius (mm)", "", nullptr,
              "Leave empty to use the radius in voxels.", nullptr},
             {"--thin-bone", "double", "", "Thin bone (ridge prominence)", "", nullptr,
              "0.5 (default) takes thin bone blurred below the isovalue (orbital roofs) as bone; 0 = off.", "0.05"},
             {"--seed-mode", "string-enumeration", "", "Seed mode", "", nullptr, "", nullptr},
             {"--seed-scale", "double", "", "Seed scale", "", nullptr, "", "0.05"},
             {"--border-seed-scale", "string", "", "Border seed scale", "", nullptr,
              "Leave empty to use the seed scale.", nullptr},
             {"--distance-threshold", "double", "", "Distance threshold (mm)", "", "0", "", nullptr},
             {"--seed-point", "point", R"(multiple="false" coordinateSystem="lps")", "Seed point", "",
              nullptr, "In Slicer: one markups point (passed in LPS, as endocast expects).", nullptr},
             {"--no-close-openings", "boolean", "", "Keep openings (paper's boundary)", "", "false", "",
              nullptr},
             {"--no-restore-creases", "boolean", "", "Leave creases closed (void fill's boundary)", "", "false",
              "", nullptr},
             {"--no-flush-dips", "boolean", "", "Leave closing surfaces dipping into plugged holes, sunk down wider channels or unfaired across wide openings", "", "false",
              "", nullptr},
             {"--opening-radius-mm", "double", "", "Opening core radius (mm)", "", "0",
              "0 = automatic.", nullptr},
             {"--surface", "string-enumeration", "", "Surface", "", nullptr, "", nullptr},
         }},
    };
    return groups;
}

/// "--void-radius" -> "void_radius" (a Slicer long flag: letters, digits, underscores).
std::string slicer_flag(const std::string& option) {
    std::string s = option.substr(option.find_first_not_of('-'));
    for (char& c : s)
        if (c == '-') c = '_';
    return s;
}

/// "--void-radius" -> "voidRadius" (a Slicer parameter name, a C identifier).
std::string slicer_name(const std::string& option) {
    if (option == "INPUT") return "inputVolume";
    std::string out;
    bool upper = false;
    for (char c : option.substr(option.find_first_not_of('-'))) {
        if (c == '-') {
            upper = true;
            continue;
        }
        out += upper ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
        upper = false;
    }
    return out;
}

/// The text between the first `open` and the next `close` in `s`, or "" when absent.
std::string between(const std::string& s, char open, char close) {
    const auto a = s.find(open);
    if (a == std::string::npos) return "";
    const auto b = s.find(close, a + 1);
    return b == std::string::npos ? "" : s.substr(a + 1, b - a - 1);
}

const CLI::Option* find_option(const CLI::App& extract, const std::string& name) {
    for (const CLI::Option* opt : extract.get_options()) {
        if (name == "INPUT" ? opt->get_positional() && opt->get_name() == "INPUT"
                            : opt->check_lname(name.substr(name.find_first_not_of('-'))))
            return opt;
    }
    throw std::logic_error("Slicer description: '" + name + "' is not an option of endocast extract");
}

void write_param(std::ostringstream& x, const CLI::App& extract, const SlicerParam& p) {
    const CLI::Option* opt = find_option(extract, p.option);
    const std::string tag = p.tag;
    x << "    <" << tag << (*p.attributes ? " " : "") << p.attributes << ">\n";
    x << "      <name>" << slicer_name(p.option) << "</name>\n";
    x << "      <label>" << escape_markup(p.label) << "</label>\n";
    std::string description = opt->get_description();
    if (*p.note) description += ". " + std::string(p.note);
    x << "      <description>" << escape_markup(description) << "</description>\n";
    if (opt->get_positional())
        x << "      <index>0</index>\n";
    else
        x << "      <longflag>--" << slicer_flag(p.option) << "</longflag>\n";
    if (*p.channel) x << "      <channel>" << p.channel << "</channel>\n";
    std::string def = opt->get_default_str();
    if (def.empty() && p.fallback_default) def = p.fallback_default;
    const bool numeric = tag == "double" || tag == "boolean" || tag == "string-enumeration";
    if (numeric && def.empty())
        throw std::logic_error(std::string("Slicer description: ") + p.option + " needs a default");
    if (!def.empty()) x << "      <default>" << escape_markup(def) << "</default>\n";
    if (tag == "string-enumeration") {
        // CLI::IsMember describes itself as {a,b,c}.
        const std::string members = between(opt->get_type_name(), '{', '}');
        if (members.empty())
            throw std::logic_error(std::string("Slicer description: ") + p.option + " has no IsMember check");
        for (const std::string& e : split(members, ","))
            x << "      <element>" << escape_markup(e) << "</element>\n";
    }
    if (p.step) {
        // CLI::Range describes itself as "FLOAT in [min - max]".
        const std::vector<std::string> range = split(between(opt->get_type_name(), '[', ']'), " - ");
        if (range.size() != 2)
            throw std::logic_error(std::string("Slicer description: ") + p.option + " has no Range check");
        x << "      <constraints>\n        <minimum>" << range[0] << "</minimum>\n        <maximum>"
          << range[1] << "</maximum>\n        <step>" << p.step << "</step>\n      </constraints>\n";
    }
    x << "    </" << tag << ">\n";
}

}  // namespace

std::string extract_slicer_xml(const CLI::App& extract) {
    std::ostringstream x;
    x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<executable>\n"
      << "  <category>Segmentation</category>\n"
      << "  <title>Endocast extraction</title>\n"
      << "  <description>" << escape_markup(extract.get_description()) << "</description>\n"
      << "  <version>" << kVersion << "</version>\n"
      << "  <documentation-url>https://doi.org/10.1371/journal.pone.0168516</documentation-url>\n"
      << "  <license>libendocast and libmeshpost: permissive; the endocast program links CGAL and is "
         "therefore distributed under the GPL (version 3 or later)</license>\n"
      << "  <contributor>endocast developers</contributor>\n"
      << "  <acknowledgements>Method of Michikawa T, Suzuki H, Moriguchi M, Ogihara N, Kondo O, "
         "Kobayashi Y (2017), PLoS ONE 12(4): e0168516. Uses ITK, CGAL, OpenMesh, Eigen, CLI11 and "
         "nlohmann-json.</acknowledgements>\n";
    for (const SlicerGroup& g : slicer_groups()) {
        x << "  <parameters>\n    <label>" << escape_markup(g.label) << "</label>\n    <description>"
          << escape_markup(g.description) << "</description>\n";
        for (const SlicerParam& p : g.params) write_param(x, extract, p);
        x << "  </parameters>\n";
    }
    x << "</executable>\n";
    return x.str();
}

void setup_slicer_xml(CLI::App& app) {
    CLI::App* extract = app.get_subcommand("extract");
    // Runs while parsing, before required options are checked, so `extract --xml` needs no INPUT.
    auto print = [extract](std::int64_t) {
        std::cout << extract_slicer_xml(*extract);
        throw CLI::Success();
    };
    extract->add_flag_function("--xml", print,
                               "Print the 3D Slicer Execution Model description of this command "
                               "(docs/slicer.md) and exit");
    app.add_flag_function(
        "--xml",
        [&app, print](std::int64_t n) {
            for (const CLI::App* sub : app.get_subcommands())
                if (sub->get_name() != "extract")
                    throw CLI::ValidationError("--xml", "describes `extract` only, not `" + sub->get_name() + "`");
            print(n);
        },
        "Print the 3D Slicer Execution Model description of `extract` and exit (docs/slicer.md)");
}

}  // namespace endocast::cli
