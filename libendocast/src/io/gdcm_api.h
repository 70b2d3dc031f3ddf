// The parts of DICOM reading that need GDCM, reached through a table of functions (internal).
//
// GDCM builds its DICOM dictionaries when its libraries are loaded: about 45 ms of every start of
// a program linked against them, whatever it reads. So the endocast binary does not link GDCM; the
// functions below live in libendocast/gdcm/gdcm_module.cpp, built twice: as the module
// libendocast_gdcm.so, which gdcm_api() loads with dlopen the first time a DICOM series is read,
// and as the static library endocast_gdcm, which programs linked against libendocast (the tests,
// the installed package's users) link in, so that gdcm_api() finds the table without loading
// anything. Both sides come from one build, so the table passes C++ types.
#pragma once

#include <itkImageIOBase.h>

#include <cstdint>
#include <string>
#include <vector>

namespace endocast {

/// A DICOM element's tag.
struct DicomTag {
    uint16_t group = 0, element = 0;
};

/// One file gdcm::Scanner read as DICOM: its path and the values of the tags asked for, in their
/// order (empty when the file has no such element).
struct ScannedDicomFile {
    std::string path;
    std::vector<std::string> values;
};

/// Raised when the table is changed: a module from another build is refused.
constexpr int kGdcmApiVersion = 1;

struct GdcmApi {
    int version;
    size_t size;  // sizeof(GdcmApi) where the table was built
    /// A new itk::GDCMImageIO.
    itk::ImageIOBase::Pointer (*new_image_io)();
    /// GDCMImageIO::GetInternalComponentType of an ImageIO from new_image_io: the type stored in
    /// the files (ImageIOBase's component type is the one after rescaling).
    itk::IOComponentEnum (*internal_component_type)(const itk::ImageIOBase& io);
    /// gdcm::Scanner over `paths` (files that are not DICOM are left out; GDCM's warnings are
    /// silenced), reading the elements `tags` of each (no pixel data).
    std::vector<ScannedDicomFile> (*scan)(const std::vector<std::string>& paths, const std::vector<DicomTag>& tags);
    /// The name GDCM gives a SOP class UID ("CT Image Storage"), or the UID itself when unknown.
    std::string (*sop_class_name)(const std::string& uid);
};

/// The table: from endocast_gdcm when the program links it, else from the module, loaded on the
/// first call from (in order) the file named by the environment variable ENDOCAST_GDCM_MODULE
/// (only there when it is set), the directory ENDOCAST_GDCM_MODULE_DIR relative to the running
/// executable's (the build tree and an installed tree alike), then the install prefix's. Throws
/// IoError naming every place tried, and what dlopen said, when none holds a module of this build.
const GdcmApi& gdcm_api();

}  // namespace endocast

/// The module's entry point (extern "C": looked up by name with dlsym).
extern "C" const endocast::GdcmApi* endocast_gdcm_api();
