// extract's pictures and reports: --qc PNG, --html report (checked in headless Chromium when
// installed), progress output (--log-json, --quiet).
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <sstream>

#include "cli_helpers.h"
#include "endocast/qc.h"

using namespace cli_test;

namespace {

// One small phantom extracted once per test process, with every output.
struct Extracted {
    fs::path dir;
    CliRun run;
};

/// A small phantom (macaque), made once per test process.
const fs::path& phantom() {
    static const fs::path p = [] {
        const fs::path dir = temp_dir("report_phantom");
        const CliRun ph = run("phantom " + (dir / "mq.nrrd").string() + " --preset macaque --seed 3");
        if (ph.status != 0) throw std::runtime_error("phantom failed: " + ph.output);
        return dir / "mq.nrrd";
    }();
    return p;
}

const Extracted& extracted() {
    static const Extracted e = [] {
        Extracted x;
        x.dir = temp_dir("report");
        x.run = run("extract " + phantom().string() + " -o " + (x.dir / "mq.stl").string() + " --qc " +
                    (x.dir / "qc.png").string() + " --html " + (x.dir / "html").string() + " --report " +
                    (x.dir / "r.json").string());
        return x;
    }();
    return e;
}

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

/// Runs a shell command, returns its stdout.
std::string shell(const std::string& cmd) {
    std::string out;
    FILE* p = popen(cmd.c_str(), "r");
    if (!p) return out;
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    pclose(p);
    return out;
}

std::string find_chromium() {
    for (const char* name : {"chromium", "chromium-browser", "google-chrome"}) {
        std::string path = shell(std::string("command -v ") + name + " 2>/dev/null");
        while (!path.empty() && (path.back() == '\n' || path.back() == ' ')) path.pop_back();
        if (!path.empty()) return path;
    }
    return "";
}

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> v;
    std::istringstream s(text);
    for (std::string l; std::getline(s, l);)
        if (!l.empty()) v.push_back(l);
    return v;
}

/// The opening tag `<name ...>` (first one) of an HTML text, or "".
std::string open_tag(const std::string& html, const std::string& name) {
    const size_t a = html.find("<" + name);
    if (a == std::string::npos) return "";
    const size_t b = html.find('>', a);
    return b == std::string::npos ? "" : html.substr(a, b - a + 1);
}

size_t count_colour(const cv::Mat& img, const cv::Vec3b& c) {
    size_t n = 0;
    for (int y = 0; y < img.rows; ++y)
        for (int x = 0; x < img.cols; ++x) n += img.at<cv::Vec3b>(y, x) == c;
    return n;
}

}  // namespace

TEST(CliQc, PngShowsTheOutlineInEveryPanel) {
    const Extracted& e = extracted();
    ASSERT_EQ(e.run.status, 0) << e.run.output;
    ASSERT_TRUE(fs::exists(e.dir / "qc.png"));
    const auto bytes = fs::file_size(e.dir / "qc.png");
    EXPECT_GT(bytes, 20'000u);
    EXPECT_LT(bytes, 5'000'000u);
    const cv::Mat img = cv::imread((e.dir / "qc.png").string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty());
    // A last row of slices through the closures: one per closing surface listed, up to six.
    const auto rep = read_json(e.dir / "r.json");
    endocast::QcParams defaults;
    defaults.closures.resize(std::min<size_t>(6, rep["openings"]["list"].size()));
    ASSERT_GT(defaults.closures.size(), 0u);
    const std::vector<cv::Rect> panels = endocast::qc_panels(defaults);
    int width = 0, height = 0;
    for (const cv::Rect& r : panels) width = std::max(width, r.br().x), height = std::max(height, r.br().y);
    EXPECT_EQ(img.cols, width);
    EXPECT_EQ(img.rows, height);
    for (size_t n = 12; n < panels.size(); ++n) {  // the closures: the outline and the centre's mark
        SCOPED_TRACE("closure " + std::to_string(n));
        EXPECT_GT(count_colour(img(panels[n]), defaults.contour_bgr), 10u);
        EXPECT_GT(count_colour(img(panels[n]), defaults.closure_bgr), 3u);
    }
    for (size_t n = 0; n < 9; ++n) {  // 3 planes + 6 axial slices
        SCOPED_TRACE("panel " + std::to_string(n));
        EXPECT_GT(count_colour(img(panels[n]), defaults.contour_bgr), 40u);
    }
    for (size_t n = 9; n < 12; ++n) {  // mesh views: shaded, no outline colour
        SCOPED_TRACE("mesh view " + std::to_string(n));
        EXPECT_EQ(count_colour(img(panels[n]), defaults.contour_bgr), 0u);
        cv::Mat grey;
        img(panels[n]).convertTo(grey, CV_8U);
        EXPECT_GT(cv::countNonZero(grey.reshape(1) > 100), panels[n].area() / 20);
    }
    const auto j = read_json(e.dir / "r.json");
    // Faces not on bone in the second colour (orange: red, no blue) in the mesh views, when any.
    size_t orange = 0;
    for (size_t n = 9; n < 12; ++n)
        for (int y = 0; y < panels[n].height; ++y)
            for (int x = 0; x < panels[n].width; ++x) {
                const cv::Vec3b px = img(panels[n]).at<cv::Vec3b>(y, x);
                orange += px[2] > 60 && px[0] * 4 < px[2] && px[1] < px[2];
            }
    if (j["bone_contact"].get<double>() < 0.999) EXPECT_GT(orange, 50u);
    if (j["bone_contact"].get<double>() == 1.0) EXPECT_EQ(orange, 0u);
    EXPECT_EQ(j["outputs"]["qc"], (e.dir / "qc.png").string());
    EXPECT_EQ(j["outputs"]["html"], (e.dir / "html").string());
    EXPECT_TRUE(j["timings_s"].contains("qc"));
}

TEST(CliQc, RejectsANonPngName) {
    const fs::path out = temp_dir("qcbad");
    // Checked before the input is read.
    const CliRun r = run("extract " + (out / "missing.nrrd").string() + " --qc " + (out / "qc.jpg").string());
    EXPECT_EQ(r.status, 4) << r.output;
    EXPECT_NE(r.output.find("qc.jpg"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "qc.jpg"));
}

TEST(CliHtml, MissingParentDirectoryFailsBeforeTheWork) {
    const fs::path out = temp_dir("htmlbad");
    const CliRun r = run("extract " + phantom().string() + " --html " + (out / "no" / "such").string());
    EXPECT_EQ(r.status, 3) << r.output;
    EXPECT_NE(r.output.find((out / "no").string()), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("binarize"), std::string::npos) << r.output;
}

TEST(CliHtml, ReportHoldsTheNumbersAndLoadsNothingFromTheNetwork) {
    const Extracted& e = extracted();
    ASSERT_EQ(e.run.status, 0) << e.run.output;
    const std::string html = slurp(e.dir / "html" / "index.html");
    const auto j = read_json(e.dir / "r.json");
    ASSERT_FALSE(html.empty());
    auto fmt = [](double v) {
        std::ostringstream s;
        s.precision(6);
        s << v;
        return s.str();
    };
    EXPECT_NE(html.find("Endocast of mq"), std::string::npos);
    // Bone contact: the first row of the result, before the ECV, with its threshold.
    const double contact = j["bone_contact"].get<double>();
    const size_t bc = html.find("<tr><th>bone contact (share of the surface on bone, expected &ge; 0.85)</th>");
    ASSERT_NE(bc, std::string::npos);
    EXPECT_LT(bc, html.find("endocranial volume (mL)"));
    EXPECT_LT(html.find("<h2>Result</h2>"), bc);
    const std::string value = fmt(contact) + (contact < 0.85 ? " &mdash; below 0.85: check the openings" : "");
    EXPECT_NE(html.find(std::string(contact < 0.85 ? "bad" : "ok") + "\">" + value, bc), std::string::npos);
    EXPECT_NE(html.find(fmt(j["ecv_ml"].get<double>())), std::string::npos);
    EXPECT_NE(html.find(fmt(j["surface_area_mm2"].get<double>())), std::string::npos);
    EXPECT_NE(html.find("<th>triangles</th><td>" + std::to_string(j["faces"].get<size_t>()) + "</td>"), std::string::npos);
    EXPECT_NE(html.find("closed 2-manifold</th><td class=\"ok\">yes"), std::string::npos);
    EXPECT_NE(html.find("<th>genus</th><td>0</td>"), std::string::npos);
    EXPECT_NE(html.find("self-intersecting triangle pairs</th><td>0</td>"), std::string::npos);
    EXPECT_NE(html.find("<th>polygonize</th>"), std::string::npos);
    EXPECT_NE(html.find("src=\"data:image/png;base64,"), std::string::npos);
    if (html.find("built without three.js") == std::string::npos)
        EXPECT_NE(html.find("<script type=\"importmap\">"), std::string::npos);
    EXPECT_EQ(html.find("http://"), std::string::npos);
    EXPECT_EQ(html.find("https://"), std::string::npos);
    for (size_t a = html.find("<script"); a != std::string::npos; a = html.find("<script", a + 1)) {
        const std::string tag = html.substr(a, html.find('>', a) - a);
        EXPECT_EQ(tag.find(" src="), std::string::npos) << tag;
    }
}

TEST(CliHtml, ChromiumRendersThe3dViewWithoutErrors) {
    const std::string chromium = find_chromium();
    if (chromium.empty()) GTEST_SKIP() << "chromium not installed (apt install chromium): HTML rendering test skipped";
    const Extracted& e = extracted();
    ASSERT_EQ(e.run.status, 0) << e.run.output;
    const fs::path page = e.dir / "html" / "index.html";
    if (slurp(page).find("built without three.js") != std::string::npos)
        GTEST_SKIP() << "this endocast was built without three.js (npm missing): no 3D view to render";
    // Software WebGL (SwiftShader) so no GPU is needed; virtual time lets the module run and render.
    const std::string flags = " --headless=new --no-sandbox --disable-gpu --enable-unsafe-swiftshader "
                              "--use-angle=swiftshader --no-first-run --user-data-dir=" +
                              (e.dir / "chromium-profile").string() +
                              " --window-size=1280,1000 --virtual-time-budget=15000 ";
    const std::string dom = shell("timeout 240 " + chromium + flags + "--dump-dom file://" + page.string() + " 2>" +
                                  (e.dir / "chromium-dom.log").string());
    const std::string body = open_tag(dom, "body"), html_tag = open_tag(dom, "html");
    ASSERT_FALSE(body.empty()) << "no <body> in the DOM; see " << (e.dir / "chromium-dom.log");
    EXPECT_EQ(html_tag.find("data-errors"), std::string::npos) << "page errors: " << html_tag;
    EXPECT_NE(body.find("data-rendered=\"ok\""), std::string::npos) << body;
    std::smatch rect;
    ASSERT_TRUE(std::regex_search(body, rect, std::regex("data-canvas-rect=\"(\\d+),(\\d+),(\\d+),(\\d+)\"")))
        << body;
    const cv::Rect canvas(std::stoi(rect[1]), std::stoi(rect[2]), std::stoi(rect[3]), std::stoi(rect[4]));

    const fs::path shot = e.dir / "screenshot.png";
    shell("timeout 240 " + chromium + flags + "--screenshot=" + shot.string() + " file://" + page.string() + " 2>" +
          (e.dir / "chromium-shot.log").string());
    const cv::Mat img = cv::imread(shot.string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty()) << "no screenshot; see " << (e.dir / "chromium-shot.log");
    std::printf("[ chromium ] screenshot %s, canvas at %d,%d %dx%d\n", shot.c_str(), canvas.x, canvas.y,
                canvas.width, canvas.height);
    const cv::Rect visible = canvas & cv::Rect(0, 0, img.cols, img.rows);
    ASSERT_GT(visible.area(), 100 * 100);
    // The canvas shows the mesh (warm, lit) on the dark background: both must be there.
    size_t background = 0, mesh = 0;
    for (int y = visible.y; y < visible.br().y; ++y)
        for (int x = visible.x; x < visible.br().x; ++x) {
            const cv::Vec3b px = img.at<cv::Vec3b>(y, x);
            if (std::abs(px[0] - 32) < 8 && std::abs(px[1] - 32) < 8 && std::abs(px[2] - 32) < 8) ++background;
            else if (px[2] > 80 && px[2] > px[0] + 15) ++mesh;
        }
    EXPECT_GT(mesh, size_t(visible.area()) / 50) << "the 3D view looks blank";
    EXPECT_GT(background, size_t(visible.area()) / 10);
}

TEST(CliProgress, LogJsonGivesOneObjectPerLineForEveryStage) {
    const fs::path out = temp_dir("logjson");
    const CliRun r = run("extract " + phantom().string() + " -o " + (out / "m.stl").string() +
                         " -q --log-json");
    ASSERT_EQ(r.status, 0) << r.output;
    std::vector<std::string> stages;
    nlohmann::json last;
    for (const std::string& l : lines(r.output)) {
        nlohmann::json j;
        ASSERT_NO_THROW(j = nlohmann::json::parse(l)) << "not JSON: " << l;
        ASSERT_TRUE(j.contains("event")) << l;
        ASSERT_TRUE(j["elapsed_s"].is_number()) << l;
        if (j["event"] == "stage") stages.push_back(j["stage"]);
        last = j;
    }
    EXPECT_EQ(stages, (std::vector<std::string>{"read", "binarize", "void_fill", "distance", "seeds", "watershed",
                                                "openings", "polygonize", "check", "write"}));
    EXPECT_EQ(last["event"], "done");
    EXPECT_GT(last["ecv_ml"].get<double>(), 0.0);
    EXPECT_GE(last["bone_contact"].get<double>(), 0.0);
    EXPECT_LE(last["bone_contact"].get<double>(), 1.0);
}

TEST(CliProgress, LogJsonReportsAnErrorAsJson) {
    const fs::path out = temp_dir("logjsonerr");
    const CliRun r = run("extract " + (out / "missing.nrrd").string() + " -q --log-json");
    EXPECT_EQ(r.status, 3) << r.output;
    const std::vector<std::string> l = lines(r.output);
    ASSERT_FALSE(l.empty());
    const nlohmann::json last = nlohmann::json::parse(l.back());
    EXPECT_EQ(last["event"], "error");
    EXPECT_EQ(last["exit_code"], 3);
    EXPECT_NE(last["message"].get<std::string>().find("missing.nrrd"), std::string::npos) << last;
}

TEST(CliProgress, QuietPrintsNothing) {
    const fs::path out = temp_dir("quiet");
    const CliRun r = run("extract " + phantom().string() + " -o " + (out / "m.stl").string() + " -q");
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(r.output, "");
}

TEST(CliProgress, PlainLinesWhenNotATerminal) {
    const Extracted& e = extracted();
    ASSERT_EQ(e.run.status, 0) << e.run.output;
    for (const char* s : {"  binarize ...", "  polygonize ...", "  qc ...", "  html ..."})
        EXPECT_NE(e.run.output.find(s), std::string::npos) << s << "\n" << e.run.output;
    EXPECT_EQ(e.run.output.find("\r"), std::string::npos);
}

TEST(CliQcRealData, HeadphantomDicomQcPng) {
    if (!fs::exists(shared("headphantom-dicom")))
        GTEST_SKIP() << "../shared/data/headphantom-dicom not found: real-data test skipped";
    const fs::path out = temp_dir("hpqc");
    const CliRun r = run("extract " + shared("headphantom-dicom") + " --iso 250 --qc " + (out / "qc.png").string() +
                         " --html " + (out / "html").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const cv::Mat img = cv::imread((out / "qc.png").string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty());
    const endocast::QcParams defaults;
    const std::vector<cv::Rect> panels = endocast::qc_panels(defaults);
    for (size_t n = 0; n < 9; ++n) EXPECT_GT(count_colour(img(panels[n]), defaults.contour_bgr), 40u) << n;
    EXPECT_TRUE(fs::exists(out / "html" / "index.html"));
}
