#pragma once
// The picture and report outputs of `endocast extract` (--qc, --html), kept out of cmd_extract.cpp.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>

#include "endocast/pipeline.h"
#include "progress.h"

namespace endocast::cli {

struct QcOptions {
    std::string qc;       ///< --qc: PNG path ("" = none)
    std::string html;     ///< --html: report directory ("" = none)
    int panel_px = 400;   ///< --qc-panel-px: size of the picture's large panels
};

/// Declares --qc, --html and --qc-panel-px on the extract subcommand.
void add_qc_options(CLI::App& sub, QcOptions& o);

/// Checks the options before the work starts: --qc must end in .png (InvalidParameter).
void check_qc_options(const QcOptions& o);

/// Stages reported by `extract`: read, the pipeline's 6 (7 with openings), check, write, qc, html.
int extract_stage_count(bool openings, const QcOptions& o);

/// Draws the QC picture when either output is asked for, writes o.qc (PNG, atomically) and the
/// HTML report o.html/index.html (from `report`, which gains timings_s.qc / timings_s.html).
template <class T>
void write_qc_outputs(const QcOptions& o, const Volume<T>& ct, const ExtractionResult& r,
                      nlohmann::json& report, Progress& progress);

}  // namespace endocast::cli
