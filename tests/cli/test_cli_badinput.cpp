// Bad inputs given to `endocast extract`: each must fail with one clear line on stderr (naming the
// file, what was wrong and what was expected), the documented exit status, and no output written.
// Mesh inputs of inspect/simplify/compare are in test_cli_mesh.cpp (BadInputFailsCleanlyAndWritesNothing);
// the readers' exceptions are tested in tests/endocast/test_io.cpp. docs/reliability.md lists them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <vector>

#include "cli_helpers.h"
#include "endocast/io.h"

using namespace cli_test;

namespace {

void write_file(const fs::path& p, const std::string& bytes) {
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f << bytes;
}

std::string read_file(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
}

/// An attached NRRD: header lines + data bytes.
std::string nrrd(const std::string& type, const std::string& sizes, const std::string& extra,
                 const std::string& data) {
    return "NRRD0004\ntype: " + type + "\ndimension: 3\nsizes: " + sizes + "\n" + extra +
           "endian: little\nencoding: raw\n\n" + data;
}

/// A NIfTI-1 single file (.nii): the 348-byte header, 4 bytes of extension flags, then `data`.
std::string nifti(int16_t datatype, int16_t bitpix, int16_t nx, int16_t ny, int16_t nz,
                  const std::string& data, float spacing_x = 1) {
    std::string h(352, '\0');
    auto put = [&](size_t at, const void* v, size_t n) { std::memcpy(&h[at], v, n); };
    const int32_t size = 348;
    put(0, &size, 4);
    const int16_t dim[8] = {3, nx, ny, nz, 1, 1, 1, 1};
    put(40, dim, sizeof dim);
    put(70, &datatype, 2);
    put(72, &bitpix, 2);
    const float pixdim[8] = {1, spacing_x, 1, 1, 1, 1, 1, 1};
    put(76, pixdim, sizeof pixdim);
    const float vox_offset = 352, slope = 1;
    put(108, &vox_offset, 4);
    put(112, &slope, 4);
    put(344, "n+1\0", 4);
    return h + data;
}

std::string floats(size_t n, size_t nan_at) {
    std::string s;
    for (size_t i = 0; i < n; ++i) {
        const float v = i == nan_at ? std::numeric_limits<float>::quiet_NaN() : 1.0f;
        s.append(reinterpret_cast<const char*>(&v), 4);
    }
    return s;
}

struct Expect {
    int status;
    std::vector<std::string> needles;  ///< each must appear in the output
};

/// Runs extract on `input` with `args`; checks the status, the needles, that the error is one line
/// naming the input, and that neither the mesh nor the report was written.
void expect_failure(const fs::path& input, const std::string& args, const Expect& e,
                    bool names_input = true) {
    const fs::path out = input.parent_path() / "out";
    fs::create_directories(out);
    const CliRun r = run("extract " + input.string() + " -q " + args + " -o " +
                         (out / "e.stl").string() + " --report " + (out / "e.json").string());
    EXPECT_EQ(r.status, e.status) << r.output;
    if (e.status != 2) {  // usage errors are CLI11's: the error and a line pointing to --help
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
        EXPECT_EQ(r.output.rfind("endocast: error: ", 0), 0u) << r.output;
    }
    if (names_input) EXPECT_NE(r.output.find(input.filename().string()), std::string::npos) << r.output;
    for (const auto& n : e.needles) EXPECT_NE(r.output.find(n), std::string::npos) << n << " in " << r.output;
    EXPECT_TRUE(fs::is_empty(out)) << "output written for " << input;
}

std::vector<std::string> dicom_files() {
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(shared("headphantom-dicom")))
        if (e.path().extension() == ".dcm") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    return files;
}

/// A copy (symbolic links) of the head phantom's DICOM series without slice `skip`.
fs::path series_without_slice(const std::string& name, const std::vector<std::string>& files, size_t skip) {
    const fs::path d = temp_dir(name) / "series";
    fs::create_directories(d);
    for (size_t i = 0; i < files.size(); ++i)
        if (i != skip) fs::create_symlink(files[i], d / fs::path(files[i]).filename());
    return d;
}

}  // namespace

TEST(CliBadInput, MissingFileAndDirectoryWithoutDicom) {
    const fs::path d = temp_dir("bad_missing");
    expect_failure(d / "none.nrrd", "", {3, {"no such file"}});
    fs::create_directories(d / "nodicom");
    write_file(d / "nodicom" / "notes.txt", "not DICOM\n");
    expect_failure(d / "nodicom", "", {3, {"no DICOM series"}});
}

TEST(CliBadInput, MalformedNrrdAndNiftiHeadersAndData) {
    const fs::path d = temp_dir("bad_headers");
    const std::string u8x512(512, '\x10');
    const struct {
        const char* name;
        std::string bytes;
        Expect e;
    } cases[] = {
        {"truncated.nrrd", nrrd("uint8", "8 8 8", "", std::string(100, '\x10')), {3, {}}},
        {"huge.nrrd", nrrd("uint8", "100000 100000 100000", "", "tiny"), {3, {"100000 x 100000 x 100000", "2^40"}}},
        {"zero.nrrd", nrrd("uint8", "0 8 8", "", u8x512), {3, {}}},
        {"negative.nrrd", nrrd("uint8", "-8 8 8", "", u8x512), {3, {}}},
        {"block.nrrd", "NRRD0004\ntype: block\nblocksize: 4\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" +
                           std::string(32, '\x01'), {3, {}}},
        {"spacing0.nrrd", nrrd("uint8", "8 8 8", "spacings: 0 1 1\n", u8x512), {3, {"spacing (0) invalid"}}},
        {"nan.nrrd", nrrd("float", "4 4 4", "", floats(64, 17)), {4, {"1 voxels are NaN or infinite", "(1, 0, 1)"}}},
        {"truncated.nii", nifti(2, 8, 8, 8, 8, std::string(100, '\x10')), {3, {}}},
        {"complex.nii", nifti(32, 64, 2, 2, 2, std::string(64, '\0')), {4, {"2 components per voxel"}}},
    };
    for (const auto& c : cases) {
        SCOPED_TRACE(c.name);
        write_file(d / c.name, c.bytes);
        expect_failure(d / c.name, "", c.e);
    }
}

TEST(CliBadInput, CorruptGzipInDetachedNrrd) {
    const fs::path d = temp_dir("bad_gzip");
    write_file(d / "bad.nhdr", "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 8 8 4\n"
                               "endian: little\nencoding: gzip\ndata file: bad.raw.gz\n\n");
    std::string garbage = "\x1f\x8b";
    for (int i = 0; i < 300; ++i) garbage += static_cast<char>(i * 37 + 11);
    write_file(d / "bad.raw.gz", garbage);
    expect_failure(d / "bad.nhdr", "", {3, {}});
}

TEST(CliBadInput, RawSizesAreCheckedBeforeAllocating) {
    const fs::path d = temp_dir("bad_raw");
    write_file(d / "small.raw", std::string(1000, '\0'));
    expect_failure(d / "small.raw", "--raw-size 100000 100000 100000", {4, {"100000 x 100000 x 100000"}},
                   false);
    expect_failure(d / "small.raw", "--raw-size 0 10 10", {4, {"> 0"}}, false);
    expect_failure(d / "small.raw", "--raw-size 10 10 20 --raw-type uint8", {3, {"1000 bytes", "expected 2000"}});
}

TEST(CliBadInput, DataThatHoldsNoEndocast) {
    const fs::path d = temp_dir("bad_data");
    endocast::Geometry g;
    g.dims = {20, 20, 20};
    endocast::write_volume(endocast::Volume<float>(g, 100.0f), (d / "constant.nrrd").string());
    expect_failure(d / "constant.nrrd", "", {5, {"distinct values", "data range 100 .. 100", "--iso"}});
    endocast::Volume<float> ramp(g);
    for (size_t i = 0; i < ramp.size(); ++i) ramp[i] = static_cast<float>(i % 1000);
    endocast::write_volume(ramp, (d / "ramp.nrrd").string());
    expect_failure(d / "ramp.nrrd", "--iso 5000", {5, {"no voxel is >= the isovalue 5000", "data range 0 .. 999"}});
    expect_failure(d / "ramp.nrrd", "--iso -5", {5, {"every voxel is >= the isovalue -5", "data range 0 .. 999"}});
    expect_failure(d / "ramp.nrrd", "--iso nan", {4, {"isovalue nan, expected a finite number"}}, false);
}

TEST(CliBadInput, CropDownsampleAndMemoryOptions) {
    const fs::path d = temp_dir("bad_shrink");
    endocast::Geometry g;
    g.dims = {20, 20, 20};
    endocast::write_volume(endocast::Volume<float>(g, 100.0f), (d / "v.nrrd").string());
    expect_failure(d / "v.nrrd", "--crop 0 0 0 21 20 20", {4, {"crop box 0 0 0 21 20 20", "20 x 20 x 20"}}, false);
    expect_failure(d / "v.nrrd", "--crop 5 0 0 5 20 20", {4, {"crop box"}}, false);
    expect_failure(d / "v.nrrd", "--downsample 0", {2, {"--downsample", "not in range 1 to"}}, false);
    expect_failure(d / "v.nrrd", "--max-memory 0.01", {6, {"--max-memory", "--crop", "--downsample"}});
    expect_failure(d / "v.nrrd", "--max-memory 100 --downsample 2", {6, {"10 x 10 x 10 after crop/downsample"}});
}

TEST(CliBadInput, DicomSeriesWithAMissingSlice) {
    if (!fs::exists(shared("headphantom-dicom"))) GTEST_SKIP() << "../shared/data/headphantom-dicom not found";
    const auto files = dicom_files();
    ASSERT_EQ(files.size(), 209u);
    expect_failure(series_without_slice("bad_gap", files, 100), "--iso 250", {3, {"slices are missing", "4 mm apart", "expected 2 mm"}});
}

TEST(CliBadInput, DicomSliceOfAnotherSize) {
    if (!fs::exists(shared("headphantom-dicom"))) GTEST_SKIP() << "../shared/data/headphantom-dicom not found";
    const auto files = dicom_files();
    ASSERT_EQ(files.size(), 209u);
    const fs::path series = series_without_slice("bad_sizes", files, 100);
    // Slice 100 rewritten as 512 columns x 256 rows (implicit VR little endian: patch Rows and the
    // pixel data length, drop the second half of the pixels).
    std::string b = read_file(files[100]);
    const std::string rows("\x28\x00\x10\x00\x02\x00\x00\x00\x00\x02", 10);
    const std::string pixels("\xe0\x7f\x10\x00\x00\x00\x08\x00", 8);
    const size_t r = b.find(rows), p = b.find(pixels);
    ASSERT_NE(r, std::string::npos);
    ASSERT_NE(p, std::string::npos);
    ASSERT_EQ(b.size(), p + 8 + 524288u);
    b[r + 8] = '\x00';
    b[r + 9] = '\x01';  // 256 rows
    b[p + 6] = '\x04';  // 262144 bytes
    b.resize(p + 8 + 262144);
    write_file(series / fs::path(files[100]).filename(), b);
    expect_failure(series, "--iso 250", {3, {"is 512 x 256 pixels, expected 512 x 512", fs::path(files[100]).filename().string()}});
}

TEST(CliBadInput, CavityOpenEverywhereIsNoResult) {
    // A 5 mm slab through the braincase of the macaque phantom: the cavity is open at the top and
    // the bottom everywhere, and the outside seeds' border balls fill the slab: what is left is a
    // speck, not a braincase. Exit 5 with the reason, and no output file.
    const fs::path d = temp_dir("bad_slab");
    CliRun r = run("phantom " + (d / "mq.nrrd").string() + " --preset macaque --seed 3 -q");
    ASSERT_EQ(r.status, 0) << r.output;
    const auto dims = read_json(d / "mq.json")["dims"];
    r = run("extract " + (d / "mq.nrrd").string() + " -q --crop 0 0 70 " + std::to_string(dims[0].get<int>()) +
            " " + std::to_string(dims[1].get<int>()) + " 80 -o " + (d / "slab.stl").string() + " --report " +
            (d / "slab.json").string());
    EXPECT_EQ(r.status, 5) << r.output;
    EXPECT_NE(r.output.find("no braincase found"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(d / "slab.json"));
    EXPECT_FALSE(fs::exists(d / "slab.stl"));
}

TEST(CliBadInput, APlateWithoutACavityIsNoResult) {
    // Issue 18's case: a 40^3 volume holding only a bone plate 4 voxels thick. Exit 5, no files.
    const fs::path d = temp_dir("bad_plate");
    std::string raw(40 * 40 * 40 * 2, '\0');
    for (int z = 18; z < 22; ++z)
        for (int i = 0; i < 40 * 40; ++i) {
            const size_t k = 2 * (size_t(z) * 1600 + size_t(i));
            raw[k] = char(1000 & 0xff);
            raw[k + 1] = char(1000 >> 8);
        }
    write_file(d / "plate.raw", raw);
    const CliRun r = run("extract " + (d / "plate.raw").string() +
                         " --raw-size 40 40 40 --raw-type int16 --spacing 1 1 1 --iso 500 -o " +
                         (d / "plate.stl").string() + " --report " + (d / "plate.json").string() + " --qc " +
                         (d / "plate.png").string());
    EXPECT_EQ(r.status, 5) << r.output;
    EXPECT_NE(r.output.find("no braincase found"), std::string::npos) << r.output;
    for (const char* f : {"plate.stl", "plate.json", "plate.png"}) EXPECT_FALSE(fs::exists(d / f)) << f;
}
