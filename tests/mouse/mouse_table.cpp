// Prints the markdown table of docs/accuracy.md's mouse section: each shared mouse scan's result
// (an `endocast batch ... --masks` folder) scored against the expert label carried by landmarks.
//
//   mouse_table DATA_DIR BATCH_DIR [TEMPLATE_MASK TEMPLATE_REPORT]
//
// DATA_DIR: ../shared/data/mouse-microct; BATCH_DIR: OUTDIR of the batch (OUTDIR/<scan>/mask.nii.gz,
// report.json); the template's own extraction (--mask, --report) adds a last row.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "endocast/io.h"
#include "mouse_truth.h"

namespace fs = std::filesystem;

namespace {

endocast::Volume<uint8_t> read_mask(const std::string& p) {
    const endocast::Volume<float> f = endocast::read_volume({p}).volume;
    endocast::Volume<uint8_t> m(f.geometry(), 0);
    for (size_t i = 0; i < f.size(); ++i) m[i] = f[i] != 0.f;
    return m;
}

nlohmann::json read_json(const std::string& p) {
    std::ifstream in(p);
    return nlohmann::json::parse(in);
}

void row(const std::string& name, const nlohmann::json& rep, const mouse_truth::Scores& s) {
    std::printf("| %s | %.1f | %.1f | %.1f | %+.1f | %.3f | %.2f | %.2f | %.3f | %.3f | %zu |\n", name.c_str(),
                rep["isovalue"].get<double>(), 1000 * s.label_ml, 1000 * s.ecv_ml, 100 * s.ecv_error, s.dice,
                100 * s.nasal_share, s.fm_reach_mm, rep["bone_contact"].get<double>(), rep.value("leak_share", 0.0),
                rep["warnings"].size());
}

}  // namespace

int main(int argc, char** argv) try {
    if (argc != 3 && argc != 5) {
        std::fprintf(stderr, "usage: mouse_table DATA_DIR BATCH_DIR [TEMPLATE_MASK TEMPLATE_REPORT]\n");
        return 2;
    }
    const std::string data = argv[1], batch = argv[2];
    const auto tpl = mouse_truth::load_template(data + "/template");
    const auto frames = mouse_truth::read_frames(std::string(ENDOCAST_SOURCE_DIR) + "/tests/mouse/landmark_frames.json");
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(data + "/scans")) {
        const std::string f = e.path().filename().string();
        if (f.size() > 7 && f.substr(f.size() - 7) == ".nii.gz") names.push_back(f.substr(0, f.size() - 7));
    }
    std::sort(names.begin(), names.end());
    std::printf("| scan | isovalue | label mm^3 | ECV mm^3 | ECV error %% | Dice | nasal %% | past FM mm | bone contact | leak share | warnings |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
    std::vector<double> dice, err;
    for (const std::string& name : names) {
        const std::string dir = batch + "/" + name;
        const auto rep = read_json(dir + "/report.json");
        const auto mask = read_mask(dir + "/mask.nii.gz");
        const auto truth = mouse_truth::carry(
            tpl, mask.geometry(), mouse_truth::scan_landmarks(data + "/landmarks/" + name + ".mrk.json", name, frames));
        const mouse_truth::Scores s = mouse_truth::score(tpl, truth, mask, rep["ecv_ml"].get<double>());
        row(name, rep, s);
        dice.push_back(s.dice);
        err.push_back(std::abs(s.ecv_error));
    }
    if (argc == 5) {
        const auto rep = read_json(argv[4]);
        const auto mask = read_mask(argv[3]);
        row("template (own label)", rep,
            mouse_truth::score(tpl, mouse_truth::carry(tpl, mask.geometry(), tpl.landmarks), mask, rep["ecv_ml"].get<double>()));
    }
    std::sort(dice.begin(), dice.end());
    std::printf("\n%zu scans: Dice min %.3f, median %.3f; largest |ECV error| %.1f %%\n", dice.size(), dice.front(),
                dice[dice.size() / 2], 100 * *std::max_element(err.begin(), err.end()));
    return 0;
} catch (const std::exception& e) {
    std::fprintf(stderr, "mouse_table: %s\n", e.what());
    return 1;
}
