// Helpers of the CLI: exit codes, markup escaping, the help texts shared by subcommands.
#include <cstdlib>
#include <iostream>
#include <string>

#include "commands.h"
#include "endocast/errors.h"

namespace endocast::cli {

void exit_unless_ok(int code) {
    if (code == kOk) return;
    std::cout.flush();
    std::exit(code);
}

std::string escape_markup(const std::string& s) {
    std::string out;
    for (char c : s) {
        switch (c) {
            case '&': out += "&amp;"; break;
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '"': out += "&quot;"; break;
            default: out += c;
        }
    }
    return out;
}

}  // namespace endocast::cli
