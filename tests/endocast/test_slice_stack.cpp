// Gantry tilt and mixed slice spacing (slice_stack.h): the stack's measures, the resampling against
// a function it must reproduce exactly, phantoms written as tilted and mixed-spacing DICOM series
// (ECV and surface against the phantom's truth, in patient coordinates), and the real
// ge-tilt-dicom (its bone where an independent placement of each slice puts it).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../common/dicom_writer.h"
#include "endocast/io.h"
#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "io/slice_stack.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::error_of;
using endocast::testing::ScratchDir;
namespace fs = std::filesystem;

namespace {

const double kPi = 3.14159265358979323846;

std::vector<Vec3> stack_at(const std::vector<double>& z, const Vec3& offset_per_mm = {0, 0, 0}) {
    std::vector<Vec3> p;
    for (double v : z) p.push_back({offset_per_mm[0] * v, offset_per_mm[1] * v, v});
    return p;
}

std::vector<double> steps_to_positions(const std::vector<double>& steps) {
    std::vector<double> z{0};
    for (double s : steps) z.push_back(z.back() + s);
    return z;
}

}  // namespace

TEST(SliceStack, RegularStackAlongTheNormalNeedsNothing) {
    const SliceStack st = analyze_slice_stack(stack_at({0, 2, 4, 6, 8}), {1, 0, 0}, {0, 1, 0}, 0.5, "s");
    EXPECT_FALSE(st.needs_resampling());
    EXPECT_DOUBLE_EQ(st.tilt_deg, 0);
    ASSERT_EQ(st.runs.size(), 1u);
    EXPECT_NEAR(st.runs[0].step_mm, 2.0, 1e-12);
    EXPECT_NEAR(st.min_run_step_mm, 2.0, 1e-12);
    // Positions rounded as scanners write them stay regular.
    const SliceStack r = analyze_slice_stack(stack_at({0, 2.001, 3.999, 6.0004, 8}), {1, 0, 0}, {0, 1, 0}, 0.5, "s");
    EXPECT_FALSE(r.needs_resampling());
}

TEST(SliceStack, GantryTiltIsTheAngleBetweenTheStackAxisAndTheNormal) {
    // Slices tilted by 18.5 deg about x (the column direction leans), positions stepping along z.
    const double t = 18.5 * kPi / 180;
    const Vec3 col{0, std::cos(t), -std::sin(t)};
    const SliceStack st = analyze_slice_stack(stack_at({0, 4, 8, 12, 16, 20}), {1, 0, 0}, col, 0.49, "s");
    EXPECT_TRUE(st.tilted);
    EXPECT_TRUE(st.regular);
    EXPECT_NEAR(st.tilt_deg, 18.5, 1e-9);
    EXPECT_NEAR(st.shear_mm, 20 * std::sin(t), 1e-9);
    EXPECT_NEAR(st.min_run_step_mm, 4 * std::cos(t), 1e-9);
    EXPECT_TRUE(st.needs_resampling());
}

TEST(SliceStack, TwoStacksOfDifferentSpacingAreNotAGap) {
    // ge-tilt-dicom's pattern: 4 mm steps, 1.08 mm where the stacks meet, 7 mm steps.
    const SliceStack st = analyze_slice_stack(stack_at(steps_to_positions({4, 4, 4, 4, 1.08, 7, 7, 7, 7})), {1, 0, 0},
                                              {0, 1, 0}, 0.5, "s");
    EXPECT_FALSE(st.regular);
    EXPECT_FALSE(st.tilted);
    ASSERT_EQ(st.runs.size(), 3u);
    EXPECT_NEAR(st.runs[0].step_mm, 4, 1e-12);
    EXPECT_EQ(st.runs[0].slices, 5u);
    EXPECT_NEAR(st.runs[2].step_mm, 7, 1e-12);
    EXPECT_NEAR(st.min_run_step_mm, 4, 1e-12);  // the 1.08 mm junction is not a run of even spacing
    ASSERT_EQ(st.changes.size(), 3u);
    EXPECT_NE(st.changes[0].find("5 slices 4 mm apart"), std::string::npos) << st.changes[0];
    // A step 1.5 x its neighbour at the end, not a whole multiple: uneven, not a gap.
    EXPECT_TRUE(analyze_slice_stack(stack_at(steps_to_positions({2, 2, 2, 2, 3})), {1, 0, 0}, {0, 1, 0}, 0.5, "s")
                    .needs_resampling());
}

TEST(SliceStack, AMissingOrDuplicatedSliceIsAnErrorThatSaysWhere) {
    const std::vector<std::string> files{"a.dcm", "b.dcm", "c.dcm", "d.dcm", "e.dcm", "f.dcm"};
    const std::string gap = error_of<IoError>([&] {
        analyze_slice_stack(stack_at(steps_to_positions({2, 2, 4, 2, 2})), {1, 0, 0}, {0, 1, 0}, 0.5, "series", files);
    });
    for (const char* s : {"series", "c.dcm", "d.dcm", "4 mm apart", "expected 2 mm", "slices are missing"})
        EXPECT_NE(gap.find(s), std::string::npos) << s << " in: " << gap;
    const std::string end_gap = error_of<IoError>([&] {
        analyze_slice_stack(stack_at(steps_to_positions({2, 2, 2, 2, 4})), {1, 0, 0}, {0, 1, 0}, 0.5, "series", files);
    });
    EXPECT_NE(end_gap.find("e.dcm"), std::string::npos) << end_gap;
    EXPECT_NE(end_gap.find("slices are missing"), std::string::npos) << end_gap;
    const std::string dup = error_of<IoError>([&] {
        analyze_slice_stack(stack_at(steps_to_positions({2, 2, 0, 2, 2})), {1, 0, 0}, {0, 1, 0}, 0.5, "series", files);
    });
    EXPECT_NE(dup.find("a slice is duplicated"), std::string::npos) << dup;
    // A tilted stack with a missing slice: the gap is measured along the normal.
    const double t = 20 * kPi / 180;
    const std::string tilted_gap = error_of<IoError>([&] {
        analyze_slice_stack(stack_at(steps_to_positions({2, 2, 4, 2, 2})), {1, 0, 0}, {0, std::cos(t), std::sin(t)},
                            0.5, "series", files);
    });
    EXPECT_NE(tilted_gap.find("slices are missing"), std::string::npos) << tilted_gap;
}

// Trilinear interpolation reproduces a linear function exactly: every voxel of the regular grid
// that the slices cover holds f at that voxel's world position, for a tilted, unevenly spaced stack.
TEST(SliceStack, ResamplingReproducesALinearFunctionOfPatientPosition) {
    const double t = 15 * kPi / 180;
    const Vec3 r{1, 0, 0}, c{0, std::cos(t), std::sin(t)};
    const std::vector<double> z = steps_to_positions({1.5, 1.5, 1.5, 3, 3, 3, 0.75});
    std::vector<Vec3> pos;
    for (double v : z) pos.push_back({-20.0, 7.5, v});
    auto f = [](const Vec3& w) { return 3.0 * w[0] - 2.0 * w[1] + 5.0 * w[2] + 11.0; };
    Geometry g;
    g.dims = {12, 16, int64_t(z.size())};
    g.spacing = {0.8, 0.6, 1.0};
    g.origin = pos.front();
    g.direction = {r[0], c[0], 0, r[1], c[1], -std::sin(t), r[2], c[2], std::cos(t)};
    Volume<float> v(g, 0.f);
    for (int64_t k = 0; k < g.dims[2]; ++k)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                Vec3 w;
                for (int a = 0; a < 3; ++a) w[a] = pos[size_t(k)][a] + x * g.spacing[0] * r[a] + y * g.spacing[1] * c[a];
                v(x, y, k) = float(f(w));
            }
    const SliceStack st = analyze_slice_stack(pos, r, c, 0.6, "s");
    ASSERT_TRUE(st.needs_resampling());
    SliceResampling rp;
    rp.outside = -1e6f;
    const Volume<float> o = resample_slice_stack(v, pos, st, rp);
    const Geometry& og = o.geometry();
    EXPECT_NEAR(og.spacing[2], 1.5 * std::cos(t), 1e-9);  // the smallest run of even steps, along the normal
    EXPECT_GT(og.dims[1], g.dims[1]);                       // wider along c by the shear
    size_t covered = 0;
    double worst = 0;
    for (int64_t k = 0; k < og.dims[2]; ++k)
        for (int64_t y = 0; y < og.dims[1]; ++y)
            for (int64_t x = 0; x < og.dims[0]; ++x) {
                if (o(x, y, k) < -1e5f) continue;
                ++covered;
                worst = std::max(worst, std::fabs(double(o(x, y, k)) - f(og.index_to_world(double(x), double(y), double(k)))));
            }
    EXPECT_GT(covered, o.size() / 2);
    EXPECT_LT(worst, 2e-3);
    // The grid is orthonormal, right-handed, its third axis the slices' normal.
    EXPECT_NEAR(og.direction_determinant(), 1.0, 1e-12);
    EXPECT_NEAR(og.direction[8], std::cos(t), 1e-12);
}

// ---- Phantoms written as clinical DICOM series.

namespace {

const PhantomResult& human_phantom() {
    static const PhantomResult ph = generate_phantom(PhantomParams{});
    return ph;
}

struct Fit {
    double ecv_ratio = 0, mean_mm = 0;
};

Fit extract_and_compare(const Volume<float>& ct, const PhantomResult& ph) {
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    const ExtractionResult r = extract_endocast(ct, p);
    const std::vector<double> w = endocast::testing::vertex_areas(r.mesh);
    double sum = 0, ws = 0;
    for (size_t v = 0; v < r.mesh.vertices.size(); ++v) {
        const auto& q = r.mesh.vertices[v];
        sum += w[v] * std::fabs(phantom_cavity_signed_distance(ph, {q[0], q[1], q[2]}));
        ws += w[v];
    }
    return {r.ecv_ml / ph.true_ecv_ml, sum / ws};
}

}  // namespace

// The case: a tilted series read as a stack along the normal grows by 1/cos(tilt) and
// lies mm away from the anatomy; resampled, its ECV and surface match the truth in patient space.
TEST(SliceStackPhantom, TiltedSeriesGivesTheTrueVolumeAndSurfaceInPatientCoordinates) {
    const PhantomResult& ph = human_phantom();
    const Geometry& g = ph.ct.geometry();
    // Table positions 2 mm apart from low enough that the first tilted slice passes under the
    // phantom's far side (the slices rise by their length x sin(tilt)) to its top.
    std::vector<double> z;
    const double rise = double(g.dims[1]) * g.spacing[1] * std::tan(20 * kPi / 180);
    const double z0 = g.origin[2] - rise, z1 = g.origin[2] + double(g.dims[2] - 1) * g.spacing[2];
    for (double v = z0; v <= z1 + 1e-9; v += 2.0) z.push_back(v);
    const ScratchDir dir("tilt");
    const endocast::testing::DicomSeriesSpec spec = endocast::testing::tilted_series_over(ph.ct, 20.0, z);
    endocast::testing::write_dicom_series_from((dir.path() / "tilt").string(), spec, ph.ct, -1024);

    const ReadResult in = read_volume({(dir.path() / "tilt").string()});
    EXPECT_TRUE(in.info.resampled);
    EXPECT_NEAR(in.info.gantry_tilt_deg, 20.0, 0.01);
    ASSERT_EQ(in.info.warnings.size(), 1u);
    EXPECT_NE(in.info.warnings[0].find("gantry tilt 20 deg"), std::string::npos) << in.info.warnings[0];
    EXPECT_NEAR(in.volume.geometry().spacing[2], 2.0 * std::cos(20 * kPi / 180), 1e-6);
    const Fit fit = extract_and_compare(in.volume, ph);
    std::printf("tilted 20 deg, resampled: ECV ratio %.4f, mean distance %.3f mm\n", fit.ecv_ratio, fit.mean_mm);
    EXPECT_NEAR(fit.ecv_ratio, 1.0, 0.01);
    EXPECT_LE(fit.mean_mm, 0.3);

    // The same files stacked along the normal (what readers without tilt handling do).
    ReadOptions stacked;
    stacked.resample_slices = false;
    const ReadResult raw = read_volume({(dir.path() / "tilt").string()}, stacked);
    EXPECT_FALSE(raw.info.resampled);
    const Fit bad = extract_and_compare(raw.volume, ph);
    std::printf("tilted 20 deg, stacked along the normal: ECV ratio %.4f, mean distance %.3f mm\n", bad.ecv_ratio,
                bad.mean_mm);
    EXPECT_GT(std::fabs(bad.ecv_ratio - 1.0), 0.03);
    EXPECT_GT(bad.mean_mm, 3.0);

    // The same slices converted with the tilt kept as a shear (slice axis along the table, as
    // dcm2niix or Slicer can write them): a sheared NRRD reads onto the same grid, same result.
    Volume<float> sheared = raw.volume;
    Geometry& sg = sheared.geometry();
    const double t = 20 * kPi / 180;
    const Vec3 c{0, std::cos(t), std::sin(t)};
    sg.origin = spec.positions.front();
    sg.spacing = {spec.column_spacing_mm, spec.row_spacing_mm, 2.0};
    sg.direction = {1, 0, 0, 0, c[1], 0, 0, c[2], 1};  // columns: row, column, table axis
    const std::string nrrd = (dir.path() / "sheared.nrrd").string();
    write_volume(sheared, nrrd);
    const ReadResult fromfile = read_volume({nrrd});
    EXPECT_TRUE(fromfile.info.resampled);
    EXPECT_NEAR(fromfile.info.gantry_tilt_deg, 20.0, 0.01);
    ASSERT_EQ(fromfile.volume.dims(), in.volume.dims());
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(fromfile.volume.geometry().origin[a], in.volume.geometry().origin[a], 1e-3);
    double worst = 0;
    for (size_t i = 0; i < in.volume.size(); ++i) worst = std::max(worst, double(std::fabs(fromfile.volume[i] - in.volume[i])));
    EXPECT_LT(worst, 0.5) << "the sheared file and the DICOM series resample to different voxels";
}

TEST(SliceStackPhantom, MixedSpacingSeriesIsResampledOntoTheSmallestEvenStep) {
    const PhantomResult& ph = human_phantom();
    const Geometry& g = ph.ct.geometry();
    // 1 mm slices over the lower half (the skull base), 3 mm above, files in reverse order.
    std::vector<double> z;
    const double z0 = g.origin[2], z1 = g.origin[2] + double(g.dims[2] - 1) * g.spacing[2], mid = 0.5 * (z0 + z1);
    for (double v = z0; v < mid; v += 1.0) z.push_back(v);
    for (double v = z.back() + 2.0; v <= z1 + 1e-9; v += 3.0) z.push_back(v);
    const ScratchDir dir("mixed");
    endocast::testing::DicomSeriesSpec spec = endocast::testing::tilted_series_over(ph.ct, 0.0, z);
    std::vector<size_t> order;
    for (size_t i = z.size(); i-- > 0;) order.push_back(i);
    endocast::testing::write_dicom_series_from((dir.path() / "mixed").string(), spec, ph.ct, -1024, order);
    const ReadResult in = read_volume({(dir.path() / "mixed").string()});
    EXPECT_TRUE(in.info.resampled);
    EXPECT_DOUBLE_EQ(in.info.gantry_tilt_deg, 0);
    EXPECT_NEAR(in.volume.geometry().spacing[2], 1.0, 1e-6);
    EXPECT_EQ(in.info.slice_runs.size(), 3u);
    ASSERT_EQ(in.info.warnings.size(), 1u);
    EXPECT_NE(in.info.warnings[0].find("uneven slice spacing"), std::string::npos) << in.info.warnings[0];
    const Fit fit = extract_and_compare(in.volume, ph);
    std::printf("mixed 1/3 mm: ECV ratio %.4f, mean distance %.3f mm\n", fit.ecv_ratio, fit.mean_mm);
    EXPECT_NEAR(fit.ecv_ratio, 1.0, 0.01);
    EXPECT_LE(fit.mean_mm, 0.4);

    // A slice removed inside the 1 mm stack is a real gap.
    fs::remove(dir.path() / "mixed" / "IM0100.dcm");  // slice 19 from the bottom
    const std::string e = error_of<IoError>([&] { read_volume({(dir.path() / "mixed").string()}); });
    EXPECT_NE(e.find("slices are missing"), std::string::npos) << e;
    EXPECT_NE(e.find("expected 1 mm"), std::string::npos) << e;
}

// ---- The real tilted, mixed-spacing scan.

namespace {

std::string header_value(const std::vector<char>& b, uint16_t group, uint16_t element) {
    // Explicit or implicit VR little endian, short string values in the header.
    const char tag[4] = {char(group & 0xFF), char(group >> 8), char(element & 0xFF), char(element >> 8)};
    for (size_t i = 132; i + 8 <= std::min<size_t>(b.size(), 65536); ++i) {
        if (std::memcmp(&b[i], tag, 4) != 0) continue;
        const bool expl = std::isupper(static_cast<unsigned char>(b[i + 4])) && std::isupper(static_cast<unsigned char>(b[i + 5]));
        const size_t len = expl ? size_t(uint8_t(b[i + 6]) | (uint8_t(b[i + 7]) << 8))
                                : size_t(uint8_t(b[i + 4]) | (uint8_t(b[i + 5]) << 8) | (uint8_t(b[i + 6]) << 16));
        std::string v(b.begin() + long(i + 8), b.begin() + long(std::min(b.size(), i + 8 + len)));
        while (!v.empty() && (v.back() == ' ' || v.back() == '\0')) v.pop_back();
        return v;
    }
    return {};
}

std::vector<double> numbers(const std::string& s) {
    std::vector<double> v;
    std::stringstream ss(s);
    std::string x;
    while (std::getline(ss, x, '\\')) v.push_back(std::stod(x));
    return v;
}

}  // namespace

// The bone's centroid in the resampled volume against each slice placed on its own (its
// ImagePositionPatient and orientation read here, each slice weighted by the slab it stands for):
// the same point in patient space. Stacked along the normal, it is ~20 mm away.
TEST(SliceStackRealData, GeTiltBoneLiesWhereItsSlicesPutIt) {
    const std::string dir = std::string(ENDOCAST_SHARED_DATA) + "/ge-tilt-dicom";
    if (!fs::exists(dir)) GTEST_SKIP() << "../shared/data/ge-tilt-dicom not found";
    const ReadResult in = read_volume({dir});
    EXPECT_TRUE(in.info.resampled);
    EXPECT_NEAR(in.info.gantry_tilt_deg, 18.5, 0.05);
    EXPECT_EQ(in.info.slice_runs.size(), 3u);
    // Centroids of the mass above air, (HU + 1024)+: linear in the values, so the interpolation
    // keeps it (a threshold would not: between 7 mm slices the bone's extent is the isovalue's).
    auto mass = [](float hu) { return std::max(0.0, double(hu) + 1024.0); };
    auto centroid = [&](const Volume<float>& v) {
        Vec3 c{0, 0, 0};
        double n = 0;
        for (int64_t k = 0; k < v.nz(); ++k)
            for (int64_t y = 0; y < v.ny(); ++y)
                for (int64_t x = 0; x < v.nx(); ++x) {
                    const double m = mass(v(x, y, k));
                    if (m == 0) continue;
                    const Vec3 w = v.geometry().index_to_world(double(x), double(y), double(k));
                    for (int a = 0; a < 3; ++a) c[a] += m * w[a];
                    n += m;
                }
        for (double& a : c) a /= n;
        return c;
    };
    const Vec3 resampled = centroid(in.volume);

    ReadOptions stacked;
    stacked.resample_slices = false;
    const ReadResult raw = read_volume({dir}, stacked);
    ASSERT_EQ(raw.volume.nz(), 28);
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().extension() == ".dcm") files.push_back(e.path().string());
    std::sort(files.begin(), files.end());  // 01.dcm .. 28.dcm: ascending position
    ASSERT_EQ(files.size(), 28u);
    std::vector<Vec3> ipp;
    std::vector<double> iop, px;
    for (const auto& f : files) {
        std::ifstream s(f, std::ios::binary);
        const std::vector<char> b((std::istreambuf_iterator<char>(s)), std::istreambuf_iterator<char>());
        const std::vector<double> p = numbers(header_value(b, 0x20, 0x32));
        ASSERT_EQ(p.size(), 3u) << f;
        ipp.push_back({p[0], p[1], p[2]});
        iop = numbers(header_value(b, 0x20, 0x37));
        px = numbers(header_value(b, 0x28, 0x30));
    }
    ASSERT_EQ(iop.size(), 6u);
    ASSERT_EQ(px.size(), 2u);
    const Vec3 r{iop[0], iop[1], iop[2]}, c{iop[3], iop[4], iop[5]};
    const Vec3 n{r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
    auto along = [&](size_t k) { return ipp[k][0] * n[0] + ipp[k][1] * n[1] + ipp[k][2] * n[2]; };
    Vec3 direct{0, 0, 0};
    double wsum = 0;
    for (size_t k = 0; k < 28; ++k) {
        // The slab slice k stands for along the normal: halfway to each neighbour (the first and
        // last: to the grid's ends, as the resampled grid spans first to last slice).
        const double lo = k == 0 ? along(0) : 0.5 * (along(k - 1) + along(k));
        const double hi = k == 27 ? along(27) : 0.5 * (along(k) + along(k + 1));
        const double slab = hi - lo;
        for (int64_t y = 0; y < raw.volume.ny(); ++y)
            for (int64_t x = 0; x < raw.volume.nx(); ++x)
                if (const double m = mass(raw.volume(x, y, int64_t(k))); m > 0) {
                    // PixelSpacing: between rows (along c), then between columns (along r).
                    for (int a = 0; a < 3; ++a)
                        direct[a] += slab * m * (ipp[k][a] + double(x) * px[1] * r[a] + double(y) * px[0] * c[a]);
                    wsum += slab * m;
                }
    }
    for (double& a : direct) a /= wsum;
    const Vec3 naive = centroid(raw.volume);
    const double err = std::hypot(resampled[0] - direct[0], resampled[1] - direct[1], resampled[2] - direct[2]);
    const double naive_err = std::hypot(naive[0] - direct[0], naive[1] - direct[1], naive[2] - direct[2]);
    std::printf("ge-tilt bone centroid: resampled (%.2f, %.2f, %.2f), slices placed one by one (%.2f, %.2f, %.2f): "
                "%.2f mm apart; stacked along the normal %.2f mm apart\n",
                resampled[0], resampled[1], resampled[2], direct[0], direct[1], direct[2], err, naive_err);
    EXPECT_LT(err, 1.0);
    EXPECT_GT(naive_err, 10.0);
}

TEST(SliceStack, AShearedGridTooLargeToResampleIsAnErrorNotAnOverflow) {
    // A sheared MetaImage whose x spacing is 1e-30 mm: its slices lie 0.7 mm apart along x, so the
    // resampled grid would be 7e29 voxels wide (found by fuzz_mhd as a float-to-int64 overflow).
    const ScratchDir dir("sheared_huge");
    const std::string path = (dir.path() / "sheared.mhd").string();
    std::ofstream(path, std::ios::binary) << "ObjectType = Image\nNDims = 3\nBinaryData = True\n"
                                             "TransformMatrix = 1 0 0 0 1 0 0.6 0 0.8\nOffset = 0 0 0\n"
                                             "ElementSpacing = 1e-30 1 1\nDimSize = 2 2 3\n"
                                             "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
                                          << std::string(12, '\x01');
    const std::string e = error_of<IoError>([&] { read_volume({path}); });
    EXPECT_NE(e.find(path), std::string::npos) << e;
    EXPECT_NE(e.find("2^40"), std::string::npos) << e;
}
