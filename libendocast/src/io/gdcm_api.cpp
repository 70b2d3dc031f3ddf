// Finds the table of GDCM functions (gdcm_api.h): linked in, or the module loaded with dlopen.
#include "io/gdcm_api.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "endocast/errors.h"

// Where the module lies relative to the running executable's directory, and the install tree's
// module directory (set by libendocast/CMakeLists.txt).
#ifndef ENDOCAST_GDCM_MODULE_DIR
#define ENDOCAST_GDCM_MODULE_DIR "../lib/endocast"
#endif
#ifndef ENDOCAST_GDCM_MODULE_INSTALL_DIR
#define ENDOCAST_GDCM_MODULE_INSTALL_DIR ""
#endif

// Defined when the program links endocast_gdcm; null in the endocast binary, which does not.
extern "C" const endocast::GdcmApi* endocast_gdcm_api() __attribute__((weak));

namespace endocast {
namespace {

namespace fs = std::filesystem;

constexpr const char* kModuleName = "libendocast_gdcm.so";

// The module at `path`, or null with why in `why`. A module found is kept loaded for the
// process' life (its objects' code must outlive them).
const GdcmApi* open_module(const std::string& path, std::string& why) {
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char* e = dlerror();
        why = e ? e : "cannot be loaded";
        return nullptr;
    }
    using Entry = const GdcmApi* (*)();
    const auto entry = reinterpret_cast<Entry>(dlsym(handle, "endocast_gdcm_api"));
    const GdcmApi* api = entry ? entry() : nullptr;
    if (!api || api->version != kGdcmApiVersion || api->size != sizeof(GdcmApi)) {
        why = "not a GDCM module of this endocast build (" +
              (api ? "table version " + std::to_string(api->version) + " of " + std::to_string(api->size) +
                         " bytes, expected version " + std::to_string(kGdcmApiVersion) + " of " +
                         std::to_string(sizeof(GdcmApi)) + " bytes"
                   : std::string("no endocast_gdcm_api table")) +
              ")";
        dlclose(handle);
        return nullptr;
    }
    return api;
}

const GdcmApi* load() {
    if (endocast_gdcm_api) return endocast_gdcm_api();
    std::vector<std::string> places;
    if (const char* env = std::getenv("ENDOCAST_GDCM_MODULE"); env && *env) {
        places.push_back(env);
    } else {
        std::error_code ec;
        const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
        if (!ec) places.push_back((exe.parent_path() / ENDOCAST_GDCM_MODULE_DIR / kModuleName).lexically_normal().string());
        if (*ENDOCAST_GDCM_MODULE_INSTALL_DIR)
            places.push_back((fs::path(ENDOCAST_GDCM_MODULE_INSTALL_DIR) / kModuleName).string());
    }
    std::string tried;
    for (const std::string& p : places) {
        std::string why;
        if (const GdcmApi* api = open_module(p, why)) return api;
        // dlerror's message names the file; the version check's does not.
        tried += (tried.empty() ? "" : "; ") + (why.find(p) == std::string::npos ? p + ": " + why : why);
    }
    throw IoError("reading DICOM needs endocast's GDCM module (" + std::string(kModuleName) +
                  "), which could not be loaded: " + (tried.empty() ? "no place to look" : tried) +
                  " (set ENDOCAST_GDCM_MODULE to the module's path, or reinstall endocast)");
}

}  // namespace

const GdcmApi& gdcm_api() {
    static std::mutex m;
    static const GdcmApi* api = nullptr;
    std::lock_guard<std::mutex> lock(m);
    if (!api) api = load();  // a failure is not remembered: the next call tries again
    return *api;
}

}  // namespace endocast
