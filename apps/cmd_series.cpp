// `endocast series`: the DICOM series of a study folder or DICOMDIR, and the one extract reads.
#include <algorithm>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "commands.h"
#include "report.h"
#include "endocast/dicom_series.h"
#include "endocast/errors.h"

namespace endocast::cli {
namespace {

struct SeriesOptions {
    std::string path;
    std::string series_uid, description;  // the choice to preview, as extract's --series / --series-description
    bool json = false;
};

std::string num(double v) {
    std::ostringstream s;
    s << std::setprecision(4) << v;
    return s.str();
}

/// Columns padded to their widest cell, two spaces apart; the last column is not padded.
std::string table(const std::vector<std::vector<std::string>>& rows) {
    std::vector<size_t> width;
    for (const auto& r : rows)
        for (size_t c = 0; c < r.size(); ++c) {
            if (width.size() <= c) width.push_back(0);
            width[c] = std::max(width[c], r[c].size());
        }
    std::ostringstream out;
    for (const auto& r : rows) {
        for (size_t c = 0; c < r.size(); ++c) {
            out << r[c];
            if (c + 1 < r.size()) out << std::string(width[c] - r[c].size() + 2, ' ');
        }
        out << "\n";
    }
    return out.str();
}

void run_series(const SeriesOptions& o) {
    const DicomStudy study = list_dicom_series(o.path);
    std::optional<size_t> pick;
    std::string warning, no_volume;
    try {
        const DicomSeriesPick p = choose_dicom_series(study, {o.series_uid, o.description});
        pick = p.index;
        warning = p.warning;
    } catch (const IoError& e) {
        if (study.series.empty()) throw;  // nothing to list: unreadable input (exit 3)
        no_volume = e.what();             // only non-volumes: listed, and said
    }

    if (o.json) {
        nlohmann::json j;
        j["tool"] = "endocast series";
        j["path"] = study.path;
        j["folder"] = study.folder;
        j["files_scanned"] = study.files_scanned;
        j["files_skipped"] = study.files_skipped;
        nlohmann::json list = nlohmann::json::array();
        for (size_t i = 0; i < study.series.size(); ++i) {
            nlohmann::json s = dicom_series_json(study.series[i], pick && *pick == i);
            s["files"] = study.series[i].files;
            list.push_back(s);
        }
        j["series"] = list;
        j["chosen_series_uid"] = pick ? nlohmann::json(study.series[*pick].series_uid) : nlohmann::json(nullptr);
        j["choice_warning"] = warning.empty() ? nlohmann::json(nullptr) : nlohmann::json(warning);
        j["choice_error"] = no_volume.empty() ? nlohmann::json(nullptr) : nlohmann::json(no_volume);
        std::cout << j.dump(2) << "\n";
        return;
    }

    std::ostringstream out;
    out << study.path << ": " << study.series.size() << " DICOM series in " << study.files_scanned << " files";
    if (study.files_skipped > 0)
        out << " (" << study.files_skipped << " skipped: not DICOM, or no SeriesInstanceUID)";
    out << "\n";
    std::vector<std::vector<std::string>> rows = {{"", "SeriesInstanceUID", "description", "modality", "slices",
                                                   "size (px)", "pixel (mm)", "thickness", "step", "kernel", "volume"}};
    for (size_t i = 0; i < study.series.size(); ++i) {
        const DicomSeriesInfo& s = study.series[i];
        rows.push_back({pick && *pick == i ? "*" : "", s.series_uid, s.description.empty() ? "-" : s.description,
                        s.modality.empty() ? "-" : s.modality, std::to_string(s.files.size()),
                        std::to_string(s.columns) + " x " + std::to_string(s.rows),
                        num(s.pixel_spacing_mm[1]) + " x " + num(s.pixel_spacing_mm[0]),
                        s.slice_thickness_mm > 0 ? num(s.slice_thickness_mm) + " mm" : "-",
                        s.slice_step_mm > 0 ? num(s.slice_step_mm) + " mm" : "-", s.kernel.empty() ? "-" : s.kernel,
                        s.is_volume ? "yes" : "no: " + s.reason});
    }
    out << table(rows);
    if (pick)
        out << "* = the series extract reads"
            << (o.series_uid.empty() && o.description.empty()
                    ? " by default (the CT volume with the thinnest slices, then the most slices, then the smallest "
                      "UID); choose another with --series UID or --series-description TEXT"
                    : " with this choice")
            << "\n";
    else
        out << "extract would stop: " << no_volume << "\n";
    std::cout << out.str();
}

}  // namespace

void setup_series(CLI::App& app, const GlobalOptions& /*g*/) {
    auto o = std::make_shared<SeriesOptions>();
    auto* sub = app.add_subcommand(
        "series",
        "List the DICOM series of a folder (searched recursively; files that are not DICOM are skipped) or of "
        "the folder of a DICOMDIR file: per series its SeriesInstanceUID, description, modality, slices, size "
        "(columns x rows, pixels), pixel spacing (mm, along x by along y), slice thickness and step (mm), kernel, whether it "
        "is a volume extract can read and why not (localizer, secondary capture or report, single image, "
        "slices of several sizes); '*' marks the series extract reads. Exit 3 when PATH holds no DICOM "
        "series or cannot be read, 4 when --series/--series-description match none or several, else 0.");
    sub->add_option("PATH", o->path, "A folder holding DICOM files (any depth) or a DICOMDIR file")->required();
    sub->add_option("--series", o->series_uid, "Mark the series extract --series UID would read");
    sub->add_option("--series-description", o->description,
                    "Mark the series extract --series-description TEXT would read");
    sub->add_flag("--json", o->json,
                  "Print JSON instead of the table: path, folder, files_scanned, files_skipped, series (each "
                  "with the report's input.series_found fields plus its files in slice order), "
                  "chosen_series_uid, choice_warning, choice_error (null when unset)");
    sub->callback([o] { run_series(*o); });
}

}  // namespace endocast::cli
