#pragma once
// Runs the `endocast` binary and reads what it wrote.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace cli_test {

namespace fs = std::filesystem;

struct CliRun {
    int status = -1;
    std::string output;  ///< run(): stdout and stderr together; run_shell(): what the command wrote on stdout
};

/// Runs a shell command line; `output` is what it wrote on stdout.
inline CliRun run_shell(const std::string& cmd) {
    CliRun r;
    FILE* p = popen(cmd.c_str(), "r");
    if (!p) return r;
    std::array<char, 4096> buf{};
    size_t n;
    while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
    const int st = pclose(p);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return r;
}

/// Runs `endocast ARGS`; `output` holds stdout and stderr together.
inline CliRun run(const std::string& args) {
    return run_shell(std::string(ENDOCAST_CLI) + " " + args + " 2>&1");
}

inline nlohmann::json read_json(const fs::path& p) {
    std::ifstream in(p);
    return nlohmann::json::parse(in);
}

/// A fresh directory under the test temp dir, private to this process (ctest runs tests in
/// parallel processes).
inline fs::path temp_dir(const std::string& name) {
    const fs::path d = fs::path(::testing::TempDir()) /
                       ("endocast_cli_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

inline std::string shared(const std::string& rel) {
    return std::string(ENDOCAST_SHARED_DATA) + "/" + rel;
}

}  // namespace cli_test
