// `endocast batch`: extracts the endocasts of a collection of scans, one output folder per specimen
// and a summary table.
//
// Each specimen runs as a child process of this same binary (`/proc/self/exe extract ...`), so a
// crash or an out-of-memory kill of one specimen is recorded and the batch goes on. Every option of
// `extract` (except the per-specimen outputs) is mirrored here, read from the `extract` subcommand
// itself, and forwarded verbatim; the child validates it.
#include <fcntl.h>
#include <omp.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "commands.h"
#include "meshpost/io.h"
#include "meshpost/text.h"
#include "endocast/errors.h"

namespace endocast::cli {
namespace {

using meshpost::text::lower;
using meshpost::text::trim;

namespace fs = std::filesystem;

/// One forwarded option occurrence: the option's name followed by its values.
using Args = std::vector<std::string>;

struct BatchOptions {
    std::vector<std::string> inputs;
    std::string manifest;
    std::string outdir;
    int jobs = 1;
    bool force = false;
    bool masks = false;
    std::vector<Args> forwarded;          ///< extract options given on the command line, in order
    std::map<std::string, int> flags;     ///< extract flags given on the command line -> count
    std::vector<std::string> flag_names;  ///< every mirrored flag (long name)
    std::set<std::string> value_options;  ///< every mirrored option with values (long name)
    bool extract_has_qc = false;
};

struct Specimen {
    std::string name, input;
    std::vector<Args> row_options;  ///< from the manifest: override the command line's
    // results
    std::string status = "pending", error;
    nlohmann::json report;
    double seconds = 0;
};

const char* const kSummaryHeader =
    "specimen,input,isovalue,ecv_ml,surface_area_mm2,faces,closed_manifold,seconds,status,error,bone_contact";

// ---------------------------------------------------------------- CSV

/// Parses RFC 4180 CSV: quoted fields may hold commas, doubled quotes and newlines; CRLF or LF.
std::vector<std::vector<std::string>> parse_csv(const std::string& text, const std::string& path) {
    std::vector<std::vector<std::string>> rows;
    std::vector<std::string> row;
    std::string field;
    bool quoted = false, any = false;
    size_t i = text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // UTF-8 byte order mark
    auto end_row = [&] {
        row.push_back(field);
        field.clear();
        const bool blank = row.size() == 1 && row[0].empty() && !any;
        if (!blank) rows.push_back(row);
        row.clear();
        any = false;
    };
    for (; i < text.size(); ++i) {
        const char c = text[i];
        if (quoted) {
            if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
                field += '"';
                ++i;
            } else if (c == '"') {
                quoted = false;
            } else {
                field += c;
            }
        } else if (c == '"') {
            quoted = true;
            any = true;
        } else if (c == ',') {
            row.push_back(field);
            field.clear();
            any = true;
        } else if (c == '\n') {
            end_row();
        } else if (c != '\r') {
            field += c;
        }
    }
    if (quoted) throw IoError(path + ": unterminated quoted field (a '\"' without its closing '\"')");
    if (!field.empty() || !row.empty() || any) end_row();
    return rows;
}

std::string csv_field(const std::string& s) {
    if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

// ---------------------------------------------------------------- specimens

/// Input basename without the volume extensions; a DICOM directory gives its own name, a DICOMDIR
/// file its folder's.
std::string default_name(const std::string& input) {
    std::string base = fs::path(input).lexically_normal().filename().string();
    if (is_dicomdir_path(input)) base = fs::path(input).lexically_normal().parent_path().filename().string();
    if (base.empty() || base == ".") base = fs::path(input).lexically_normal().parent_path().filename().string();
    for (const char* ext : {".nii.gz", ".nrrd", ".nhdr", ".nii", ".mha", ".mhd"}) {
        const std::string e(ext);
        if (base.size() > e.size() && lower(base.substr(base.size() - e.size())) == e) {
            base.resize(base.size() - e.size());
            break;
        }
    }
    for (auto& c : base)
        if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.')) c = '_';
    return base.empty() ? "specimen" : base;
}

/// Gives every specimen without an explicit name a unique default one (name, name_2, name_3, ...).
void assign_names(std::vector<Specimen>& specimens) {
    std::set<std::string> taken;
    for (const auto& s : specimens) {
        if (s.name.empty()) continue;
        if (s.name.find('/') != std::string::npos || s.name == "." || s.name == "..")
            throw InvalidParameter("specimen name '" + s.name + "': expected a folder name without '/'");
        if (!taken.insert(s.name).second)
            throw InvalidParameter("specimen name '" + s.name + "' appears twice; names must be unique");
    }
    for (auto& s : specimens) {
        if (!s.name.empty()) continue;
        const std::string base = default_name(s.input);
        std::string name = base;
        for (int k = 2; taken.count(name); ++k) name = base + "_" + std::to_string(k);
        taken.insert(name);
        s.name = name;
    }
}

/// Reads the manifest: a header row with `input` (required), `specimen`, and any extract option
/// by its long name (`iso`, `seed-mode`, `--void-radius-mm`, ...); other columns are ignored.
std::vector<Specimen> read_manifest(const BatchOptions& o) {
    std::ifstream in(o.manifest, std::ios::binary);
    if (!in) throw IoError(o.manifest + ": cannot open the manifest (expected a CSV file)");
    std::stringstream ss;
    ss << in.rdbuf();
    const auto rows = parse_csv(ss.str(), o.manifest);
    if (rows.empty()) throw IoError(o.manifest + ": empty manifest, expected a header row with an 'input' column");
    const auto& header = rows[0];
    int input_col = -1, name_col = -1;
    std::map<int, std::string> option_cols;  // column -> --long-name
    std::vector<std::string> ignored;
    for (size_t c = 0; c < header.size(); ++c) {
        std::string h = lower(trim(header[c]));
        if (h == "input") input_col = int(c);
        else if (h == "specimen") name_col = int(c);
        else {
            const std::string opt = "--" + (h.rfind("--", 0) == 0 ? h.substr(2) : h);
            const bool is_flag = std::count(o.flag_names.begin(), o.flag_names.end(), opt) > 0;
            if (o.value_options.count(opt) || is_flag) option_cols[int(c)] = opt;
            else ignored.push_back(header[c]);
        }
    }
    if (input_col < 0)
        throw IoError(o.manifest + ": no 'input' column in the header row (found: " +
                      [&] { std::string s; for (const auto& h : header) s += (s.empty() ? "" : ", ") + h; return s; }() + ")");
    if (!ignored.empty()) {
        std::string s;
        for (const auto& h : ignored) s += (s.empty() ? "" : ", ") + h;
        std::cerr << "endocast: warning: " << o.manifest << ": ignoring columns that are not extract options: " << s << "\n";
    }
    const fs::path base = fs::path(o.manifest).parent_path();
    std::vector<Specimen> out;
    for (size_t r = 1; r < rows.size(); ++r) {
        const auto& row = rows[r];
        auto cell = [&](int c) { return c >= 0 && size_t(c) < row.size() ? trim(row[size_t(c)]) : std::string(); };
        if (!cell(0).empty() && cell(0)[0] == '#') continue;  // comment line
        Specimen s;
        s.input = cell(input_col);
        if (s.input.empty())
            throw IoError(o.manifest + ": row " + std::to_string(r + 1) + " has an empty 'input'");
        if (fs::path(s.input).is_relative()) s.input = (base / s.input).string();
        s.name = cell(name_col);
        for (const auto& [c, opt] : option_cols) {
            const std::string v = cell(c);
            if (v.empty()) continue;
            if (std::count(o.flag_names.begin(), o.flag_names.end(), opt)) {
                const std::string lv = lower(v);
                if (lv == "1" || lv == "true" || lv == "yes" || lv == "y") s.row_options.push_back({opt});
                else if (!(lv == "0" || lv == "false" || lv == "no" || lv == "n"))
                    throw InvalidParameter(o.manifest + ": row " + std::to_string(r + 1) + ", column '" + header[size_t(c)] +
                                           "': '" + v + "', expected true/false, yes/no or 1/0");
                continue;
            }
            Args a{opt};
            for (auto& w : meshpost::text::words(v)) a.push_back(w);
            s.row_options.push_back(a);
        }
        out.push_back(std::move(s));
    }
    if (out.empty()) throw IoError(o.manifest + ": no specimens (only a header row)");
    return out;
}

// ---------------------------------------------------------------- results

std::string fmt(double v, int decimals) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", decimals, v);
    return b;
}

std::string summary_row(const Specimen& s) {
    const auto& j = s.report;
    auto num = [&](const char* k, int d) {
        return j.contains(k) && j[k].is_number() ? fmt(j[k].get<double>(), d) : std::string();
    };
    std::string row = csv_field(s.name) + "," + csv_field(s.input) + ",";
    row += num("isovalue", 6) + "," + num("ecv_ml", 4) + "," + num("surface_area_mm2", 2) + ",";
    row += (j.contains("faces") ? std::to_string(j["faces"].get<long long>()) : "") + ",";
    row += (j.contains("closed_manifold") ? std::string(j["closed_manifold"].get<bool>() ? "true" : "false") : "") + ",";
    row += (s.status == "pending" ? "" : fmt(s.seconds, 2)) + ",";
    row += s.status + "," + csv_field(s.error) + ",";
    row += num("bone_contact", 4);  // appended last: the columns before it keep their positions
    return row;
}

void write_summary(const std::string& outdir, const std::vector<Specimen>& specimens) {
    std::string text = std::string(kSummaryHeader) + "\n";
    for (const auto& s : specimens) text += summary_row(s) + "\n";
    meshpost::write_file_atomic((fs::path(outdir) / "summary.csv").string(), text);
}

/// A finished specimen: its report.json parses, records an ECV, and the mesh is there.
bool load_done(const fs::path& dir, nlohmann::json& report) {
    const fs::path rp = dir / "report.json";
    if (!fs::exists(rp) || !fs::exists(dir / "endocast.stl")) return false;
    try {
        std::ifstream in(rp);
        report = nlohmann::json::parse(in);
    } catch (const std::exception&) {
        return false;
    }
    return report.contains("ecv_ml") && report["ecv_ml"].is_number();
}

/// The one-line reason a child failed: its last "endocast: ... error" line in the log (else its
/// last line), and how it ended.
std::string failure_message(const fs::path& log, int wait_status) {
    std::ifstream in(log);
    std::string line, last, last_error;
    while (std::getline(in, line)) {
        line = trim(line);
        if (line.empty() || line.rfind("Run with --help", 0) == 0) continue;  // CLI11's usage hint
        last = line;
        // "endocast: error: ...", "endocast: internal error: ...", a CLI11 usage error, ITK's "Error"
        if (line.find("error") != std::string::npos || line.find("Error") != std::string::npos) last_error = line;
    }
    std::string msg = !last_error.empty() ? last_error : last;
    for (const char* p : {"endocast: error: ", "endocast: "})
        if (msg.rfind(p, 0) == 0) msg = msg.substr(std::strlen(p));
    if (WIFSIGNALED(wait_status)) {  // a crash or a kill: say so first, then where it was
        const int sig = WTERMSIG(wait_status);
        std::string how = "killed by signal " + std::to_string(sig) + " (" + strsignal(sig) +
                          (sig == SIGKILL ? "; out of memory?" : "") + ")";
        return last.empty() ? how : how + " after: " + last;
    }
    const std::string how = "exit " + std::to_string(WIFEXITED(wait_status) ? WEXITSTATUS(wait_status) : -1);
    return msg.empty() ? how : msg + " (" + how + ")";
}

// ---------------------------------------------------------------- running

std::vector<std::string> child_args(const BatchOptions& o, const Specimen& s, const fs::path& dir, int threads) {
    std::vector<std::string> a{"endocast", "--threads", std::to_string(threads), "extract", s.input,
                               "-o", (dir / "endocast.stl").string(), "--report", (dir / "report.json").string()};
    if (o.extract_has_qc) {
        a.push_back("--qc");
        a.push_back((dir / "qc.png").string());
    }
    if (o.masks) {
        a.push_back("--mask");
        a.push_back((dir / "mask.nii.gz").string());
    }
    std::set<std::string> in_row;
    for (const auto& r : s.row_options) in_row.insert(r[0]);
    for (const auto& f : o.forwarded)
        if (!in_row.count(f[0])) a.insert(a.end(), f.begin(), f.end());
    for (const auto& [name, count] : o.flags)
        if (!in_row.count(name))
            for (int k = 0; k < count; ++k) a.push_back(name);
    for (const auto& r : s.row_options) a.insert(a.end(), r.begin(), r.end());
    return a;
}

/// Starts `args` as a child of this binary with stdout and stderr going to `log`.
pid_t spawn(const std::vector<std::string>& args, const fs::path& log) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw IoError(log.string() + ": cannot create the log file (is the output folder writable?)");
    std::vector<char*> argv;
    for (const auto& s : args) argv.push_back(const_cast<char*>(s.c_str()));
    argv.push_back(nullptr);
    std::cout.flush();
    std::cerr.flush();
    const pid_t pid = ::fork();
    if (pid < 0) {
        ::close(fd);
        throw std::runtime_error("fork failed: " + std::string(std::strerror(errno)));
    }
    if (pid == 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
        ::execv("/proc/self/exe", argv.data());
        const char msg[] = "endocast: error: cannot start /proc/self/exe\n";
        (void)!::write(2, msg, sizeof msg - 1);
        ::_exit(kInternalError);
    }
    ::close(fd);
    return pid;
}

volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void on_stop_signal(int sig) { g_stop_signal = sig; }

/// On SIGINT/SIGTERM the batch stops its running children and leaves them `pending`.
void install_stop_handlers() {
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGINT, &sa, nullptr);
    ::sigaction(SIGTERM, &sa, nullptr);
}

std::string progress_line(size_t k, size_t n, const Specimen& s, bool skipped) {
    std::ostringstream out;
    out << "[" << k << "/" << n << "] " << s.name << ": ";
    if (s.status == "failed") {
        out << "FAILED " << s.error;
    } else {
        out << (skipped ? "skipped (done) " : "ok ") << fmt(s.report.value("ecv_ml", 0.0), 1) << " mL "
            << fmt(s.seconds, 1) << " s";
        if (!s.report.value("closed_manifold", true)) out << " (mesh not a closed 2-manifold)";
    }
    return out.str();
}

int run_batch(BatchOptions o, const GlobalOptions& g) {
    if (o.inputs.empty() && o.manifest.empty())
        throw InvalidParameter("batch: no specimens; give INPUTS... or --manifest FILE.csv");
    std::vector<Specimen> specimens;
    if (!o.manifest.empty()) {
        specimens = read_manifest(o);
    } else {
        for (const auto& in : o.inputs) {
            Specimen s;
            s.input = in;
            specimens.push_back(s);
        }
    }
    assign_names(specimens);
    std::error_code ec;
    fs::create_directories(o.outdir, ec);
    if (ec || !fs::is_directory(o.outdir))
        throw IoError(o.outdir + ": cannot create the output folder (" + ec.message() + ")");

    const int total_threads = std::max(1, omp_get_max_threads());
    const int child_threads = std::max(1, total_threads / std::max(1, o.jobs));
    auto log = [&](const std::string& s) {
        if (!g.quiet) std::cout << s << std::endl;
    };
    log("batch: " + std::to_string(specimens.size()) + " specimen(s) into " + o.outdir + ", " +
        std::to_string(o.jobs) + " at a time, " + std::to_string(child_threads) + " threads each");

    const size_t n = specimens.size();
    size_t finished = 0;
    std::vector<size_t> queue;
    for (size_t i = 0; i < n; ++i) {
        Specimen& s = specimens[i];
        const fs::path dir = fs::path(o.outdir) / s.name;
        if (!o.force && load_done(dir, s.report)) {
            s.status = "ok";
            s.seconds = s.report.contains("timings_s") ? s.report["timings_s"].value("total", 0.0) : 0.0;
            log(progress_line(++finished, n, s, true));
        } else {
            queue.push_back(i);
        }
    }
    write_summary(o.outdir, specimens);

    struct Running {
        size_t index;
        std::chrono::steady_clock::time_point start;
    };
    std::map<pid_t, Running> running;
    size_t next = 0;
    install_stop_handlers();
    while (next < queue.size() || !running.empty()) {
        if (g_stop_signal) {
            for (const auto& r : running) ::kill(r.first, SIGTERM);
            for (const auto& r : running) ::waitpid(r.first, nullptr, 0);
            write_summary(o.outdir, specimens);
            log("batch: interrupted by signal " + std::to_string(int(g_stop_signal)) + "; " +
                std::to_string(finished) + " of " + std::to_string(n) + " finished, the others are pending in summary.csv");
            std::cout.flush();
            std::exit(128 + int(g_stop_signal));
        }
        while (next < queue.size() && running.size() < size_t(std::max(1, o.jobs))) {
            Specimen& s = specimens[queue[next++]];
            const fs::path dir = fs::path(o.outdir) / s.name;
            fs::create_directories(dir, ec);
            if (ec) throw IoError(dir.string() + ": cannot create the specimen folder (" + ec.message() + ")");
            // A stale report from an earlier run must not mark this run done if it fails.
            fs::remove(dir / "report.json", ec);
            const pid_t pid = spawn(child_args(o, s, dir, child_threads), dir / "log.txt");
            running[pid] = {queue[next - 1], std::chrono::steady_clock::now()};
        }
        int st = 0;
        // Polled, so that a stop signal is seen at once while children run.
        const pid_t pid = ::waitpid(-1, &st, WNOHANG);
        if (pid == 0 || (pid < 0 && errno == EINTR)) {
            ::usleep(50000);
            continue;
        }
        if (pid < 0) throw std::runtime_error("waitpid failed: " + std::string(std::strerror(errno)));
        const auto it = running.find(pid);
        if (it == running.end()) continue;
        Specimen& s = specimens[it->second.index];
        s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.start).count();
        running.erase(it);
        const fs::path dir = fs::path(o.outdir) / s.name;
        if (WIFEXITED(st) && WEXITSTATUS(st) == 0 && load_done(dir, s.report)) {
            s.status = "ok";
        } else {
            s.status = "failed";
            s.report = nlohmann::json::object();
            s.error = WIFEXITED(st) && WEXITSTATUS(st) == 0 ? "exit 0 but no report.json/endocast.stl written"
                                                             : failure_message(dir / "log.txt", st);
        }
        log(progress_line(++finished, n, s, false));
        write_summary(o.outdir, specimens);
    }

    const auto failed = std::count_if(specimens.begin(), specimens.end(), [](const Specimen& s) { return s.status == "failed"; });
    log("batch: " + std::to_string(n - size_t(failed)) + " ok, " + std::to_string(failed) + " failed; wrote " +
        (fs::path(o.outdir) / "summary.csv").string());
    return failed > 0 ? kDefects : kOk;
}

/// Long names of extract's options that batch sets itself per specimen.
bool is_per_specimen_output(const CLI::Option* opt) {
    for (const auto& l : opt->get_lnames())
        if (l == "output" || l == "report" || l == "mask" || l == "qc" || l == "help") return true;
    return false;
}

}  // namespace

void setup_batch(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<BatchOptions>();
    auto* sub = app.add_subcommand(
        "batch",
        "Extract the endocasts of many scans. Each specimen gets OUTDIR/<specimen>/ with endocast.stl, "
        "report.json, log.txt (and qc.png when extract can draw one), and OUTDIR/summary.csv gets a row "
        "per specimen (specimen,input,isovalue,ecv_ml,surface_area_mm2,faces,closed_manifold,seconds,"
        "status,error,bone_contact), rewritten as each one finishes. Each specimen runs as a separate process, so a "
        "failure, crash or out-of-memory kill is recorded (status failed, with the error) and the batch "
        "goes on; the batch exits with 1 if any specimen failed (on SIGINT/SIGTERM it stops the running "
        "ones, leaves them pending and exits with 128 + signal). Specimens whose report.json records a "
        "result are skipped on a re-run (--force redoes them). Every extract option (--iso, "
        "--seed-mode, --void-radius, ...) is accepted and forwarded to each specimen.");
    sub->add_option("INPUTS", o->inputs,
                    "Scans (any input extract reads: .nrrd/.nhdr/.nii/.nii.gz/.mha/.mhd, DICOM directory or DICOMDIR, "
                    "TIFF stack folder or multi-page .tif). "
                    "The specimen name is the file or folder name without extension, made unique with _2, _3");
    sub->add_option("--manifest", o->manifest,
                    "CSV with a header row: 'input' (required; relative paths are relative to the CSV's "
                    "folder), optional 'specimen' (folder name) and any extract option by name, e.g. 'iso' "
                    "or 'seed-mode' (a per-specimen value that overrides the command line; flags take "
                    "true/false; several values separated by spaces). Quoted fields may hold commas")
        ->excludes(sub->get_option("INPUTS"));
    sub->add_option("-o,--outdir", o->outdir, "Output folder (created if needed)")->required();
    sub->add_option("-j,--jobs", o->jobs,
                    "Specimens extracted at the same time; each gets max(1, threads / jobs) threads "
                    "(threads: the global --threads, default all cores). Memory grows with jobs")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub->add_flag("--force", o->force, "Redo specimens that a previous run finished");
    sub->add_flag("--masks", o->masks, "Also write each specimen's label volume, OUTDIR/<specimen>/mask.nii.gz");

    // Mirror every option of `extract` and forward the ones given.
    const CLI::App* extract = app.get_subcommand("extract");
    for (const CLI::Option* opt : extract->get_options()) {
        if (!opt->nonpositional()) continue;
        if (is_per_specimen_output(opt)) {
            if (opt->check_lname("qc")) o->extract_has_qc = true;
            continue;
        }
        if (opt->get_lnames().empty()) continue;
        const std::string name = "--" + opt->get_lnames().front();
        const std::string desc = "[extract] " + opt->get_description();
        if (opt->get_type_size_max() == 0 || opt->get_items_expected_max() == 0) {
            o->flag_names.push_back(name);
            sub->add_flag_callback(name, [o, name] { ++o->flags[name]; }, desc);
            continue;
        }
        o->value_options.insert(name);
        sub->add_option(
               name,
               [o, name](const CLI::results_t& res) {
                   Args a{name};
                   for (const auto& r : res)
                       if (!r.empty()) a.push_back(r);
                   o->forwarded.push_back(a);
                   return true;
               },
               desc)
            ->type_name(opt->get_type_name())
            ->default_str(opt->get_default_str())  // shown in --help only; never forwarded
            ->type_size(opt->get_type_size_min(), opt->get_type_size_max())
            ->expected(opt->get_expected_min(), opt->get_expected_max())
            ->allow_extra_args(opt->get_allow_extra_args())
            ->trigger_on_parse();
    }
    // Status 1 (a specimen failed) is not an error of the batch: it ends after summary.csv is written.
    sub->callback([o, &g] { exit_unless_ok(run_batch(*o, g)); });
}

}  // namespace endocast::cli
