// Helpers of the CLI: exit codes, markup escaping, the help texts shared by subcommands.
#include <cstdlib>
#include <iostream>
#include <string>

#include "commands.h"
#include "endocast/errors.h"

namespace endocast::cli {

const char* const kSurfaceHelp =
    "iso: the isosurface at T (the paper's method); half-max: the half-maximum-height surface "
    "(Spoor et al. 1993, the standard edge criterion for CT in physical anthropology): near the "
    "cavity's boundary each voxel gets the threshold half-way between the cavity content (median CT "
    "of the cavity's core) and the local bone peak (largest CT within a few voxels), the voxels "
    "there are re-classified by it and the surface follows it, so it moves far less with --iso "
    "(T still segments the skull and is used where no bone edge is near)";

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
