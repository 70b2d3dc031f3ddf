#include <gtest/gtest.h>

#include <random>

#include "method/memory.h"
#include "endocast/pipeline.h"
#include "endocast/stages/resample.h"

using namespace endocast;

namespace {

/// Random voxels on a rotated, flipped, anisotropic grid.
Volume<float> random_volume(Dims d, uint32_t seed) {
    Geometry g;
    g.dims = d;
    g.spacing = {0.5, 0.8, 1.7};
    g.origin = {-12.5, 40.0, 7.25};
    g.direction = {0, -1, 0, 1, 0, 0, 0, 0, -1};
    Volume<float> v(g);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1000.0f, 3000.0f);
    for (size_t i = 0; i < v.size(); ++i) v[i] = u(rng);
    return v;
}

void expect_near(const Vec3& a, const Vec3& b, double tol, const std::string& what) {
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], b[i], tol) << what << " axis " << i;
}

}  // namespace

TEST(Crop, MatchesBruteForceAndKeepsWorldPositions) {
    const Volume<float> v = random_volume({13, 9, 7}, 1);
    const CropBox box{{2, 1, 3}, {11, 9, 5}};
    const Volume<float> c = crop(v, box);
    ASSERT_EQ(c.dims(), (Dims{9, 8, 2}));
    EXPECT_EQ(c.geometry().spacing, v.geometry().spacing);
    EXPECT_EQ(c.geometry().direction, v.geometry().direction);
    for (int64_t z = 0; z < 2; ++z)
        for (int64_t y = 0; y < 8; ++y)
            for (int64_t x = 0; x < 9; ++x) {
                ASSERT_EQ(c(x, y, z), v(x + 2, y + 1, z + 3));
                expect_near(c.geometry().index_to_world(x, y, z),
                            v.geometry().index_to_world(x + 2, y + 1, z + 3), 1e-9, "crop");
            }
    // The whole volume is a copy.
    const Volume<float> all = crop(v, {{0, 0, 0}, v.dims()});
    EXPECT_EQ(all.buffer(), v.buffer());
    EXPECT_EQ(to_string(box), "2 1 3 11 9 5");
}

// uncrop puts the box back where crop took it from and fills the rest; a part of the wrong size
// is refused.
TEST(Crop, UncropIsTheInverseOfCrop) {
    const Volume<float> f = random_volume({13, 9, 7}, 3);
    Volume<uint8_t> v(f.geometry());
    for (size_t i = 0; i < v.size(); ++i) v[i] = uint8_t(int(f[i]) & 0x7f);
    const CropBox box{{2, 1, 3}, {11, 9, 5}};
    const Volume<uint8_t> back = uncrop(crop(v, box), v.geometry(), box, 200);
    ASSERT_EQ(back.dims(), v.dims());
    EXPECT_EQ(back.geometry().origin, v.geometry().origin);
    for (int64_t z = 0; z < 7; ++z)
        for (int64_t y = 0; y < 9; ++y)
            for (int64_t x = 0; x < 13; ++x) {
                const bool in = x >= 2 && x < 11 && y >= 1 && y < 9 && z >= 3 && z < 5;
                ASSERT_EQ(back(x, y, z), in ? v(x, y, z) : 200) << x << " " << y << " " << z;
            }
    EXPECT_THROW(uncrop(crop(v, box), v.geometry(), CropBox{{2, 1, 3}, {11, 9, 6}}, 0), InvalidParameter);
    EXPECT_THROW(uncrop(crop(v, box), v.geometry(), CropBox{{2, 1, 3}, {11, 9, 8}}, 0), InvalidParameter);
}

TEST(Crop, RejectsBoxesOutsideTheVolume) {
    const Volume<float> v = random_volume({4, 4, 4}, 2);
    for (const CropBox& b : {CropBox{{0, 0, 0}, {5, 4, 4}}, CropBox{{-1, 0, 0}, {4, 4, 4}},
                             CropBox{{2, 0, 0}, {2, 4, 4}}, CropBox{{3, 0, 0}, {1, 4, 4}}}) {
        try {
            crop(v, b);
            ADD_FAILURE() << "accepted " << to_string(b);
        } catch (const InvalidParameter& e) {
            EXPECT_NE(std::string(e.what()).find(to_string(b)), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("4 x 4 x 4"), std::string::npos) << e.what();
        }
    }
}

TEST(Downsample, MatchesBruteForceBlockMeansAndBlockCentres) {
    for (int f : {1, 2, 3}) {
        const Volume<float> v = random_volume({11, 8, 7}, 3 + f);
        const Volume<float> d = downsample(v, f);
        const Dims want{(11 + f - 1) / f, (8 + f - 1) / f, (7 + f - 1) / f};
        ASSERT_EQ(d.dims(), want) << f;
        for (int a = 0; a < 3; ++a)
            EXPECT_DOUBLE_EQ(d.geometry().spacing[a], v.geometry().spacing[a] * f);
        for (int64_t z = 0; z < want[2]; ++z)
            for (int64_t y = 0; y < want[1]; ++y)
                for (int64_t x = 0; x < want[0]; ++x) {
                    double sum = 0;
                    Vec3 centre{0, 0, 0};
                    int n = 0;
                    for (int64_t k = z * f; k < (z + 1) * f; ++k)
                        for (int64_t j = y * f; j < (y + 1) * f; ++j)
                            for (int64_t i = x * f; i < (x + 1) * f; ++i) {
                                if (!v.contains(i, j, k)) continue;
                                sum += v(i, j, k);
                                const Vec3 w = v.geometry().index_to_world(i, j, k);
                                for (int a = 0; a < 3; ++a) centre[a] += w[a];
                                ++n;
                            }
                    ASSERT_NEAR(d(x, y, z), sum / n, 1e-3) << f << " at " << x << "," << y << "," << z;
                    // Full blocks: the output voxel sits at the centre of its block.
                    if (n == f * f * f) {
                        for (auto& c : centre) c /= n;
                        expect_near(d.geometry().index_to_world(x, y, z), centre, 1e-9, "block centre");
                    }
                }
    }
    EXPECT_THROW(downsample(random_volume({2, 2, 2}, 9), 0), InvalidParameter);
    // A factor larger than the volume leaves one voxel per axis.
    EXPECT_EQ(downsample(random_volume({2, 3, 1}, 9), 4).dims(), (Dims{1, 1, 1}));
}

TEST(Shrink, CropThenDownsampleAndGeometryAgree) {
    const Volume<float> v = random_volume({20, 18, 16}, 11);
    ShrinkParams s;
    s.crop = CropBox{{3, 2, 1}, {17, 18, 16}};
    s.downsample = 2;
    const Volume<float> out = shrink(v, s);
    const Volume<float> ref = downsample(crop(v, *s.crop), 2);
    EXPECT_EQ(out.buffer(), ref.buffer());
    const Geometry g = shrunk_geometry(v.geometry(), s);
    EXPECT_EQ(g.dims, out.dims());
    expect_near(g.origin, out.geometry().origin, 1e-12, "origin");
    s.crop = CropBox{{0, 0, 0}, {21, 18, 16}};
    EXPECT_THROW(shrink(v, s), InvalidParameter);
}

TEST(Shrink, BoundingBoxAboveThresholdWithMargin) {
    Geometry g;
    g.dims = {10, 10, 10};
    Volume<float> v(g, 0.0f);
    v(3, 4, 5) = 10;
    v(6, 4, 7) = 10;
    const CropBox b = bounding_box_above(v, 5, 2);
    EXPECT_EQ(b.lo, (Dims{1, 2, 3}));
    EXPECT_EQ(b.hi, (Dims{9, 7, 10}));
    EXPECT_THROW(bounding_box_above(v, 50, 2), NoResult);
}

TEST(MemoryGuard, EstimateGrowsWithTheGridAndShrinkingHelps) {
    const Dims big{512, 512, 400}, half{256, 256, 200};
    const uint64_t full = estimate_extract_memory_bytes(big, 2, big);
    const uint64_t down = estimate_extract_memory_bytes(big, 2, half);
    EXPECT_GT(full, 100u * 512 * 512 * 400 / 10);
    EXPECT_LT(down, full);  // reading the full grid still counts
    EXPECT_LT(estimate_extract_memory_bytes(half, 2, half), full / 4);
    EXPECT_GT(estimate_extract_memory_bytes(big, 4, big), full - 1);
    // Saturates instead of overflowing.
    const Dims huge{int64_t{1} << 40, int64_t{1} << 40, int64_t{1} << 40};
    EXPECT_EQ(estimate_extract_memory_bytes(huge, 2, huge), UINT64_MAX);
}

TEST(MemoryGuard, ChecksAgainstMaxMemoryWithAClearMessage) {
    VolumeHeader h;
    h.geometry.dims = {512, 512, 400};
    h.stored_voxel_bytes = 2;
    try {
        check_extract_memory(h, {}, 100.0, "scan.nrrd");
        ADD_FAILURE() << "no exception";
    } catch (const OutOfMemory& e) {
        const std::string m = e.what();
        for (const char* s : {"scan.nrrd", "512 x 512 x 400", "100 MB", "--max-memory", "--crop",
                              "--downsample"})
            EXPECT_NE(m.find(s), std::string::npos) << s << " in " << m;
    }
    h.geometry.dims = {10, 10, 10};
    EXPECT_NO_THROW(check_extract_memory(h, {}, 200.0, "small.nrrd"));
    EXPECT_THROW(check_extract_memory(h, {}, -1.0, "small.nrrd"), InvalidParameter);
    ShrinkParams s;
    s.crop = CropBox{{0, 0, 0}, {11, 10, 10}};
    EXPECT_THROW(check_extract_memory(h, s, 200.0, "small.nrrd"), InvalidParameter);
    const MemoryLimit m = available_memory();
    EXPECT_GT(m.bytes, 0u);
    EXPECT_FALSE(m.source.empty());
}
