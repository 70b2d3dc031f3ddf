#pragma once
// Subcommands of the `endocast` CLI: each has an options struct, a setup_* that declares its
// options on the app, and a run_* that does the work and returns the exit status.
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "endocast/dicom_series.h"
#include "endocast/stages/polygonize.h"

#ifndef ENDOCAST_VERSION
#define ENDOCAST_VERSION "unknown"  // set by apps/CMakeLists.txt from project(VERSION)
#endif

namespace endocast::cli {

/// The version of this build (CMake's project version), written into reports and the Slicer XML.
inline constexpr const char* kVersion = ENDOCAST_VERSION;

/// Exit statuses, listed in `endocast --help` and the README.
enum ExitCode : int {
    kOk = 0,
    kDefects = 1,          ///< inspect: the mesh is readable but not a clean closed 2-manifold;
                           ///< batch: one or more specimens failed (listed in summary.csv)
    kUsage = 2,            ///< bad command line
    kInputError = 3,       ///< missing, unreadable or malformed input file
    kInvalidParameter = 4, ///< a parameter out of range or inconsistent with the input
    kNoResult = 5,         ///< valid input, but no cavity/bone found
    kOutOfMemory = 6,
    kInternalError = 7,
};

const char* exit_code_help();

/// `s` with & < > " replaced by their entities, for HTML and XML text and attribute values.
std::string escape_markup(const std::string& s);

/// Ends the process with `code` (after flushing stdout) unless it is kOk. For statuses that report
/// a finding rather than an error (1: defects found, a batch specimen failed); main() maps
/// exceptions to the statuses 2-7.
void exit_unless_ok(int code);

/// Help of `--surface` (extract, robustness; batch mirrors extract's).
extern const char* const kSurfaceHelp;

/// Help of `--series` and `--series-description` (extract, robustness; batch mirrors extract's).
extern const char* const kSeriesHelp;
extern const char* const kSeriesDescriptionHelp;

/// Global options shared by all subcommands.
struct GlobalOptions {
    int threads = 0;     ///< 0 = all cores
    bool quiet = false;
    bool log_json = false;  ///< progress as one JSON object per line on stderr (extract)
};

void setup_extract(CLI::App& app, const GlobalOptions& g);
void setup_phantom(CLI::App& app, const GlobalOptions& g);
void setup_inspect(CLI::App& app, const GlobalOptions& g);
void setup_simplify(CLI::App& app, const GlobalOptions& g);
void setup_compare(CLI::App& app, const GlobalOptions& g);
void setup_robustness(CLI::App& app, const GlobalOptions& g);
void setup_series(CLI::App& app, const GlobalOptions& g);
/// Needs setup_extract first: mirrors extract's options.
void setup_batch(CLI::App& app, const GlobalOptions& g);

/// Adds `--xml` to the app and to its `extract` subcommand (call after setup_extract): prints the
/// 3D Slicer Execution Model description of `extract` and exits 0 (docs/slicer.md).
void setup_slicer_xml(CLI::App& app);
/// The Slicer Execution Model XML describing the `extract` subcommand `extract`. Throws
/// std::logic_error when its table names an option the subcommand does not have.
std::string extract_slicer_xml(const CLI::App& extract);

}  // namespace endocast::cli
