// The architecture's rules, read from the sources: libendocast/src/kernels (EDT, morphology,
// components, watershed, marching cubes) include no reader, no ITK/GDCM and no CGAL; nothing in
// libendocast includes CGAL (GPL: it lives in libmeshpost/cgal, its own target); the libraries
// know nothing of the command line.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct Include {
    std::string file, header;
};

std::vector<Include> includes_under(const fs::path& dir) {
    std::vector<Include> out;
    const std::regex inc(R"(^\s*#\s*include\s*[<"]([^>"]+)[>"])");
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (!e.is_regular_file()) continue;
        const std::string ext = e.path().extension().string();
        if (ext != ".cpp" && ext != ".h") continue;
        std::ifstream f(e.path());
        std::string line;
        std::smatch m;
        while (std::getline(f, line))
            if (std::regex_search(line, m, inc)) out.push_back({e.path().string(), m[1]});
    }
    return out;
}

bool starts(const std::string& s, const std::string& p) { return s.compare(0, p.size(), p) == 0; }

const fs::path kRoot = ENDOCAST_SOURCE_DIR;

}  // namespace

TEST(Layering, KernelsIncludeNoReaderItkGdcmOrCgal) {
    const auto incs = includes_under(kRoot / "libendocast/src/kernels");
    ASSERT_FALSE(incs.empty());
    for (const Include& i : incs) {
        const std::string& h = i.header;
        EXPECT_FALSE(starts(h, "CGAL/") || starts(h, "itk") || starts(h, "gdcm") || h == "endocast/io.h" ||
                     h.find("io_internal.h") != std::string::npos || starts(h, "io/") || starts(h, "meshpost/cgal") ||
                     starts(h, "method/") || starts(h, "phantom/"))
            << i.file << " includes " << h;
    }
}

TEST(Layering, NoCgalOutsideItsTargetAndNoCommandLineInTheLibraries) {
    for (const char* lib : {"libendocast", "libmeshpost/src", "libmeshpost/include"}) {
        for (const Include& i : includes_under(kRoot / lib)) {
            if (i.file.find("/cgal/") != std::string::npos) continue;  // libmeshpost's GPL target
            EXPECT_FALSE(starts(i.header, "CGAL/")) << i.file << " includes " << i.header;
            EXPECT_FALSE(starts(i.header, "CLI/")) << i.file << " includes " << i.header;
            EXPECT_FALSE(i.header.find("apps/") != std::string::npos) << i.file << " includes " << i.header;
        }
    }
}

TEST(Layering, LibendocastSourcesLiveInTheirRooms) {
    // Every source file of libendocast is in io/, kernels/, method/ or phantom/ (none at the top).
    for (const auto& e : fs::directory_iterator(kRoot / "libendocast/src"))
        EXPECT_TRUE(e.is_directory()) << e.path() << " lies in libendocast/src itself";
}

TEST(Layering, CgalHeadersSayWhichTargetToLink) {
    // The headers of meshpost_cgal (GPL) are include/meshpost/cgal/*.h, one per source in
    // libmeshpost/cgal/; the permissive libraries include none of them.
    for (const auto& e : fs::directory_iterator(kRoot / "libmeshpost/cgal")) {
        const std::string stem = e.path().stem().string();
        if (e.path().extension() != ".cpp" || stem == "cgal_anchor") continue;
        EXPECT_TRUE(fs::exists(kRoot / "libmeshpost/include/meshpost/cgal" / (stem + ".h"))) << e.path();
    }
    for (const char* lib : {"libendocast", "libmeshpost/src"})
        for (const Include& i : includes_under(kRoot / lib))
            EXPECT_FALSE(starts(i.header, "meshpost/cgal/")) << i.file << " includes " << i.header;
}

TEST(Layering, GdcmOnlyInItsModule) {
    // GDCM builds its dictionaries when its libraries load (~45 ms of a start): only
    // libendocast/gdcm (the module the binary loads on its first DICOM input, io/gdcm_api.h)
    // includes GDCM or ITK's GDCM reader.
    for (const Include& i : includes_under(kRoot / "libendocast")) {
        if (i.file.find("/libendocast/gdcm/") != std::string::npos) continue;
        EXPECT_FALSE(starts(i.header, "gdcm") || starts(i.header, "itkGDCM")) << i.file << " includes " << i.header;
    }
}
