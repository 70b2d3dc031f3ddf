// Progress of a long command on stderr: bar, lines, JSON lines or nothing (progress.h).
#include "progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <sstream>

namespace endocast::cli {

ProgressStyle choose_progress_style(bool quiet, bool json) {
    if (json) return ProgressStyle::Json;
    if (quiet) return ProgressStyle::None;
    return ::isatty(STDERR_FILENO) ? ProgressStyle::Bar : ProgressStyle::Lines;
}

Progress::Progress(ProgressStyle style, int stages)
    : style_(style), stages_(stages < 1 ? 1 : stages), t0_(std::chrono::steady_clock::now()) {}

Progress::~Progress() { end_bar_line(); }

double Progress::elapsed_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
}

void Progress::end_bar_line() {
    if (bar_open_) std::cerr << "\n" << std::flush;
    bar_open_ = false;
}

void Progress::stage(const std::string& name) {
    ++index_;
    switch (style_) {
        case ProgressStyle::None: return;
        case ProgressStyle::Lines: std::cerr << "  " << name << " ..." << std::endl; return;
        case ProgressStyle::Json:
            std::cerr << nlohmann::json{{"event", "stage"}, {"stage", name}, {"index", index_},
                                        {"of", stages_}, {"elapsed_s", elapsed_s()}}.dump()
                      << std::endl;
            return;
        case ProgressStyle::Bar:
            stage_name_ = name;
            draw_bar();
            return;
    }
}

void Progress::draw_bar() {
    constexpr int kWidth = 24;
    const int k = index_ > stages_ ? stages_ : index_;
    const int filled = (k - 1) * kWidth / stages_;
    char t[32];
    std::snprintf(t, sizeof t, "%7.1f s", elapsed_s());
    std::cerr << "\r  [" << std::string(size_t(filled), '#') << std::string(size_t(kWidth - filled), '-') << "] "
              << k << "/" << stages_ << " " << stage_name_
              << std::string(12 - std::min<size_t>(12, stage_name_.size()), ' ') << t << "\x1b[K" << std::flush;
    bar_open_ = true;
}

void Progress::info(const std::string& message) {
    if (style_ == ProgressStyle::None) return;
    if (style_ == ProgressStyle::Json) {
        std::cerr << nlohmann::json{{"event", "info"}, {"message", message}, {"elapsed_s", elapsed_s()}}.dump() << std::endl;
        return;
    }
    if (bar_open_) {  // the message above, the bar redrawn below it
        std::cerr << "\r\x1b[K" << message << "\n";
        draw_bar();
        return;
    }
    std::cerr << message << std::endl;
}

void Progress::warning(const std::string& message) {
    if (style_ == ProgressStyle::Json) {
        std::cerr << nlohmann::json{{"event", "warning"}, {"message", message}, {"elapsed_s", elapsed_s()}}.dump() << std::endl;
        return;
    }
    if (bar_open_) std::cerr << "\r\x1b[K";
    bar_open_ = false;
    std::cerr << "endocast: warning: " << message << "\n";
}

void Progress::done(const nlohmann::json& extra) {
    if (style_ == ProgressStyle::Json) {
        nlohmann::json j{{"event", "done"}, {"elapsed_s", elapsed_s()}};
        for (auto it = extra.begin(); it != extra.end(); ++it) j[it.key()] = it.value();
        std::cerr << j.dump() << std::endl;
        return;
    }
    if (style_ == ProgressStyle::Bar && bar_open_) {
        char t[32];
        std::snprintf(t, sizeof t, "%7.1f s", elapsed_s());
        std::cerr << "\r  [" << std::string(24, '#') << "] " << stages_ << "/" << stages_ << " done        " << t
                  << "\x1b[K";
    }
    end_bar_line();
}

}  // namespace endocast::cli
