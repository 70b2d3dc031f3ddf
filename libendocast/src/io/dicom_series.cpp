// The DICOM series of a study folder and the choice of the one to read (dicom_series.h).
//
// The headers are read with gdcm::Scanner (through gdcm_api.h: GDCM is loaded on the first use),
// which parses each file only up to the last tag asked for (PixelSpacing, group 0028): no pixel
// data is read, so a study of thousands of files is listed in about the time it takes to open them.
// Files are grouped by SeriesInstanceUID alone (as ITK's GDCMSeriesFileNames with
// SetUseSeriesDetails(false), which read_dicom_dir used before) and ordered as
// gdcm::SerieHelper::OrderFileList orders them, so that a folder holding one series gives the same
// files in the same order, hence the same volume, as before.
#include "endocast/dicom_series.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <system_error>

#include "endocast/errors.h"
#include "io/gdcm_api.h"
#include "meshpost/text.h"

namespace endocast {
namespace {

using meshpost::text::lower;
using meshpost::text::trim;
using meshpost::text::upper;

namespace fs = std::filesystem;

const char* const kCtImage = "1.2.840.10008.5.1.4.1.1.2";
const char* const kMrImage = "1.2.840.10008.5.1.4.1.1.4";

/// A UID as GDCMSeriesFileNames names a series: only '.', letters and digits kept.
std::string clean_uid(const std::string& s) {
    std::string out;
    for (char c : s)
        if (c == '.' || std::isalnum(static_cast<unsigned char>(c))) out += c;
    return out;
}

/// The numbers of a DS/IS value "a\b\c"; stops at the first that does not parse.
std::vector<double> numbers(const char* v) {
    std::vector<double> out;
    if (!v) return out;
    std::string s(v);
    std::replace(s.begin(), s.end(), '\\', ' ');
    std::istringstream is(s);
    double x;
    while (is >> x) out.push_back(x);
    return out;
}

/// One file's header, as the scanner read it.
struct FileHeader {
    std::string path;
    std::string values[14];  // by the order of kTags below
};

// The header elements read from every file, in the order of Field.
const std::vector<DicomTag> kTags = {
    {0x0008, 0x0008},  // ImageType
    {0x0008, 0x0016},  // SOPClassUID
    {0x0008, 0x0060},  // Modality
    {0x0008, 0x103E},  // SeriesDescription
    {0x0018, 0x0050},  // SliceThickness
    {0x0018, 0x1210},  // ConvolutionKernel
    {0x0020, 0x000E},  // SeriesInstanceUID
    {0x0020, 0x0011},  // SeriesNumber
    {0x0020, 0x0013},  // InstanceNumber
    {0x0020, 0x0032},  // ImagePositionPatient
    {0x0020, 0x0037},  // ImageOrientationPatient
    {0x0028, 0x0010},  // Rows
    {0x0028, 0x0011},  // Columns
    {0x0028, 0x0030},  // PixelSpacing
};
enum Field { ImageType, SopClass, Modality, Description, Thickness, Kernel, SeriesUid, SeriesNumber,
             InstanceNumber, Position, Orientation, Rows, Columns, PixelSpacing };

/// The files of one series in the order gdcm::SerieHelper::OrderFileList gives them (no user
/// ordering, DirectOrder): by the distance of ImagePositionPatient along the slice normal of the
/// first file (in path order), ascending, when no two are equal and they are not all equal; else
/// by InstanceNumber when those are distinct; else by path. Returns the sorted distances (empty
/// when the positions were not used).
std::vector<double> order_files(std::vector<const FileHeader*>& files) {
    std::vector<double> cos = numbers(files.front()->values[Orientation].c_str());
    if (cos.size() != 6) cos = {1, 0, 0, 0, 1, 0};  // ImageHelper's default
    const double n[3] = {cos[1] * cos[5] - cos[2] * cos[4], cos[2] * cos[3] - cos[0] * cos[5],
                         cos[0] * cos[4] - cos[1] * cos[3]};
    std::vector<std::pair<double, const FileHeader*>> dist;
    for (const FileHeader* f : files) {
        std::vector<double> p = numbers(f->values[Position].c_str());
        if (p.size() != 3) p = {0, 0, 0};  // ImageHelper's default
        double d = 0;
        for (int i = 0; i < 3; ++i) d += n[i] * p[i];
        dist.emplace_back(d, f);
    }
    std::stable_sort(dist.begin(), dist.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    bool unique = dist.front().first != dist.back().first;
    for (size_t i = 1; i < dist.size() && unique; ++i) unique = dist[i].first != dist[i - 1].first;
    if (unique || files.size() == 1) {
        std::vector<double> out;
        for (size_t i = 0; i < dist.size(); ++i) {
            files[i] = dist[i].second;
            out.push_back(dist[i].first);
        }
        return out;
    }
    std::set<long> instances;
    for (const FileHeader* f : files) {
        const std::vector<double> v = numbers(f->values[InstanceNumber].c_str());
        instances.insert(v.empty() ? -1 : long(v[0]));
    }
    auto instance = [](const FileHeader* f) {
        const std::vector<double> v = numbers(f->values[InstanceNumber].c_str());
        return v.empty() ? -1L : long(v[0]);
    };
    if (instances.size() == files.size())
        std::sort(files.begin(), files.end(),
                  [&](const FileHeader* a, const FileHeader* b) { return instance(a) < instance(b); });
    else
        std::sort(files.begin(), files.end(),
                  [](const FileHeader* a, const FileHeader* b) { return a->path < b->path; });
    return {};
}

bool has_token(const std::string& image_type, const char* token) {
    std::istringstream is(upper(image_type));
    std::string t;
    while (std::getline(is, t, '\\'))
        if (trim(t) == token) return true;
    return false;
}

std::string num(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

/// Fills the series' header fields, slice step and volume verdict from its ordered files.
DicomSeriesInfo describe_series(const std::string& uid, std::vector<const FileHeader*> files) {
    const std::vector<double> dist = order_files(files);
    const FileHeader& h = *files.front();
    DicomSeriesInfo s;
    s.series_uid = uid;
    s.description = trim(h.values[Description]);
    s.modality = trim(h.values[Modality]);
    s.sop_class_uid = clean_uid(h.values[SopClass]);
    s.sop_class = gdcm_api().sop_class_name(s.sop_class_uid);
    s.image_type = trim(h.values[ImageType]);
    s.kernel = trim(h.values[Kernel]);
    if (const auto v = numbers(h.values[SeriesNumber].c_str()); !v.empty()) s.series_number = int(v[0]);
    if (const auto v = numbers(h.values[Rows].c_str()); !v.empty()) s.rows = int(v[0]);
    if (const auto v = numbers(h.values[Columns].c_str()); !v.empty()) s.columns = int(v[0]);
    if (const auto v = numbers(h.values[PixelSpacing].c_str()); v.size() == 2) s.pixel_spacing_mm = {v[0], v[1]};
    if (const auto v = numbers(h.values[Thickness].c_str()); !v.empty()) s.slice_thickness_mm = v[0];
    if (dist.size() >= 2) {
        std::vector<double> steps;
        for (size_t i = 1; i < dist.size(); ++i) steps.push_back(std::abs(dist[i] - dist[i - 1]));
        std::nth_element(steps.begin(), steps.begin() + long(steps.size() / 2), steps.end());
        s.slice_step_mm = steps[steps.size() / 2];
    }
    std::set<std::string> folders;
    for (const FileHeader* f : files) {
        s.files.push_back(f->path);
        folders.insert(fs::path(f->path).parent_path().string());
    }
    s.folders.assign(folders.begin(), folders.end());

    // The verdict, the most telling reason first.
    const std::string sop = s.sop_class_uid;
    const std::string modality = upper(s.modality);
    const std::string size = std::to_string(s.columns) + " x " + std::to_string(s.rows);
    std::string odd;  // the first file of another size
    for (const FileHeader* f : files)
        if (trim(f->values[Rows]) != trim(h.values[Rows]) || trim(f->values[Columns]) != trim(h.values[Columns])) {
            odd = "slice " + fs::path(f->path).filename().string() + " is " + trim(f->values[Columns]) + " x " +
                  trim(f->values[Rows]) + " pixels, expected " + size + " like " +
                  fs::path(h.path).filename().string() + ": a series must hold slices of one size";
            break;
        }
    if (!sop.empty() && sop != kCtImage && sop != kMrImage)
        s.reason = s.sop_class + (s.sop_class == sop ? "" : " (SOP class " + sop + ")") +
                   ", not CT or MR image storage";
    else if (modality == "SR" || modality == "OT" || modality == "DOC" || modality == "KO" || modality == "PR")
        s.reason = "modality " + s.modality + ", not an image of the patient (a report or screenshot)";
    else if (has_token(s.image_type, "LOCALIZER") || has_token(s.image_type, "SCOUT"))
        s.reason = "localizer (ImageType " + s.image_type + ")";
    else if (!odd.empty())
        s.reason = odd;
    else if (files.size() == 1)
        s.reason = "a single image";
    else if (files.size() < 3)
        s.reason = std::to_string(files.size()) + " images, fewer than the 3 slices of a volume";
    s.is_volume = s.reason.empty();
    return s;
}

/// Thickness used to compare series: SliceThickness, else the slice step.
double thickness(const DicomSeriesInfo& s) {
    return s.slice_thickness_mm > 0 ? s.slice_thickness_mm : s.slice_step_mm;
}

/// "UID (description)" or "UID" for lists.
std::string label(const DicomSeriesInfo& s) {
    return s.description.empty() ? s.series_uid : s.series_uid + " (" + s.description + ")";
}

std::string list_all(const DicomStudy& study) {
    std::string out;
    for (const auto& s : study.series) {
        if (!out.empty()) out += "; ";
        out += describe_dicom_series(s);
        if (!s.is_volume) out += ": not a volume, " + s.reason;
    }
    return out;
}

}  // namespace

bool is_dicomdir_path(const std::string& path) {
    return lower(fs::path(path).filename().string()) == "dicomdir";
}

std::string describe_dicom_series(const DicomSeriesInfo& s) {
    std::ostringstream o;
    o << s.series_uid << " (";
    if (!s.description.empty()) o << "'" << s.description << "', ";
    o << (s.modality.empty() ? "no modality" : s.modality) << ", " << s.files.size()
      << (s.files.size() == 1 ? " file" : " files");
    if (thickness(s) > 0) o << " of " << num(thickness(s)) << " mm";
    if (!s.kernel.empty()) o << ", kernel " << s.kernel;
    o << ")";
    return o.str();
}

DicomStudy list_dicom_series(const std::string& path) {
    DicomStudy study;
    study.path = path;
    std::error_code ec;
    const auto st = fs::status(path, ec);
    if (!fs::exists(st)) throw IoError(path + ": no such file or directory");
    if (fs::is_directory(st)) {
        study.folder = path;
    } else if (is_dicomdir_path(path)) {
        const fs::path parent = fs::path(path).parent_path();
        study.folder = parent.empty() ? "." : parent.string();
    } else {
        throw IoError(path + ": neither a folder nor a DICOMDIR file, expected a folder holding "
                             "DICOM files or a DICOMDIR");
    }

    std::vector<std::string> names;
    try {
        // Linked folders are followed (a study gathered with symbolic links), each real folder once
        // (a link back up would loop).
        std::set<fs::path> seen;
        {
            std::error_code ce;
            seen.insert(fs::canonical(study.folder, ce));
        }
        const auto opts = fs::directory_options::skip_permission_denied | fs::directory_options::follow_directory_symlink;
        for (fs::recursive_directory_iterator it(study.folder, opts, ec), end; !ec && it != end; it.increment(ec)) {
            std::error_code fe;
            if (it->is_directory(fe)) {
                const fs::path real = fs::canonical(it->path(), fe);
                if (fe || !seen.insert(real).second) it.disable_recursion_pending();
                continue;
            }
            if (it->is_regular_file(fe)) names.push_back(it->path().string());
        }
    } catch (const fs::filesystem_error& e) {
        throw IoError(study.folder + ": cannot search for DICOM files: " + e.what());
    }
    if (ec) throw IoError(study.folder + ": cannot search for DICOM files: " + ec.message());
    std::sort(names.begin(), names.end());
    study.files_scanned = names.size();

    std::vector<FileHeader> headers;
    headers.reserve(names.size());
    std::vector<ScannedDicomFile> scanned;
    if (!names.empty()) scanned = gdcm_api().scan(names, kTags);  // an empty folder needs no GDCM
    for (ScannedDicomFile& f : scanned) {
        FileHeader h;
        h.path = std::move(f.path);
        for (size_t i = 0; i < 14; ++i) h.values[i] = std::move(f.values[i]);
        h.values[SeriesUid] = clean_uid(h.values[SeriesUid]);
        if (h.values[SeriesUid].empty()) continue;
        headers.push_back(std::move(h));
    }
    study.files_skipped = names.size() - headers.size();

    std::map<std::string, std::vector<const FileHeader*>> by_uid;  // sorted by UID
    for (const FileHeader& h : headers) by_uid[h.values[SeriesUid]].push_back(&h);
    for (auto& [uid, files] : by_uid) study.series.push_back(describe_series(uid, files));
    return study;
}

DicomSeriesPick choose_dicom_series(const DicomStudy& study, const DicomSeriesChoice& choice) {
    const std::string& where = study.path;
    const auto& all = study.series;
    if (all.empty())
        throw IoError(where + ": directory holds no DICOM series, expected DICOM files (or give a "
                              "volume file, or raw options)");
    std::vector<size_t> candidates;
    for (size_t i = 0; i < all.size(); ++i)
        if (choice.series_uid.empty() || all[i].series_uid == choice.series_uid) candidates.push_back(i);
    if (candidates.empty())
        throw InvalidParameter(where + ": no DICOM series with SeriesInstanceUID " + choice.series_uid +
                               "; the folder holds " + list_all(study));

    if (!choice.description.empty()) {
        const std::string want = lower(choice.description);
        // Among the volumes first, then among all; an exact match wins over a partial one.
        std::vector<size_t> match;
        for (bool volumes_only : {true, false}) {
            std::vector<size_t> exact, partial;
            for (size_t i : candidates) {
                if (volumes_only && !all[i].is_volume) continue;
                const std::string d = lower(all[i].description);
                if (d == want) exact.push_back(i);
                else if (d.find(want) != std::string::npos) partial.push_back(i);
            }
            match = !exact.empty() ? exact : partial;
            if (!match.empty()) break;
        }
        if (match.empty())
            throw InvalidParameter(where + ": no DICOM series" +
                                   (choice.series_uid.empty() ? "" : " " + choice.series_uid) +
                                   " with a SeriesDescription containing '" + choice.description +
                                   "'; the folder holds " + list_all(study));
        if (match.size() > 1) {
            std::string names;
            for (size_t i : match) names += (names.empty() ? "" : "; ") + describe_dicom_series(all[i]);
            throw InvalidParameter(where + ": the series description '" + choice.description + "' matches " +
                                   std::to_string(match.size()) + " DICOM series: " + names +
                                   "; expected one: give more of the description or the SeriesInstanceUID");
        }
        candidates = match;
    }

    if (!choice.series_uid.empty() || !choice.description.empty()) {
        const DicomSeriesInfo& s = all[candidates.front()];
        if (!s.is_volume) {
            std::string volumes;
            for (const auto& v : all)
                if (v.is_volume) volumes += (volumes.empty() ? "" : "; ") + describe_dicom_series(v);
            throw InvalidParameter(where + ": DICOM series " + describe_dicom_series(s) + " is not a volume: " +
                                   s.reason + "; expected a CT or MR volume" +
                                   (volumes.empty() ? std::string(" (the folder holds none)")
                                                    : "; the volumes are " + volumes));
        }
        return {candidates.front(), ""};
    }

    // The default rule: CT first, then the thinnest slices, then the most slices, then the UID.
    std::vector<size_t> volumes;
    for (size_t i = 0; i < all.size(); ++i)
        if (all[i].is_volume) volumes.push_back(i);
    if (volumes.empty())
        throw IoError(where + ": holds no DICOM volume, only " + list_all(study) +
                      "; expected a series of CT or MR slices");
    const bool any_ct = std::any_of(volumes.begin(), volumes.end(),
                                    [&](size_t i) { return upper(all[i].modality) == "CT"; });
    auto better = [&](size_t a, size_t b) {  // a before b
        const DicomSeriesInfo &x = all[a], &y = all[b];
        if (any_ct) {
            const bool cx = upper(x.modality) == "CT", cy = upper(y.modality) == "CT";
            if (cx != cy) return cx;
        }
        const double tx = thickness(x) > 0 ? thickness(x) : 1e300, ty = thickness(y) > 0 ? thickness(y) : 1e300;
        if (std::abs(tx - ty) > 1e-3) return tx < ty;
        if (x.files.size() != y.files.size()) return x.files.size() > y.files.size();
        return x.series_uid < y.series_uid;
    };
    std::stable_sort(volumes.begin(), volumes.end(), better);
    DicomSeriesPick pick;
    pick.index = volumes.front();
    if (all.size() == 1) return pick;

    const DicomSeriesInfo& c = all[pick.index];
    std::ostringstream w;
    w << where << ": holds " << all.size() << " DICOM series; read " << describe_dicom_series(c) << ", the "
      << (any_ct ? "CT " : "") << "volume with the thinnest slices, then the most; not read: ";
    bool first = true;
    for (size_t i = 0; i < all.size(); ++i) {
        if (i == pick.index) continue;
        const DicomSeriesInfo& s = all[i];
        w << (first ? "" : "; ") << label(s) << ": ";
        first = false;
        if (!s.is_volume) w << "not a volume, " << s.reason;
        else if (any_ct && upper(s.modality) != "CT") w << "modality " << s.modality << ", not CT";
        else if (std::abs(thickness(s) - thickness(c)) > 1e-3 || thickness(s) <= 0)
            w << (thickness(s) > 0 ? "slices of " + num(thickness(s)) + " mm" : std::string("slice thickness unknown"));
        else if (s.files.size() != c.files.size()) w << "fewer slices (" << s.files.size() << ")";
        else w << "as thin, as many slices, a later UID";
    }
    w << "; to read another, choose it by SeriesInstanceUID or description";
    pick.warning = w.str();
    return pick;
}

}  // namespace endocast
