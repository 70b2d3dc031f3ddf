#pragma once
// Progress of a long command on stderr: a bar on a terminal, plain lines otherwise, JSON lines
// with --log-json, nothing with --quiet.
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>

namespace endocast::cli {

enum class ProgressStyle {
    None,   ///< --quiet
    Lines,  ///< "  stage ..." lines (stderr is not a terminal)
    Bar,    ///< one line redrawn in place: [#####-----] k/n stage  elapsed s
    Json,   ///< one JSON object per line: {"event":"stage","stage":...,"index":k,"of":n,"elapsed_s":...}
};

/// None when quiet (and not json), Json when json, Bar when stderr is a terminal, Lines otherwise.
ProgressStyle choose_progress_style(bool quiet, bool json);

class Progress {
public:
    /// `stages`: how many stage() calls are expected (for the bar's k of n).
    Progress(ProgressStyle style, int stages);
    /// Ends an open bar line, so an error message printed after an exception starts a new line.
    ~Progress();
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;
    /// A stage starts (its name as the pipeline reports it, e.g. "distance").
    void stage(const std::string& name);
    /// A line of information (Lines/Bar: printed as is; Json: {"event":"info","message":...}).
    void info(const std::string& message);
    /// A warning (always printed, except None keeps "endocast: warning:" lines on stderr too).
    void warning(const std::string& message);
    /// The run finished: ends the bar's line; Json: {"event":"done","elapsed_s":...} + `extra`.
    void done(const nlohmann::json& extra = nlohmann::json::object());
    double elapsed_s() const;

private:
    void end_bar_line();
    void draw_bar();
    std::string stage_name_;
    ProgressStyle style_;
    int stages_, index_ = 0;
    bool bar_open_ = false;
    std::chrono::steady_clock::time_point t0_;
};

}  // namespace endocast::cli
