// TIFF volumes (tiff.h): slice folders, patterns and multi-page files read with libtiff, their
// voxel size from ImageJ's or the standard resolution tags; and volumes written as TIFF.
#include "endocast/tiff.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <tiffio.h>

#include "io_internal.h"
#include "meshpost/text.h"

namespace endocast {
namespace {

namespace fs = std::filesystem;

using meshpost::text::lower;

std::string num(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

/// An open TIFF with the first error libtiff reported on it (libtiff's own handlers print to
/// stderr; these keep the message for our exception and stay quiet about warnings).
struct Tiff {
    std::string path;
    std::string error;
    TIFF* tif = nullptr;
    Tiff() = default;
    Tiff(const Tiff&) = delete;
    Tiff& operator=(const Tiff&) = delete;
    ~Tiff() {
        if (tif) TIFFClose(tif);
    }
    /// "libtiff: <message>" or "" when libtiff said nothing.
    std::string why() const { return error.empty() ? std::string() : ": " + error; }
};

int keep_error(TIFF*, void* user, const char* module, const char* fmt, va_list ap) {
    auto* t = static_cast<Tiff*>(user);
    if (t->error.empty()) {
        char buf[512];
        std::vsnprintf(buf, sizeof buf, fmt, ap);
        t->error = std::string(module ? module : "libtiff") + ": " + buf;
    }
    return 1;
}

int ignore_warning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

std::unique_ptr<Tiff> open_tiff(const std::string& path, const char* mode) {
    auto t = std::make_unique<Tiff>();
    t->path = path;
    TIFFOpenOptions* o = TIFFOpenOptionsAlloc();
    TIFFOpenOptionsSetErrorHandlerExtR(o, keep_error, t.get());
    TIFFOpenOptionsSetWarningHandlerExtR(o, ignore_warning, nullptr);
    t->tif = TIFFOpenExt(path.c_str(), mode, o);
    TIFFOpenOptionsFree(o);
    if (!t->tif)
        throw IoError(path + ": cannot open as TIFF" + (t->error.empty() ? std::string(": ") + std::strerror(errno) : t->why()));
    return t;
}

std::string page_name(const TiffStack& s, int64_t z) {
    return s.multipage ? s.files[0] + ", page " + std::to_string(z + 1) : s.files[size_t(z)];
}

/// The current page's size and sample type; throws IoError for what we cannot read.
struct Page {
    uint32_t width = 0, height = 0;
    RawType type = RawType::UInt16;
};

Page page_of(const Tiff& t, const std::string& what) {
    Page p;
    uint16_t spp = 1, bps = 1, fmt = SAMPLEFORMAT_UINT, photometric = PHOTOMETRIC_MINISBLACK;
    if (!TIFFGetField(t.tif, TIFFTAG_IMAGEWIDTH, &p.width) || !TIFFGetField(t.tif, TIFFTAG_IMAGELENGTH, &p.height) ||
        p.width == 0 || p.height == 0)
        throw IoError(what + ": TIFF without an image size" + t.why());
    TIFFGetFieldDefaulted(t.tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
    TIFFGetFieldDefaulted(t.tif, TIFFTAG_BITSPERSAMPLE, &bps);
    TIFFGetFieldDefaulted(t.tif, TIFFTAG_SAMPLEFORMAT, &fmt);
    TIFFGetField(t.tif, TIFFTAG_PHOTOMETRIC, &photometric);
    if (spp != 1)
        throw IoError(what + ": TIFF with " + std::to_string(spp) +
                      " samples per pixel (colour), expected grey images of one sample");
    if (photometric != PHOTOMETRIC_MINISBLACK)
        throw IoError(what + ": TIFF with photometric interpretation " + std::to_string(photometric) +
                      (photometric == PHOTOMETRIC_MINISWHITE ? " (inverted grey)" : "") +
                      ", expected grey images where 0 is black (1)");
    auto bad = [&]() {
        return IoError(what + ": TIFF with " + std::to_string(bps) + "-bit samples of format " + std::to_string(fmt) +
                       ", expected 8/16/32-bit unsigned or signed integers (formats 1, 2) or 32/64-bit floats (3)");
    };
    if (fmt == SAMPLEFORMAT_UINT || fmt == SAMPLEFORMAT_INT) {
        const bool s = fmt == SAMPLEFORMAT_INT;
        if (bps == 8) p.type = s ? RawType::Int8 : RawType::UInt8;
        else if (bps == 16) p.type = s ? RawType::Int16 : RawType::UInt16;
        else if (bps == 32) p.type = s ? RawType::Int32 : RawType::UInt32;
        else throw bad();
    } else if (fmt == SAMPLEFORMAT_IEEEFP) {
        if (bps == 32) p.type = RawType::Float32;
        else if (bps == 64) p.type = RawType::Float64;
        else throw bad();
    } else {
        throw bad();
    }
    return p;
}

/// Millimetres per ImageJ unit, or 0 for none/unknown.
double imagej_unit_mm(const std::string& unit) {
    const std::string u = lower(unit);
    if (u == "mm" || u == "millimeter" || u == "millimetre") return 1;
    if (u == "micron" || u == "microns" || u == "um" || u == "\xc2\xb5m" || u == "\xb5m" || u == "micrometer" ||
        u == "micrometre")
        return 1e-3;
    if (u == "nm" || u == "nanometer" || u == "nanometre") return 1e-6;
    if (u == "cm" || u == "centimeter" || u == "centimetre") return 10;
    if (u == "m" || u == "meter" || u == "metre") return 1000;
    if (u == "inch" || u == "in") return 25.4;
    return 0;
}

/// ImageJ's "key=value" lines, when the description is ImageJ's.
std::vector<std::pair<std::string, std::string>> imagej_fields(const char* desc) {
    std::vector<std::pair<std::string, std::string>> f;
    if (!desc || std::strncmp(desc, "ImageJ=", 7) != 0) return f;
    std::istringstream in(desc);
    std::string line;
    while (std::getline(in, line)) {
        const size_t eq = line.find('=');
        if (eq != std::string::npos) f.emplace_back(line.substr(0, eq), line.substr(eq + 1));
    }
    return f;
}

std::optional<double> number(const std::optional<std::string>& s) {
    if (!s) return std::nullopt;
    std::istringstream in(*s);
    double v = 0;
    if (in >> v && std::isfinite(v)) return v;
    return std::nullopt;
}

/// The voxel size and origin the first page's tags give (s.spacing_mm, origin_mm, spacing_source,
/// warnings); `why_none` says why there is none.
void read_resolution(const Tiff& t, TiffStack& s, std::string& why_none) {
    float xr = 0, yr = 0;
    uint16_t unit = RESUNIT_INCH;
    const bool has_x = TIFFGetField(t.tif, TIFFTAG_XRESOLUTION, &xr) && xr > 0 && std::isfinite(xr);
    const bool has_y = TIFFGetField(t.tif, TIFFTAG_YRESOLUTION, &yr) && yr > 0 && std::isfinite(yr);
    TIFFGetField(t.tif, TIFFTAG_RESOLUTIONUNIT, &unit);
    const char* desc = nullptr;
    TIFFGetField(t.tif, TIFFTAG_IMAGEDESCRIPTION, &desc);
    const auto ij = imagej_fields(desc);
    auto field = [&](const char* key) -> std::optional<std::string> {
        for (const auto& [k, v] : ij)
            if (k == key) return v;
        return std::nullopt;
    };
    if (!ij.empty()) {
        const std::string u = field("unit").value_or("");
        const double f = imagej_unit_mm(u);
        // Our own writer's exact values (XResolution is a 32-bit float in libtiff: 1/x loses digits).
        if (const auto exact = field("endocast_spacing_mm")) {
            std::istringstream in(*exact);
            Vec3 v{};
            if (in >> v[0] >> v[1] >> v[2] && v[0] > 0 && v[1] > 0 && v[2] > 0) {
                s.spacing_mm = v;
                s.spacing_source = "ImageJ description written by endocast (spacing " + meshpost::text::point(v) + " mm)";
            }
        }
        if (!s.spacing_mm && f > 0 && has_x) {
            const double sx = f / double(xr), sy = has_y ? f / double(yr) : sx;
            const auto z = number(field("spacing"));
            s.spacing_mm = Vec3{sx, sy, z && *z > 0 ? *z * f : sx};
            s.spacing_source = "ImageJ description (unit " + u + (z ? ", spacing " + *field("spacing") : "") +
                               ") and XResolution/YResolution";
            if (!(z && *z > 0))
                s.warnings.push_back(t.path + ": the TIFF gives no slice spacing; z spacing taken equal to x (" +
                                     num(sx) + " mm)");
        }
        if (s.spacing_mm) {
            const Vec3& sp = *s.spacing_mm;
            const char* keys[3] = {"xorigin", "yorigin", "zorigin"};
            for (int a = 0; a < 3; ++a)
                if (const auto o = number(field(keys[a]))) s.origin_mm[a] = -*o * sp[a];
            return;
        }
        if (f == 0) why_none = "ImageJ description with unit '" + u + "', not a length";
    }
    if (unit != RESUNIT_CENTIMETER && unit != RESUNIT_INCH) {
        if (why_none.empty()) why_none = "no resolution unit";
        return;
    }
    if (!has_x) {
        if (why_none.empty()) why_none = "no XResolution";
        return;
    }
    if (unit == RESUNIT_INCH && (xr == 72.0f || xr == 96.0f)) {
        why_none = std::to_string(int(xr)) + " dpi, a display default, not a scan's resolution";
        return;
    }
    const double f = unit == RESUNIT_CENTIMETER ? 10.0 : 25.4;
    const double sx = f / double(xr), sy = has_y ? f / double(yr) : sx;
    s.spacing_mm = Vec3{sx, sy, sx};
    s.spacing_source = std::string("XResolution/YResolution (pixels per ") +
                       (unit == RESUNIT_CENTIMETER ? "centimetre" : "inch") + ")";
    s.warnings.push_back(t.path + ": the TIFF gives no slice spacing; z spacing taken equal to x (" +
                         num(sx) + " mm)");
}

/// Decodes the current page (strips or tiles) into raw (its samples as stored, native byte order).
void decode_page(const Tiff& t, const TiffStack& s, const std::string& what, std::vector<unsigned char>& raw) {
    const size_t w = size_t(s.dims[0]), h = size_t(s.dims[1]), b = raw_type_size(s.type);
    const size_t row = w * b;
    raw.resize(row * h);
    auto fail = [&](const std::string& part) {
        return IoError(what + ": cannot decode " + part + " (truncated or corrupt TIFF)" + t.why());
    };
    if (TIFFIsTiled(t.tif)) {
        uint32_t tw = 0, th = 0;
        TIFFGetField(t.tif, TIFFTAG_TILEWIDTH, &tw);
        TIFFGetField(t.tif, TIFFTAG_TILELENGTH, &th);
        if (tw == 0 || th == 0) throw fail("its tiles (no tile size)");
        std::vector<unsigned char> tile(size_t(tw) * th * b);
        for (uint32_t y0 = 0; y0 < h; y0 += th)
            for (uint32_t x0 = 0; x0 < w; x0 += tw) {
                const tmsize_t n = TIFFReadEncodedTile(t.tif, TIFFComputeTile(t.tif, x0, y0, 0, 0), tile.data(),
                                                       tmsize_t(tile.size()));
                if (n < 0) throw fail("the tile at x " + std::to_string(x0) + ", y " + std::to_string(y0));
                const size_t cols = std::min<size_t>(tw, w - x0), rows = std::min<size_t>(th, h - y0);
                for (size_t r = 0; r < rows; ++r)
                    std::memcpy(raw.data() + (y0 + r) * row + size_t(x0) * b, tile.data() + r * tw * b, cols * b);
            }
        return;
    }
    uint32_t rps = 0;
    TIFFGetFieldDefaulted(t.tif, TIFFTAG_ROWSPERSTRIP, &rps);
    if (rps == 0 || rps > h) rps = uint32_t(h);
    const uint32_t strips = uint32_t((h + rps - 1) / rps);
    for (uint32_t k = 0; k < strips; ++k) {
        const size_t rows = std::min<size_t>(rps, h - size_t(k) * rps);
        const tmsize_t want = tmsize_t(rows * row);
        const tmsize_t n = TIFFReadEncodedStrip(t.tif, k, raw.data() + size_t(k) * rps * row, want);
        if (n != want) throw fail("strip " + std::to_string(k + 1) + " of " + std::to_string(strips));
    }
}

void check_page(const Page& p, const TiffStack& s, const std::string& what) {
    if (int64_t(p.width) != s.dims[0] || int64_t(p.height) != s.dims[1] || p.type != s.type)
        throw IoError(what + ": " + std::to_string(p.width) + " x " + std::to_string(p.height) + " " +
                      to_string(p.type) + " pixels, expected " + std::to_string(s.dims[0]) + " x " +
                      std::to_string(s.dims[1]) + " " + to_string(s.type) + " like " + page_name(s, 0));
}

/// Runs body(i) for i in [0, n) in parallel; rethrows the first failure (lowest i) as IoError.
template <class F>
void parallel_slices(int64_t n, F&& body) {
    std::vector<std::string> errors(size_t(std::max<int64_t>(n, 0)));
    bool failed = false;
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t i = 0; i < n; ++i) {
        bool stop;
#pragma omp atomic read
        stop = failed;
        if (stop) continue;
        try {
            body(i);
        } catch (const std::exception& e) {
            errors[size_t(i)] = e.what();
#pragma omp atomic write
            failed = true;
        }
    }
    for (const auto& e : errors)
        if (!e.empty()) throw IoError(e);
}

}  // namespace

bool is_tiff_path(const std::string& path) {
    const std::string l = lower(path);
    auto ends = [&](const char* e) {
        const size_t n = std::strlen(e);
        return l.size() >= n && l.compare(l.size() - n, n, e) == 0;
    };
    return ends(".tif") || ends(".tiff");
}

namespace {

std::vector<std::string> tiff_files_in(const std::string& dir) {
    std::vector<std::string> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
        const std::string name = e.path().filename().string();
        if (!name.empty() && name[0] != '.' && is_tiff_path(name) && e.is_regular_file(ec))
            files.push_back(e.path().string());
    }
    return files;
}

}  // namespace

bool is_tiff_input(const std::vector<std::string>& inputs) {
    if (inputs.empty()) return false;
    std::error_code ec;
    if (inputs.size() == 1 && fs::is_directory(inputs[0], ec)) return !tiff_files_in(inputs[0]).empty();
    return std::all_of(inputs.begin(), inputs.end(), [](const std::string& p) { return is_tiff_path(p); });
}

TiffStack scan_tiff(const std::vector<std::string>& inputs) {
    if (inputs.empty()) throw InvalidParameter("no TIFF input given, expected a folder, a file or a pattern");
    TiffStack s;
    std::error_code ec;
    if (inputs.size() == 1 && fs::is_directory(inputs[0], ec)) {
        s.files = tiff_files_in(inputs[0]);
        if (s.files.empty()) throw IoError(inputs[0] + ": no .tif or .tiff files in this folder");
    } else {
        for (const auto& in : inputs) {
            auto f = expand_files(in, "TIFF");
            s.files.insert(s.files.end(), f.begin(), f.end());
        }
    }
    std::stable_sort(s.files.begin(), s.files.end(), natural_less);
    std::string why_none;
    {
        const auto first = open_tiff(s.files[0], "r");
        const Page p = page_of(*first, s.files[0]);
        s.dims = {int64_t(p.width), int64_t(p.height), int64_t(s.files.size())};
        s.type = p.type;
        read_resolution(*first, s, why_none);
        if (s.files.size() == 1) {
            // One file: its pages are the slices.
            s.multipage = true;
            int64_t pages = 1;
            while (TIFFReadDirectory(first->tif)) {
                check_page(page_of(*first, page_name(s, pages)), s, page_name(s, pages));
                ++pages;
            }
            if (!first->error.empty())
                throw IoError(s.files[0] + ": cannot read the TIFF page after page " + std::to_string(pages) +
                              first->why());
            s.dims[2] = pages;
        }
    }
    if (!s.multipage)
        parallel_slices(s.dims[2], [&](int64_t z) {
            const auto t = open_tiff(s.files[size_t(z)], "r");
            check_page(page_of(*t, s.files[size_t(z)]), s, s.files[size_t(z)]);
            if (TIFFReadDirectory(t->tif))
                throw IoError(s.files[size_t(z)] + ": a TIFF of several pages in a stack of " +
                              std::to_string(s.files.size()) + " files, expected one page per slice file");
        });
    if (!s.spacing_mm && !why_none.empty()) s.spacing_source = "none (" + why_none + ")";
    return s;
}

void read_tiff_slices(const TiffStack& s, int64_t z0, int64_t nz, float* dst) {
    if (z0 < 0 || nz < 0 || z0 + nz > s.dims[2])
        throw InvalidParameter("TIFF slices " + std::to_string(z0) + " to " + std::to_string(z0 + nz) +
                               " requested, expected a range within the " + std::to_string(s.dims[2]) + " slices");
    const size_t per = size_t(s.dims[0]) * size_t(s.dims[1]);
    if (!s.multipage) {
        parallel_slices(nz, [&](int64_t i) {
            const std::string& f = s.files[size_t(z0 + i)];
            const auto t = open_tiff(f, "r");
            check_page(page_of(*t, f), s, f);
            std::vector<unsigned char> raw;
            decode_page(*t, s, f, raw);
            convert_samples(s.type, raw.data(), per, false, dst + size_t(i) * per);
        });
        return;
    }
    // Pages: each thread walks its own run of pages with its own handle.
    const int64_t runs = std::min<int64_t>(nz, 16);
    parallel_slices(runs, [&](int64_t r) {
        const int64_t a = z0 + nz * r / runs, b = z0 + nz * (r + 1) / runs;
        const auto t = open_tiff(s.files[0], "r");
        if (!TIFFSetDirectory(t->tif, tdir_t(a)))
            throw IoError(page_name(s, a) + ": cannot find this TIFF page" + t->why());
        std::vector<unsigned char> raw;
        for (int64_t z = a; z < b; ++z) {
            if (z > a && !TIFFReadDirectory(t->tif))
                throw IoError(page_name(s, z) + ": cannot read this TIFF page" + t->why());
            check_page(page_of(*t, page_name(s, z)), s, page_name(s, z));
            decode_page(*t, s, page_name(s, z), raw);
            convert_samples(s.type, raw.data(), per, false, dst + size_t(z - z0) * per);
        }
    });
}

Geometry tiff_geometry(const TiffStack& s, const TiffReadOptions& opt, InputInfo& info) {
    const std::string what = s.multipage ? s.files[0] : s.files.front() + " ... " + s.files.back();
    Geometry g;
    g.dims = s.dims;
    if (opt.spacing) {
        g.spacing = *opt.spacing;
        info.spacing_source = "given (--spacing)";
        if (s.spacing_mm && meshpost::text::point(*s.spacing_mm) != meshpost::text::point(*opt.spacing))
            info.warnings.push_back(what + ": the given spacing " + meshpost::text::point(*opt.spacing) +
                                    " mm replaces the files' " + meshpost::text::point(*s.spacing_mm) + " mm (" +
                                    s.spacing_source + ")");
    } else if (s.spacing_mm) {
        g.spacing = *s.spacing_mm;
        info.spacing_source = s.spacing_source;
        info.warnings.insert(info.warnings.end(), s.warnings.begin(), s.warnings.end());
    } else {
        throw InvalidParameter(what + ": the TIFF files carry no voxel size (" +
                               (s.spacing_source.empty() ? std::string("no resolution tags") : s.spacing_source) +
                               "), expected it given: --spacing SX SY SZ (mm)");
    }
    g.origin = opt.origin ? *opt.origin : s.origin_mm;
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(g.spacing[a]) || !(g.spacing[a] > 0))
            throw InvalidParameter(what + ": spacing " + meshpost::text::point(g.spacing) +
                                   " mm, expected finite values > 0");
        if (!std::isfinite(g.origin[a]))
            throw InvalidParameter(what + ": origin " + meshpost::text::point(g.origin) + " mm, expected finite values");
    }
    return g;
}

ReadResult read_tiff(const std::vector<std::string>& inputs, const TiffReadOptions& opt,
                     const std::function<void(const VolumeHeader&)>& check_header) {
    TiffStack s = scan_tiff(inputs);
    const std::string what = s.multipage ? s.files[0] : s.files.front() + " ... " + s.files.back();
    ReadResult r;
    const Geometry g = tiff_geometry(s, opt, r.info);
    if (check_header) check_header({g, raw_type_size(s.type)});
    try {
        r.volume = Volume<float>(g);
    } catch (const std::bad_alloc&) {
        throw OutOfMemory(what + ": out of memory allocating " + std::to_string(g.voxel_count() * sizeof(float) >> 20) +
                          " MiB");
    }
    read_tiff_slices(s, 0, s.dims[2], r.volume.data());
    if (s.type == RawType::Float32 || s.type == RawType::Float64) {
        const std::string bad = describe_non_finite(r.volume);
        if (!bad.empty()) throw InvalidParameter(what + ": " + bad + ", expected finite values");
    }
    r.info.paths = inputs;
    r.info.format = "tiff";
    r.info.voxel_type = to_string(s.type);
    r.info.files_read = s.files.size();
    return r;
}

namespace {

template <class T>
struct SampleTags;
template <>
struct SampleTags<uint8_t> {
    static constexpr uint16_t bits = 8, format = SAMPLEFORMAT_UINT;
};
template <>
struct SampleTags<int16_t> {
    static constexpr uint16_t bits = 16, format = SAMPLEFORMAT_INT;
};
template <>
struct SampleTags<float> {
    static constexpr uint16_t bits = 32, format = SAMPLEFORMAT_IEEEFP;
};

std::string exact(double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
}

/// ImageJ's description for `pages` slices of g, with our exact spacing as an extra key.
std::string imagej_description(const Geometry& g, int64_t pages) {
    std::string d = "ImageJ=1.54f\n";
    if (pages > 1) d += "images=" + std::to_string(pages) + "\nslices=" + std::to_string(pages) + "\n";
    d += "unit=mm\nspacing=" + exact(g.spacing[2]) + "\n";
    const char* keys[3] = {"xorigin", "yorigin", "zorigin"};
    for (int a = 0; a < 3; ++a) d += std::string(keys[a]) + "=" + exact(-g.origin[a] / g.spacing[a]) + "\n";
    d += "endocast_spacing_mm=" + exact(g.spacing[0]) + " " + exact(g.spacing[1]) + " " + exact(g.spacing[2]) + "\n";
    if (pages > 1) d += "loop=false\n";
    return d;
}

template <class T>
void write_page(Tiff& t, const Volume<T>& v, int64_t z, const std::string& desc, const std::string& what) {
    const Geometry& g = v.geometry();
    TIFF* tif = t.tif;
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, uint32_t(g.dims[0]));
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, uint32_t(g.dims[1]));
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(1));
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, SampleTags<T>::bits);
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SampleTags<T>::format);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, uint16_t(PHOTOMETRIC_MINISBLACK));
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, uint16_t(PLANARCONFIG_CONTIG));
    TIFFSetField(tif, TIFFTAG_COMPRESSION, uint16_t(COMPRESSION_NONE));
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, uint32_t(g.dims[1]));
    TIFFSetField(tif, TIFFTAG_XRESOLUTION, float(1.0 / g.spacing[0]));
    TIFFSetField(tif, TIFFTAG_YRESOLUTION, float(1.0 / g.spacing[1]));
    TIFFSetField(tif, TIFFTAG_RESOLUTIONUNIT, uint16_t(RESUNIT_NONE));
    TIFFSetField(tif, TIFFTAG_IMAGEDESCRIPTION, desc.c_str());
    TIFFSetField(tif, TIFFTAG_SOFTWARE, "endocast");
    const size_t per = size_t(g.dims[0]) * size_t(g.dims[1]);
    const T* src = v.data() + size_t(z) * per;
    if (TIFFWriteEncodedStrip(tif, 0, const_cast<T*>(src), tmsize_t(per * sizeof(T))) < 0 || !TIFFWriteDirectory(tif))
        throw IoError(what + ": cannot write TIFF slice " + std::to_string(z) + t.why());
}

std::string temp_name(const fs::path& p) {
    return (p.parent_path() / ("." + p.filename().string() + ".part")).string();
}

/// Writes the slices of a grid as they come: pages of one file, or a file per slice (pattern),
/// under temporary names renamed by finish(); destroyed unfinished, it removes what it wrote.
template <class T>
class TiffWriter {
public:
    TiffWriter(const std::string& path, const Geometry& whole) : path_(path), whole_(whole) {
        const Geometry& g = whole;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c)
                if (std::fabs(g.direction[size_t(3 * r + c)] - (r == c ? 1.0 : 0.0)) > 1e-9)
                    throw InvalidParameter(path + ": TIFF stores no direction, expected a volume with the identity "
                                                  "direction (this one's is " +
                                           meshpost::text::point(Vec3{g.direction[0], g.direction[4], g.direction[8]}) +
                                           " on the diagonal)");
        if (g.dims[0] > int64_t(UINT32_MAX) || g.dims[1] > int64_t(UINT32_MAX) || g.voxel_count() == 0)
            throw InvalidParameter(path + ": a volume of " + std::to_string(g.dims[0]) + " x " +
                                   std::to_string(g.dims[1]) + " x " + std::to_string(g.dims[2]) +
                                   " voxels, expected slices of 1 to 2^32 - 1 pixels a side");
        pattern_ = parse_printf(path);
        if (!pattern_ && path.find('%') != std::string::npos && path.find("%%") == std::string::npos)
            throw IoError(path + ": a TIFF pattern needs exactly one integer conversion such as %04d");
        desc_ = imagej_description(g, pattern_ ? 1 : g.dims[2]);
        if (!pattern_) {
            const bool big = g.voxel_count() * sizeof(T) > (uint64_t{2} << 30);
            temps_.push_back(temp_name(path));
            multi_ = open_tiff(temps_.back(), big ? "w8" : "w");
        }
    }
    TiffWriter(const TiffWriter&) = delete;
    TiffWriter& operator=(const TiffWriter&) = delete;
    ~TiffWriter() {
        if (finished_) return;
        multi_.reset();
        std::error_code ec;
        for (const auto& f : temps_) fs::remove(f, ec);
        for (const auto& f : done_) fs::remove(f, ec);
    }

    void write(const Volume<T>& slab) {
        const Dims d = slab.dims();
        check_slab(path_, whole_, next_z_, d);
        for (int64_t z = 0; z < d[2]; ++z, ++next_z_) {
            if (multi_) {
                write_page(*multi_, slab, z, desc_, path_);
                continue;
            }
            const std::string name = pattern_->format(long(next_z_));
            temps_.push_back(temp_name(name));
            const auto t = open_tiff(temps_.back(), "w");
            write_page(*t, slab, z, desc_, name);
        }
    }

    void finish() {
        if (next_z_ != whole_.dims[2])
            throw InvalidParameter(path_ + ": " + std::to_string(next_z_) + " slices written, expected " +
                                   std::to_string(whole_.dims[2]));
        try {
            if (multi_) {
                multi_.reset();  // TIFFClose writes the last directory
                fs::rename(temps_.back(), path_);
                temps_.clear();
                done_.push_back(path_);
            } else {
                for (int64_t z = 0; z < whole_.dims[2]; ++z) {
                    const std::string name = pattern_->format(long(z));
                    fs::rename(temps_[size_t(z)], name);
                    done_.push_back(name);
                }
                temps_.clear();
            }
        } catch (const std::exception& e) {
            throw IoError(path_ + ": cannot put the TIFF in place: " + e.what());
        }
        finished_ = true;
    }

private:
    std::string path_;
    Geometry whole_;
    std::optional<PrintfPattern> pattern_;
    std::string desc_;
    std::unique_ptr<Tiff> multi_;
    std::vector<std::string> temps_, done_;
    int64_t next_z_ = 0;
    bool finished_ = false;
};

template <class T>
void write_tiff_volume(const Volume<T>& v, const std::string& path) {
    TiffWriter<T> w(path, v.geometry());
    w.write(v);
    w.finish();
}

class TiffSlabWriter : public SlabWriter {
public:
    TiffSlabWriter(const std::string& path, const Geometry& whole) : w_(path, whole) {}
    void write(const Volume<int16_t>& slab) override { w_.write(slab); }
    void finish() override { w_.finish(); }

private:
    TiffWriter<int16_t> w_;
};

}  // namespace

void check_slab(const std::string& path, const Geometry& whole, int64_t next_z, const Dims& d) {
    if (d[0] != whole.dims[0] || d[1] != whole.dims[1] || next_z + d[2] > whole.dims[2])
        throw InvalidParameter(path + ": a slab of " + std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " +
                               std::to_string(d[2]) + " voxels after " + std::to_string(next_z) + " slices, expected " +
                               std::to_string(whole.dims[0]) + " x " + std::to_string(whole.dims[1]) +
                               " and at most " + std::to_string(whole.dims[2]) + " slices in all");
}

void write_tiff(const Volume<uint8_t>& v, const std::string& path) { write_tiff_volume(v, path); }
void write_tiff(const Volume<int16_t>& v, const std::string& path) { write_tiff_volume(v, path); }
void write_tiff(const Volume<float>& v, const std::string& path) { write_tiff_volume(v, path); }

std::unique_ptr<SlabWriter> open_tiff_slab_writer(const std::string& path, const Geometry& whole) {
    return std::make_unique<TiffSlabWriter>(path, whole);
}

}  // namespace endocast
