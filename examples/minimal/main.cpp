// The smallest program on the endocast library: extract the endocast of a CT (or of a generated
// phantom skull) with endocast::extract, the whole of `endocast extract`, and print its volume.
//
//   endocast_minimal [CT [ISOVALUE]]     CT: a file or DICOM folder, as the CLI reads them
//
// Without arguments it generates a small phantom (2 mm voxels) whose true volume is known.
#include <cstdlib>
#include <exception>
#include <iostream>
#include <stdexcept>
#include <string>

#include <endocast/endocast.h>
#include <endocast/phantom.h>

int main(int argc, char** argv) {
    try {
        endocast::Options options;  // the defaults of `endocast extract`
        endocast::Source source;
        endocast::PhantomResult phantom;
        if (argc > 1) {
            source.paths = {argv[1]};
            if (argc > 2) {
                char* end = nullptr;
                options.method.binarize.isovalue = std::strtod(argv[2], &end);
                if (end == argv[2] || *end) throw std::invalid_argument(std::string("ISOVALUE '") + argv[2] + "' is not a number");
            }
        } else {
            endocast::PhantomParams pp;
            pp.spacing = {2.0, 2.0, 2.0};
            phantom = endocast::generate_phantom(pp);
            source.volume16 = &phantom.ct;
            source.name = "phantom";
        }
        const endocast::Result r = endocast::extract(source, options);
        std::cout << "isovalue " << r.method.params.isovalue << "\n";
        std::cout << "ECV " << r.ecv_ml() << " mL, " << r.mesh().faces.size() << " faces, closed 2-manifold "
                  << (r.closed_manifold() ? "yes" : "no") << "\n";
        if (phantom.true_ecv_ml > 0) std::cout << "true ECV " << phantom.true_ecv_ml << " mL\n";
        for (const endocast::Warning& w : r.method.warnings) std::cerr << "warning (" << w.code << "): " << w.message << "\n";
        return EXIT_SUCCESS;
    } catch (const std::exception& e) {
        std::cerr << "endocast_minimal: " << e.what() << "\n";
        return EXIT_FAILURE;
    }
}
