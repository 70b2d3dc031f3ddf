// The DICOM functions that need GDCM (io/gdcm_api.h): built as the module libendocast_gdcm.so,
// which the endocast binary loads on its first DICOM input, and as the static library
// endocast_gdcm for programs that link libendocast.
#include <gdcmScanner.h>
#include <gdcmTag.h>
#include <gdcmTrace.h>
#include <gdcmUIDs.h>
#include <itkGDCMImageIO.h>

#include "io/gdcm_api.h"

namespace endocast {
namespace {

itk::ImageIOBase::Pointer new_image_io() { return itk::GDCMImageIO::New().GetPointer(); }

itk::IOComponentEnum internal_component_type(const itk::ImageIOBase& io) {
    return static_cast<const itk::GDCMImageIO&>(io).GetInternalComponentType();
}

std::vector<ScannedDicomFile> scan(const std::vector<std::string>& paths, const std::vector<DicomTag>& tags) {
    // GDCM would print a line on stderr for every file that is not DICOM.
    gdcm::Trace::WarningOff();
    gdcm::Trace::ErrorOff();
    gdcm::Scanner scanner;
    std::vector<gdcm::Tag> keys;
    for (const DicomTag& t : tags) keys.emplace_back(t.group, t.element);
    for (const gdcm::Tag& k : keys) scanner.AddTag(k);
    scanner.Scan(paths);
    std::vector<ScannedDicomFile> files;
    for (const std::string& path : paths) {
        if (!scanner.IsKey(path.c_str())) continue;
        ScannedDicomFile f;
        f.path = path;
        f.values.resize(keys.size());
        for (size_t i = 0; i < keys.size(); ++i)
            if (const char* v = scanner.GetValue(path.c_str(), keys[i])) f.values[i] = v;
        files.push_back(std::move(f));
    }
    return files;
}

std::string sop_class_name(const std::string& uid) {
    if (uid.empty()) return "";
    gdcm::UIDs u;
    if (u.SetFromUID(uid.c_str()) && u.GetName() && *u.GetName()) return u.GetName();
    return uid;
}

const GdcmApi kApi{kGdcmApiVersion, sizeof(GdcmApi), new_image_io, internal_component_type, scan, sop_class_name};

}  // namespace
}  // namespace endocast

extern "C" __attribute__((visibility("default"))) const endocast::GdcmApi* endocast_gdcm_api() {
    return &endocast::kApi;
}
