// endocast: the command-line front end. See `endocast --help`.
#include <omp.h>

#include <iostream>
#include <new>
#include <nlohmann/json.hpp>
#include <string>

#include "commands.h"
#include "endocast/errors.h"
#include "endocast/volume.h"
#include "meshpost/mesh.h"

namespace endocast::cli {

const char* exit_code_help() {
    return "Exit status: 0 success; 1 inspect found defects, or batch had a failed specimen; 2 usage error; 3 unreadable or "
           "malformed input; 4 invalid parameter; 5 no result (no bone, no cavity); 6 out of "
           "memory; 7 internal error.";
}

}  // namespace endocast::cli

int main(int argc, char** argv) {
    // glibc's malloc tuned for volumes (volume.h): one arena, every block from the heap and the heap
    // kept (each new full-volume buffer was otherwise faulted in and zeroed by the kernel again:
    // headphantom 5.3 -> 4.5 s when this was first done), the heap on huge pages where they pay
    // (huge_pages_advised, measured in docs/benchmarks.md at commit 7f12c5f). Before any thread.
    endocast::tune_heap_for_volumes();
    using namespace endocast::cli;
    CLI::App app{"endocast: closed, clean endocast meshes from CT scans of skulls "
                 "(method of Michikawa et al. 2017, PLoS ONE 12(4) e0168516).\n"
                 "Lengths are in millimetres; isovalues in the scan's own units (HU for DICOM)."};
    app.footer(exit_code_help());
    app.require_subcommand(1);
    app.fallthrough();  // global options may follow the subcommand
    GlobalOptions g;
    app.add_option("--threads", g.threads, "Worker threads (0 = all cores); results are identical for any count")
        ->check(CLI::NonNegativeNumber);
    app.add_flag("-q,--quiet", g.quiet, "No progress or summary on stderr/stdout");
    app.add_flag("--log-json", g.log_json,
                 "Progress as JSON lines on stderr (extract): {\"event\":\"stage\",\"stage\":NAME,"
                 "\"index\":K,\"of\":N,\"elapsed_s\":S} per stage, \"info\"/\"warning\" events and a final "
                 "{\"event\":\"done\",...} (or {\"event\":\"error\",\"exit_code\":N,\"message\":...}); replaces the progress "
                 "bar/lines, even with --quiet");
    setup_extract(app, g);
    setup_phantom(app, g);
    setup_inspect(app, g);
    setup_simplify(app, g);
    setup_compare(app, g);
    setup_robustness(app, g);
    setup_series(app, g);
    setup_batch(app, g);    // after setup_extract: forwards its options
    setup_slicer_xml(app);  // after setup_extract: describes its options
    app.parse_complete_callback([&] {
        if (g.threads > 0) omp_set_num_threads(g.threads);
    });
    // An error on stderr: text, or with --log-json {"event":"error","exit_code":N,"message":...}.
    auto fail = [&g](int code, const std::string& text) {
        if (g.log_json)
            std::cerr << nlohmann::json{{"event", "error"}, {"exit_code", code}, {"message", text}}.dump() << std::endl;
        else
            std::cerr << "endocast: " << (code == kInternalError ? "internal error: " : "error: ") << text << "\n";
        return code;
    };
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::Success&) {  // --xml printed the Slicer description
        return kOk;
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return kUsage;
    } catch (const endocast::IoError& e) {
        return fail(kInputError, e.what());
    } catch (const meshpost::MeshIoError& e) {
        return fail(kInputError, e.what());
    } catch (const endocast::InvalidParameter& e) {
        return fail(kInvalidParameter, e.what());
    } catch (const endocast::NoResult& e) {
        return fail(kNoResult, e.what());
    } catch (const endocast::OutOfMemory& e) {
        return fail(kOutOfMemory, e.what());
    } catch (const std::bad_alloc&) {
        return fail(kOutOfMemory, "out of memory (try extract --crop or --downsample)");
    } catch (const std::exception& e) {
        return fail(kInternalError, e.what());
    }
    return kOk;
}
