// The smallest program on the endocast library: extract the endocast of a CT volume (or of a
// generated phantom skull) and print its volume.
//
//   endocast_minimal [CT.nrrd [ISOVALUE]]
//
// Without arguments it generates a small phantom (2 mm voxels) whose true volume is known.
#include <cstdlib>
#include <exception>
#include <iostream>
#include <stdexcept>
#include <string>

#include <endocast/io.h>
#include <endocast/phantom.h>
#include <endocast/pipeline.h>

int main(int argc, char** argv) {
    try {
        endocast::Volume<float> ct;
        endocast::ExtractParams params;  // the defaults of `endocast extract`
        double true_ecv_ml = 0;
        if (argc > 1) {
            ct = endocast::read_volume({argv[1]}).volume;
            if (argc > 2) {
                char* end = nullptr;
                params.binarize.isovalue = std::strtod(argv[2], &end);
                if (end == argv[2] || *end) throw std::invalid_argument(std::string("ISOVALUE '") + argv[2] + "' is not a number");
            }
        } else {
            endocast::PhantomParams pp;
            pp.spacing = {2.0, 2.0, 2.0};
            const endocast::PhantomResult phantom = endocast::generate_phantom(pp);
            ct = endocast::Volume<float>(phantom.ct.geometry());
            for (size_t i = 0; i < ct.size(); ++i) ct[i] = phantom.ct[i];
            true_ecv_ml = phantom.true_ecv_ml;
        }
        const endocast::ExtractionResult r = endocast::extract_endocast(ct, params);
        std::cout << "isovalue " << r.params.isovalue << "\n";
        std::cout << "ECV " << r.ecv_ml << " mL, " << r.mesh.faces.size() << " faces\n";
        if (true_ecv_ml > 0) std::cout << "true ECV " << true_ecv_ml << " mL\n";
        for (const std::string& w : r.warnings) std::cerr << "warning: " << w << "\n";
        return EXIT_SUCCESS;
    } catch (const std::exception& e) {
        std::cerr << "endocast_minimal: " << e.what() << "\n";
        return EXIT_FAILURE;
    }
}
