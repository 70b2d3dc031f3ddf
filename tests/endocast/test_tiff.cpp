// TIFF volumes (tiff.h): slice folders, patterns and multi-page files, their voxel size from the
// tags, every sample type and layout libtiff writes, and what is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <tiffio.h>

#include "endocast/io.h"
#include "endocast/tiff.h"
#include "test_helpers.h"

using namespace endocast;
namespace fs = std::filesystem;
using endocast::testing::ScratchDir;

namespace {

/// What a hand-written TIFF page holds beyond its pixels.
struct PageTags {
    uint16_t bits = 16, format = SAMPLEFORMAT_UINT, spp = 1, photometric = PHOTOMETRIC_MINISBLACK;
    uint16_t compression = COMPRESSION_NONE;
    uint32_t tile = 0;       ///< > 0: tiles of this size, else strips
    uint32_t rows_per_strip = 3;
    float xres = 0, yres = 0;  ///< 0: no resolution tags
    uint16_t res_unit = RESUNIT_NONE;
    std::string description;
};

/// The value of voxel (x, y, z) in the hand-written volumes.
double value_at(int64_t x, int64_t y, int64_t z) { return double(x + 7 * y + 50 * z); }

/// Writes pages [z0, z1) of a w x h volume with value_at (as the sample type) into one file.
void write_pages(const std::string& path, uint32_t w, uint32_t h, int64_t z0, int64_t z1, const PageTags& t,
                 const char* mode = "w") {
    TIFF* tif = TIFFOpen(path.c_str(), mode);
    ASSERT_NE(tif, nullptr) << path;
    for (int64_t z = z0; z < z1; ++z) {
        TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, w);
        TIFFSetField(tif, TIFFTAG_IMAGELENGTH, h);
        TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, t.spp);
        TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, t.bits);
        TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, t.format);
        TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, t.photometric);
        TIFFSetField(tif, TIFFTAG_PLANARCONFIG, uint16_t(PLANARCONFIG_CONTIG));
        TIFFSetField(tif, TIFFTAG_COMPRESSION, t.compression);
        if (t.xres > 0) {
            TIFFSetField(tif, TIFFTAG_XRESOLUTION, t.xres);
            TIFFSetField(tif, TIFFTAG_YRESOLUTION, t.yres > 0 ? t.yres : t.xres);
            TIFFSetField(tif, TIFFTAG_RESOLUTIONUNIT, t.res_unit);
        }
        if (!t.description.empty()) TIFFSetField(tif, TIFFTAG_IMAGEDESCRIPTION, t.description.c_str());
        const size_t b = t.bits / 8 * t.spp;
        std::vector<unsigned char> img(size_t(w) * h * b);
        for (uint32_t y = 0; y < h; ++y)
            for (uint32_t x = 0; x < w; ++x) {
                unsigned char* p = img.data() + (size_t(y) * w + x) * b;
                const double v = value_at(x, y, z);
                for (uint16_t s = 0; s < t.spp; ++s, p += t.bits / 8) {
                    if (t.format == SAMPLEFORMAT_IEEEFP && t.bits == 32) {
                        const float f = float(v) + 0.25f;
                        std::memcpy(p, &f, 4);
                    } else if (t.format == SAMPLEFORMAT_IEEEFP) {
                        const double d = v + 0.25;
                        std::memcpy(p, &d, 8);
                    } else if (t.bits == 8) {
                        *p = uint8_t(int64_t(v) % 256);
                    } else if (t.bits == 16) {
                        const int16_t s16 = int16_t(t.format == SAMPLEFORMAT_INT ? -int64_t(v) : int64_t(v));
                        std::memcpy(p, &s16, 2);
                    } else {
                        const int32_t s32 = int32_t(t.format == SAMPLEFORMAT_INT ? -int64_t(v) * 1000 : int64_t(v) * 1000);
                        std::memcpy(p, &s32, 4);
                    }
                }
            }
        if (t.tile > 0) {
            TIFFSetField(tif, TIFFTAG_TILEWIDTH, t.tile);
            TIFFSetField(tif, TIFFTAG_TILELENGTH, t.tile);
            std::vector<unsigned char> tile(size_t(t.tile) * t.tile * b, 0);
            for (uint32_t ty = 0; ty < h; ty += t.tile)
                for (uint32_t tx = 0; tx < w; tx += t.tile) {
                    std::fill(tile.begin(), tile.end(), 0);
                    for (uint32_t r = 0; r < t.tile && ty + r < h; ++r)
                        std::memcpy(tile.data() + size_t(r) * t.tile * b, img.data() + (size_t(ty + r) * w + tx) * b,
                                    std::min<size_t>(t.tile, w - tx) * b);
                    ASSERT_GE(TIFFWriteTile(tif, tile.data(), tx, ty, 0, 0), 0);
                }
        } else {
            TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, t.rows_per_strip);
            for (uint32_t y = 0; y < h; y += t.rows_per_strip) {
                const uint32_t rows = std::min(t.rows_per_strip, h - y);
                ASSERT_GE(TIFFWriteEncodedStrip(tif, y / t.rows_per_strip, img.data() + size_t(y) * w * b,
                                                tmsize_t(size_t(rows) * w * b)),
                          0);
            }
        }
        ASSERT_TRUE(TIFFWriteDirectory(tif));
    }
    TIFFClose(tif);
}

/// Expected value of voxel (x, y, z) as read from a page written with `t`.
double expected(const PageTags& t, int64_t x, int64_t y, int64_t z) {
    const double v = value_at(x, y, z);
    if (t.format == SAMPLEFORMAT_IEEEFP) return v + 0.25;
    if (t.bits == 8) return double(int64_t(v) % 256);
    if (t.bits == 16) return t.format == SAMPLEFORMAT_INT ? -v : v;
    return t.format == SAMPLEFORMAT_INT ? -v * 1000 : v * 1000;
}

void expect_values(const Volume<float>& v, const PageTags& t) {
    const Dims d = v.dims();
    for (int64_t z = 0; z < d[2]; ++z)
        for (int64_t y = 0; y < d[1]; ++y)
            for (int64_t x = 0; x < d[0]; ++x)
                ASSERT_EQ(v(x, y, z), float(expected(t, x, y, z))) << x << " " << y << " " << z;
}

const Vec3 kOne{1, 1, 1};

template <class E, class F>
void expect_error(F&& f, const std::vector<std::string>& parts) {
    try {
        f();
        FAIL() << "no exception";
    } catch (const E& e) {
        for (const auto& p : parts) EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
    }
}

}  // namespace

TEST(TiffRead, EverySampleTypeInStripsAndTilesCompressedOrNot) {
    ScratchDir dir("tiff_types");
    int k = 0;
    const std::pair<uint16_t, uint16_t> kinds[] = {  // bits, format
        {8, SAMPLEFORMAT_UINT},  {16, SAMPLEFORMAT_UINT}, {16, SAMPLEFORMAT_INT},     {32, SAMPLEFORMAT_UINT},
        {32, SAMPLEFORMAT_INT},  {32, SAMPLEFORMAT_IEEEFP}, {64, SAMPLEFORMAT_IEEEFP}};
    for (const auto& [bits, format] : kinds)
        for (uint32_t tile : {0u, 16u})
                for (uint16_t comp : {uint16_t(COMPRESSION_NONE), uint16_t(COMPRESSION_ADOBE_DEFLATE), uint16_t(COMPRESSION_LZW)}) {
                    PageTags t;
                    t.bits = bits;
                    t.format = format;
                    t.tile = tile;
                    t.compression = comp;
                    const std::string f = dir / ("v" + std::to_string(k++) + ".tif");
                    write_pages(f, 37, 21, 0, 4, t);  // tiles do not divide the slice; strips of 3 rows neither
                    const ReadResult r = read_tiff({f}, {kOne});
                    SCOPED_TRACE(f + " bits " + std::to_string(bits) + " format " + std::to_string(format) +
                                 " tile " + std::to_string(tile) + " compression " + std::to_string(comp));
                    EXPECT_EQ(r.volume.dims(), (Dims{37, 21, 4}));
                    EXPECT_EQ(r.info.format, "tiff");
                    EXPECT_EQ(r.info.files_read, 1u);
                    expect_values(r.volume, t);
                }
    EXPECT_GT(k, 20);
}

TEST(TiffRead, BigEndianFile) {
    ScratchDir dir("tiff_be");
    PageTags t;
    write_pages(dir / "be.tif", 9, 8, 0, 3, t, "wb");
    const ReadResult r = read_tiff({dir / "be.tif"}, {kOne});
    expect_values(r.volume, t);
}

TEST(TiffRead, FolderAndPatternsInNaturalOrderOtherFilesIgnored) {
    ScratchDir dir("tiff_folder");
    PageTags t;
    // slice2 before slice10: natural order, not the names' byte order.
    for (int z = 0; z < 12; ++z) write_pages(dir / ("slice" + std::to_string(z) + ".tif"), 10, 6, z, z + 1, t);
    std::ofstream(dir / "scan.log") << "scanner log\n";
    std::ofstream(dir / ".hidden.tif") << "not a tiff\n";
    for (const std::vector<std::string>& in :
         {std::vector<std::string>{dir.str()}, {dir / "slice%d.tif"}, {dir / "slice*.tif"}}) {
        SCOPED_TRACE(in[0]);
        const ReadResult r = read_volume(in, [&] {
            ReadOptions o;
            o.spacing = Vec3{0.1, 0.1, 0.2};
            return o;
        }());
        EXPECT_EQ(r.volume.dims(), (Dims{10, 6, 12}));
        EXPECT_EQ(r.info.files_read, 12u);
        EXPECT_EQ(r.volume.geometry().spacing, (Vec3{0.1, 0.1, 0.2}));
        EXPECT_EQ(r.info.spacing_source, "given (--spacing)");
        expect_values(r.volume, t);
    }
    EXPECT_TRUE(is_tiff_input({dir.str()}));
    EXPECT_FALSE(is_tiff_input({"a.nrrd"}));
    EXPECT_TRUE(is_tiff_input({"A.TIFF", "b.tif"}));
}

TEST(TiffRead, VoxelSizeFromImageJOrResolutionTagsAndSaidSo) {
    ScratchDir dir("tiff_res");
    // ImageJ: pixels per micron, slice spacing in microns, origin in pixels.
    PageTags ij;
    ij.xres = 20;  // 20 px/um: 0.05 um = 5e-5 mm
    ij.yres = 10;
    ij.description = "ImageJ=1.54f\nimages=3\nslices=3\nunit=micron\nspacing=0.2\nxorigin=4\nloop=false\n";
    write_pages(dir / "ij.tif", 8, 8, 0, 3, ij);
    ReadResult r = read_tiff({dir / "ij.tif"});
    EXPECT_NEAR(r.volume.geometry().spacing[0], 5e-5, 1e-12);
    EXPECT_NEAR(r.volume.geometry().spacing[1], 1e-4, 1e-12);
    EXPECT_NEAR(r.volume.geometry().spacing[2], 2e-4, 1e-12);
    EXPECT_NEAR(r.volume.geometry().origin[0], -4 * 5e-5, 1e-12);
    EXPECT_NE(r.info.spacing_source.find("ImageJ"), std::string::npos) << r.info.spacing_source;
    EXPECT_TRUE(r.info.warnings.empty());

    // Standard tags in pixels per centimetre: z taken equal to x, with a warning.
    PageTags cm;
    cm.xres = 40;  // 0.25 mm
    cm.res_unit = RESUNIT_CENTIMETER;
    write_pages(dir / "cm.tif", 8, 8, 0, 3, cm);
    r = read_tiff({dir / "cm.tif"});
    EXPECT_NEAR(r.volume.geometry().spacing[0], 0.25, 1e-9);
    EXPECT_NEAR(r.volume.geometry().spacing[2], 0.25, 1e-9);
    EXPECT_NE(r.info.spacing_source.find("centimetre"), std::string::npos) << r.info.spacing_source;
    ASSERT_EQ(r.info.warnings.size(), 1u);
    EXPECT_NE(r.info.warnings[0].find("z spacing taken equal to x"), std::string::npos) << r.info.warnings[0];

    // The given spacing wins, and the replaced one is named.
    r = read_tiff({dir / "cm.tif"}, {Vec3{0.5, 0.5, 1.0}});
    EXPECT_EQ(r.volume.geometry().spacing, (Vec3{0.5, 0.5, 1.0}));
    ASSERT_EQ(r.info.warnings.size(), 1u);
    EXPECT_NE(r.info.warnings[0].find("replaces"), std::string::npos) << r.info.warnings[0];

    // No resolution, or 72 dpi (a display default): the spacing must be given.
    PageTags none, dpi72;
    dpi72.xres = 72;
    dpi72.res_unit = RESUNIT_INCH;
    write_pages(dir / "none.tif", 8, 8, 0, 2, none);
    write_pages(dir / "dpi72.tif", 8, 8, 0, 2, dpi72);
    expect_error<InvalidParameter>([&] { read_tiff({dir / "none.tif"}); }, {"none.tif", "no voxel size", "--spacing"});
    expect_error<InvalidParameter>([&] { read_tiff({dir / "dpi72.tif"}); }, {"dpi72.tif", "72 dpi", "--spacing"});
    EXPECT_NO_THROW(read_tiff({dir / "dpi72.tif"}, {kOne}));
    expect_error<InvalidParameter>([&] { read_tiff({dir / "none.tif"}, {Vec3{1, 0, 1}}); }, {"spacing", "> 0"});
}

TEST(TiffWrite, RoundTripsVoxelsAndGeometryMultiPageAndSlices) {
    ScratchDir dir("tiff_write");
    Geometry g;
    g.dims = {13, 9, 5};
    g.spacing = {0.48828125, 0.3, 0.625};  // 1/x is not a float exactly: the exact values travel too
    g.origin = {-12.5, 3.25, 100.125};
    Volume<int16_t> v16(g);
    Volume<uint8_t> v8(g);
    Volume<float> vf(g);
    for (size_t i = 0; i < v16.size(); ++i) {
        v16.data()[i] = int16_t(int(i) * 37 - 1000);
        v8.data()[i] = uint8_t(i * 7);
        vf.data()[i] = float(i) * 0.5f - 3.0f;
    }
    auto check = [&](const std::vector<std::string>& in, auto& vol) {
        SCOPED_TRACE(in[0]);
        const ReadResult r = read_volume(in);
        EXPECT_EQ(r.volume.geometry().dims, g.dims);
        EXPECT_EQ(r.volume.geometry().spacing, g.spacing);
        EXPECT_EQ(r.volume.geometry().origin, g.origin);
        for (size_t i = 0; i < vol.size(); ++i) ASSERT_EQ(r.volume.data()[i], float(vol.data()[i])) << i;
    };
    write_volume(v16, dir / "v16.tif");
    check({dir / "v16.tif"}, v16);
    write_volume(v8, dir / "v8.tiff");
    check({dir / "v8.tiff"}, v8);
    fs::create_directories(dir.path() / "stack");
    write_volume(vf, dir / "stack/s%03d.tif");
    EXPECT_TRUE(fs::exists(dir.path() / "stack/s000.tif"));
    EXPECT_TRUE(fs::exists(dir.path() / "stack/s004.tif"));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir.path() / "stack"), fs::directory_iterator{}), 5);
    check({(dir.path() / "stack").string()}, vf);
    check({dir / "stack/s%03d.tif"}, vf);

    // Slab reads give the same voxels as the whole read.
    const TiffStack s = scan_tiff({dir / "v16.tif"});
    EXPECT_TRUE(s.multipage);
    std::vector<float> slab(size_t(13 * 9 * 2));
    read_tiff_slices(s, 2, 2, slab.data());
    for (size_t i = 0; i < slab.size(); ++i) ASSERT_EQ(slab[i], float(v16.data()[2 * 13 * 9 + i]));
    EXPECT_THROW(read_tiff_slices(s, 4, 2, slab.data()), InvalidParameter);

    // A direction TIFF cannot hold, a missing folder: refused, nothing left behind.
    Geometry rot = g;
    rot.direction = {0, 1, 0, 1, 0, 0, 0, 0, 1};
    expect_error<InvalidParameter>([&] { write_tiff(Volume<int16_t>(rot), dir / "rot.tif"); }, {"rot.tif", "direction"});
    EXPECT_THROW(write_volume(v16, dir / "missing/s%03d.tif"), IoError);
    EXPECT_FALSE(fs::exists(dir.path() / "rot.tif"));
    for (const auto& e : fs::directory_iterator(dir.path())) EXPECT_EQ(e.path().filename().string().find(".part"), std::string::npos);
}

TEST(TiffRead, RefusesWhatItCannotReadWithTheFileNamed) {
    ScratchDir dir("tiff_bad");
    PageTags rgb;
    rgb.bits = 8;
    rgb.spp = 3;
    rgb.photometric = PHOTOMETRIC_RGB;
    write_pages(dir / "rgb.tif", 8, 8, 0, 1, rgb);
    expect_error<IoError>([&] { read_tiff({dir / "rgb.tif"}, {kOne}); }, {"rgb.tif", "3 samples per pixel"});

    PageTags white;
    white.photometric = PHOTOMETRIC_MINISWHITE;
    write_pages(dir / "white.tif", 8, 8, 0, 1, white);
    expect_error<IoError>([&] { read_tiff({dir / "white.tif"}, {kOne}); }, {"white.tif", "inverted grey"});

    // A slice of another size in a folder.
    fs::create_directories(dir.path() / "mixed");
    PageTags t;
    write_pages(dir / "mixed/a1.tif", 8, 8, 0, 1, t);
    write_pages(dir / "mixed/a2.tif", 8, 9, 1, 2, t);
    expect_error<IoError>([&] { read_tiff({(dir.path() / "mixed").string()}, {kOne}); }, {"a2.tif", "8 x 9", "8 x 8"});

    // A multi-page file in a stack of slice files.
    fs::create_directories(dir.path() / "multi");
    write_pages(dir / "multi/b1.tif", 8, 8, 0, 1, t);
    write_pages(dir / "multi/b2.tif", 8, 8, 1, 3, t);
    expect_error<IoError>([&] { read_tiff({(dir.path() / "multi").string()}, {kOne}); }, {"b2.tif", "one page per slice"});

    // Truncated data; not a TIFF at all; an empty folder; a pattern matching nothing.
    write_pages(dir / "whole.tif", 64, 64, 0, 2, t);
    const auto size = fs::file_size(dir.path() / "whole.tif");
    fs::copy_file(dir.path() / "whole.tif", dir.path() / "cut.tif");
    fs::resize_file(dir.path() / "cut.tif", size / 3);
    EXPECT_THROW(read_tiff({dir / "cut.tif"}, {kOne}), IoError);
    std::ofstream(dir / "text.tif") << "hello\n";
    expect_error<IoError>([&] { read_tiff({dir / "text.tif"}, {kOne}); }, {"text.tif", "TIFF"});
    fs::create_directories(dir.path() / "empty");
    EXPECT_FALSE(is_tiff_input({(dir.path() / "empty").string()}));
    expect_error<IoError>([&] { read_tiff({(dir.path() / "empty").string()}, {kOne}); }, {"no .tif"});
    expect_error<IoError>([&] { read_tiff({dir / "nothing%03d.tif"}, {kOne}); }, {"nothing%03d.tif", "no file matches"});

    // NaN in float samples.
    {
        TIFF* tif = TIFFOpen((dir / "nan.tif").c_str(), "w");
        ASSERT_NE(tif, nullptr);
        float px[4] = {1, NAN, 2, 3};
        TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, 2u);
        TIFFSetField(tif, TIFFTAG_IMAGELENGTH, 2u);
        TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(32));
        TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, uint16_t(SAMPLEFORMAT_IEEEFP));
        TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, uint16_t(PHOTOMETRIC_MINISBLACK));
        TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 2u);
        TIFFWriteEncodedStrip(tif, 0, px, sizeof px);
        TIFFClose(tif);
    }
    expect_error<InvalidParameter>([&] { read_tiff({dir / "nan.tif"}, {kOne}); }, {"nan.tif", "finite"});

    // Spacing for a format with its own geometry.
    ReadOptions o;
    o.spacing = kOne;
    EXPECT_THROW(read_volume({dir / "x.nrrd"}, o), InvalidParameter);
}

TEST(TiffRead, HeaderCheckRunsBeforeTheVoxelsAreAllocated) {
    ScratchDir dir("tiff_check");
    PageTags t;
    write_pages(dir / "v.tif", 16, 16, 0, 4, t);
    VolumeHeader seen;
    EXPECT_THROW(read_tiff({dir / "v.tif"}, {kOne},
                           [&](const VolumeHeader& h) {
                               seen = h;
                               throw OutOfMemory("stop");
                           }),
                 OutOfMemory);
    EXPECT_EQ(seen.geometry.dims, (Dims{16, 16, 4}));
    EXPECT_EQ(seen.stored_voxel_bytes, 2u);
}
