// Reading in slabs (slice_source.h): read_shrunk gives exactly the voxels and grid of shrinking the
// whole volume, from raw NRRD, TIFF stacks and raw files, over many slabs; inputs that cannot be
// read in slabs are read whole; the memory guard estimates and names the path taken. Uncompressed
// MetaImages are read in slabs too.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "endocast/errors.h"
#include "endocast/io.h"
#include "method/memory.h"
#include "endocast/stages/resample.h"
#include "io/slice_source.h"
#include "endocast/tiff.h"
#include "test_helpers.h"

namespace endocast {
namespace {

using testing::ScratchDir;

/// 23 x 17 x 19 voxels of varied int16 values (every voxel differs from its neighbours).
Volume<int16_t> varied(const Geometry& g) {
    Volume<int16_t> v(g);
    for (size_t i = 0; i < v.size(); ++i) v[i] = int16_t((i * 7919u) % 3001u) - 1000;
    return v;
}

Geometry odd_grid(bool identity) {
    Geometry g;
    g.dims = {23, 17, 19};
    g.spacing = {0.5, 0.7, 0.9};
    g.origin = {-3.0, 12.5, 40.0};
    if (!identity) g.direction = {-1, 0, 0, 0, 1, 0, 0, 0, -1};  // perpendicular, flipped
    return g;
}

void write_raw_nrrd(const Volume<int16_t>& v, const std::string& path) {
    auto w = open_slab_writer(path, v.geometry());
    w->write(v);
    w->finish();
}

/// Same voxels; the same grid, within `tol` mm (NIfTI stores its geometry as float32).
void expect_same(const ReadResult& got, const Volume<float>& want, const std::string& what, double tol = 0) {
    ASSERT_EQ(got.volume.dims(), want.dims()) << what;
    const Geometry &a = got.volume.geometry(), &b = want.geometry();
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(a.spacing[i], b.spacing[i], tol) << what;
        EXPECT_NEAR(a.origin[i], b.origin[i], tol) << what;
    }
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(a.direction[i], b.direction[i], tol) << what;
    EXPECT_EQ(0, std::memcmp(got.volume.data(), want.data(), want.size() * sizeof(float))) << what;
}

std::vector<ShrinkParams> shrinkings() {
    std::vector<ShrinkParams> out;
    ShrinkParams crop;
    crop.crop = CropBox{{3, 1, 2}, {20, 16, 18}};
    out.push_back(crop);
    for (int f : {2, 3, 4}) {  // 19 slices: a partial block at the far face for every factor
        ShrinkParams d;
        d.downsample = f;
        out.push_back(d);
        ShrinkParams both = crop;
        both.downsample = f;
        out.push_back(both);
    }
    return out;
}

TEST(ReadShrunk, SlabsGiveTheVoxelsAndGridOfShrinkingTheWholeVolume) {
    ScratchDir dir("slabs_same");
    const Volume<int16_t> flipped = varied(odd_grid(false)), plain = varied(odd_grid(true));
    write_raw_nrrd(flipped, dir / "raw.nrrd");
    write_volume(flipped, dir / "gz.nrrd");  // gzip, inflated in order
    write_volume(plain, dir / "stack%03d.tif");
    {
        std::ofstream raw(dir / "v.raw", std::ios::binary);
        raw.write("HEADER", 6);
        raw.write(reinterpret_cast<const char*>(plain.data()), std::streamsize(plain.size() * 2));
    }
    // Uncompressed MetaImages (metaimage_header.cpp): LOCAL, a big-endian data file after a
    // 6-byte header of its own, one file per slice (a pattern).
    {
        const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 23 17 19\nElementSpacing = 0.5 0.7 0.9\n"
                                 "Offset = -3 12.5 40\nTransformMatrix = -1 0 0 0 1 0 0 0 -1\nElementType = MET_SHORT\n";
        const auto bytes = [](const Volume<int16_t>& v, bool big) {
            std::string b(reinterpret_cast<const char*>(v.data()), v.size() * 2);
            if (big)
                for (size_t i = 0; i < b.size(); i += 2) std::swap(b[i], b[i + 1]);
            return b;
        };
        std::ofstream(dir / "local.mha", std::ios::binary) << head << "ElementDataFile = LOCAL\n" << bytes(flipped, false);
        std::ofstream(dir / "msb.mhd", std::ios::binary)
            << head << "BinaryDataByteOrderMSB = True\nHeaderSize = 6\nElementDataFile = msb.dat\n";
        std::ofstream(dir / "msb.dat", std::ios::binary) << "HEADER" << bytes(flipped, true);
        std::ofstream(dir / "pat.mhd", std::ios::binary) << head << "ElementDataFile = sl%02d.dat 0 18 1\n";
        const std::string all = bytes(flipped, false), slice_bytes = std::to_string(23 * 17 * 2);
        for (int z = 0; z < 19; ++z)
            std::ofstream(dir / ("sl" + std::string(z < 10 ? "0" : "") + std::to_string(z) + ".dat"), std::ios::binary)
                << all.substr(size_t(z) * 23 * 17 * 2, 23 * 17 * 2);
    }
    ReadOptions raw_opt;
    raw_opt.raw = RawOptions{plain.dims(), RawType::Int16, Endian::Little, 6, plain.geometry().spacing,
                             plain.geometry().origin};
    struct Case {
        std::vector<std::string> inputs;
        ReadOptions opt;
    };
    const std::vector<Case> cases = {{{dir / "raw.nrrd"}, {}},
                                     {{dir / "gz.nrrd"}, {}},
                                     {{dir / "stack%03d.tif"}, {}},
                                     {{dir / "v.raw"}, raw_opt},
                                     {{dir / "local.mha"}, {}},
                                     {{dir / "msb.mhd"}, {}},
                                     {{dir / "pat.mhd"}, {}}};
    for (const Case& c : cases) {
        const Volume<float> whole = read_volume(c.inputs, c.opt).volume;
        for (const ShrinkParams& s : shrinkings())
            for (int64_t slab : {int64_t(1), int64_t(23 * 17 * 5), kShrinkSlabVoxels}) {
                const std::string what = c.inputs[0] + " downsample " + std::to_string(s.downsample) +
                                         (s.crop ? " crop " + to_string(*s.crop) : "") + ", slabs of " +
                                         std::to_string(slab) + " voxels";
                bool slabs_checked = false;
                int64_t last_done = 0, calls = 0;
                ReadOptions opt = c.opt;
                opt.check_header = [&](const VolumeHeader& h) { slabs_checked = h.read_in_slabs; };
                opt.slab_progress = [&](int64_t done, int64_t total) {
                    EXPECT_GT(done, last_done);
                    EXPECT_EQ(total, s.crop ? s.crop->size()[2] : 19);
                    last_done = done;
                    ++calls;
                };
                const ReadResult r = read_shrunk(c.inputs, opt, s, slab);
                expect_same(r, shrink(whole, s), what);
                EXPECT_EQ(r.info.read_path, "slabs") << what;
                EXPECT_TRUE(slabs_checked) << what;
                EXPECT_EQ(last_done, s.crop ? s.crop->size()[2] : 19) << what;
                if (slab == 1) EXPECT_GT(calls, 3) << what;  // many slabs
                EXPECT_EQ(r.input_grid.dims, whole.dims()) << what;
            }
    }
}

TEST(ReadShrunk, InputsThatCannotBeReadInSlabsAreReadWholeWithTheSameResult) {
    ScratchDir dir("slabs_whole");
    const Volume<int16_t> v = varied(odd_grid(false));
    write_raw_nrrd(v, dir / "raw.nrrd");
    write_volume(v, dir / "v.mha");  // compressed, as write_volume writes a .mha
    write_volume(v, dir / "v.nii.gz");
    EXPECT_EQ(open_slice_source({dir / "v.mha"}), nullptr);
    // A short uncompressed MetaImage: not read in slabs; read whole, refused with what it holds.
    std::ofstream(dir / "short.mha", std::ios::binary)
        << "NDims = 3\nDimSize = 23 17 19\nElementType = MET_SHORT\nElementDataFile = LOCAL\n" << std::string(100, '\1');
    EXPECT_EQ(open_slice_source({dir / "short.mha"}), nullptr);
    ShrinkParams half;
    half.downsample = 2;
    try {
        read_shrunk({dir / "short.mha"}, {}, half);
        ADD_FAILURE() << "short.mha was read";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("short.mha: holds 100 bytes of voxel data"), std::string::npos) << e.what();
    }
    EXPECT_EQ(open_slice_source({dir / "v.nii.gz"}), nullptr);
    EXPECT_NE(open_slice_source({dir / "raw.nrrd"}), nullptr);
    ShrinkParams s;
    s.downsample = 2;
    const ReadResult slabs = read_shrunk({dir / "raw.nrrd"}, {}, s, 1);
    for (const char* name : {"v.mha", "v.nii.gz"}) {
        bool in_slabs = true;
        ReadOptions opt;
        opt.check_header = [&](const VolumeHeader& h) { in_slabs = h.read_in_slabs; };
        const ReadResult r = read_shrunk({dir / name}, opt, s);
        EXPECT_EQ(r.info.read_path, "whole") << name;
        EXPECT_FALSE(in_slabs) << name;
        expect_same(r, slabs.volume, name, 1e-5);
    }
    // Nothing to shrink: read whole, whatever the format.
    EXPECT_EQ(read_shrunk({dir / "raw.nrrd"}, {}, {}).info.read_path, "whole");
}

TEST(ReadShrunk, RefusesBadSlabsWithTheFileNamed) {
    ScratchDir dir("slabs_bad");
    const Volume<int16_t> v = varied(odd_grid(true));
    write_raw_nrrd(v, dir / "raw.nrrd");
    ShrinkParams s;
    s.downsample = 2;
    // A crop box outside the volume: InvalidParameter before any voxel is read.
    ShrinkParams outside;
    outside.crop = CropBox{{0, 0, 0}, {24, 17, 19}};
    testing::error_of<InvalidParameter>([&] { read_shrunk({dir / "raw.nrrd"}, {}, outside); });
    // A truncated raw NRRD is not read in slabs; the whole read says what is wrong.
    {
        std::ifstream in(dir / "raw.nrrd", std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        bytes.resize(bytes.size() - 100);
        std::ofstream(dir / "short.nrrd", std::ios::binary) << bytes;
    }
    EXPECT_EQ(open_slice_source({dir / "short.nrrd"}), nullptr);
    EXPECT_THROW(read_shrunk({dir / "short.nrrd"}, {}, s), IoError);
    // Gzip NRRD data that ends early, or holds more than the header says: IoError naming the file.
    {
        const Volume<int16_t> small = varied(odd_grid(true));
        write_volume(small, dir / "gz.nrrd");
        std::ifstream in(dir / "gz.nrrd", std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        std::ofstream(dir / "gz_short.nrrd", std::ios::binary) << bytes.substr(0, bytes.size() - 300);
        // A second gzip member after the data: the header's voxels and more.
        const size_t data_at = bytes.find("\n\n") + 2;
        std::ofstream(dir / "gz_long.nrrd", std::ios::binary) << bytes << bytes.substr(data_at);
    }
    ASSERT_NE(open_slice_source({dir / "gz_short.nrrd"}), nullptr);
    const std::string early = testing::error_of<IoError>([&] { read_shrunk({dir / "gz_short.nrrd"}, {}, s); });
    EXPECT_NE(early.find("gz_short.nrrd"), std::string::npos) << early;
    const std::string more = testing::error_of<IoError>([&] { read_shrunk({dir / "gz_long.nrrd"}, {}, s); });
    EXPECT_NE(more.find("more gzip data"), std::string::npos) << more;
    // Slices asked for out of order are inflated again from the start.
    {
        auto src = open_slice_source({dir / "gz.nrrd"});
        ASSERT_NE(src, nullptr);
        const Volume<float> whole = read_volume({dir / "gz.nrrd"}).volume;
        const size_t slice = 23 * 17;
        std::vector<float> got(slice * 2);
        for (int64_t z : {int64_t(7), int64_t(2), int64_t(17), int64_t(0)}) {
            src->read(z, 2, got.data());
            EXPECT_EQ(0, std::memcmp(got.data(), whole.data() + size_t(z) * slice, got.size() * sizeof(float))) << z;
        }
        EXPECT_THROW(src->read(18, 2, got.data()), InvalidParameter);
    }
    // Float raw data with a NaN: the voxel is named.
    std::vector<float> f(4 * 4 * 4, 1.0f);
    f[2 + 4 * (3 + 4 * 2)] = std::numeric_limits<float>::quiet_NaN();
    {
        std::ofstream raw(dir / "f.raw", std::ios::binary);
        raw.write(reinterpret_cast<const char*>(f.data()), std::streamsize(f.size() * 4));
    }
    ReadOptions opt;
    opt.raw = RawOptions{{4, 4, 4}, RawType::Float32, Endian::Little, 0, {1, 1, 1}, {0, 0, 0}};
    const std::string m = testing::error_of<InvalidParameter>([&] { read_shrunk({dir / "f.raw"}, opt, s, 1); });
    for (const char* want : {"f.raw", "(2, 3, 2)", "NaN"}) EXPECT_NE(m.find(want), std::string::npos) << m;
    // A raw file too short for its size: IoError naming it, from the header check.
    std::ofstream(dir / "short.raw", std::ios::binary) << "abc";
    opt.raw->type = RawType::UInt8;
    const std::string m2 = testing::error_of<IoError>([&] { read_shrunk({dir / "short.raw"}, opt, s); });
    EXPECT_NE(m2.find("short.raw"), std::string::npos) << m2;
}

TEST(MemoryGuard, MicroCtDownsampledInSlabsFitsAndTheMessageNamesThePath) {
    VolumeHeader h;
    h.geometry.dims = {2048, 2048, 1500};
    h.stored_voxel_bytes = 2;
    ShrinkParams s;
    s.downsample = 4;
    const Geometry work = shrunk_geometry(h.geometry, s);
    const uint64_t whole = estimate_extract_memory_bytes(h.geometry.dims, 2, work.dims);
    h.read_in_slabs = true;
    const uint64_t slabs =
        estimate_extract_memory_bytes(h.geometry.dims, 2, work.dims, shrink_slab_bytes(h, s));
    EXPECT_GT(whole, uint64_t(50) << 30);  // 6.3 G voxels as float and more
    EXPECT_LT(slabs, uint64_t(4) << 30);   // 98 M voxels of work, one 256 MB slab
    EXPECT_GT(slabs, work.voxel_count() * 20);
    EXPECT_NO_THROW(check_extract_memory(h, s, 4096.0, "scan/slice%04d.tif"));
    const std::string in_slabs =
        testing::error_of<OutOfMemory>([&] { check_extract_memory(h, s, 1000.0, "scan/slice%04d.tif"); });
    EXPECT_NE(in_slabs.find("in slabs"), std::string::npos) << in_slabs;
    h.read_in_slabs = false;
    const std::string read_whole =
        testing::error_of<OutOfMemory>([&] { check_extract_memory(h, s, 4096.0, "scan.nii.gz"); });
    for (const char* want : {"scan.nii.gz", "whole volume first", "read in slabs", "--crop"})
        EXPECT_NE(read_whole.find(want), std::string::npos) << want << " in " << read_whole;
}

}  // namespace
}  // namespace endocast
