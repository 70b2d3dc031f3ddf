// endocast::extract (endocast.h), the whole method in one call: a file and the same CT in memory
// give the same mesh, the path and the checks are reported, progress comes in order, and bad
// sources are refused.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "endocast/endocast.h"
#include "endocast/phantom.h"
#include "meshpost/cgal/self_intersections.h"
#include "test_helpers.h"

using namespace endocast;

namespace {

PhantomResult small_phantom() {
    PhantomParams p;
    p.spacing = {2.0, 2.0, 2.0};
    return generate_phantom(p);
}

struct Recorder : Progress {
    std::vector<std::string> stages;
    int plans = 0;
    void planned(const ExtractPlan&) override { ++plans; }
    void stage(const std::string& s) override { stages.push_back(s); }
};

}  // namespace

TEST(Extract, AFileAndTheSameCtInMemoryGiveTheSameMesh) {
    const PhantomResult ph = small_phantom();
    const endocast::testing::ScratchDir dir("extract_api");
    const std::string path = dir / "p.nrrd";
    write_volume(ph.ct, path);
    Options o;
    o.self_intersections = meshpost::count_self_intersections;
    Recorder progress;
    const Result from_file = extract(Source{{path}}, o, &progress);
    Source memory;
    memory.volume16 = &ph.ct;
    const Result from_memory = extract(memory, o);
    EXPECT_EQ(from_file.mesh().vertices, from_memory.mesh().vertices);
    EXPECT_EQ(from_file.mesh().faces, from_memory.mesh().faces);
    EXPECT_EQ(from_file.ecv_ml(), from_memory.ecv_ml());
    EXPECT_NEAR(from_file.ecv_ml() / ph.true_ecv_ml, 1.0, 0.02);
    EXPECT_TRUE(from_file.closed_manifold());
    EXPECT_EQ(from_file.self_intersections, 0);
    EXPECT_EQ(from_file.plan.path, ExtractPath::WholeGrid);
    EXPECT_EQ(from_file.ct_storage, "int16");
    EXPECT_EQ(from_file.input.format, "nrrd");
    EXPECT_EQ(from_memory.input.format, "memory");
    EXPECT_EQ(from_file.paths, std::vector<std::string>{path});
    EXPECT_TRUE(from_file.ct.empty() && from_file.ct16.empty());  // not kept unless asked
    EXPECT_EQ(progress.plans, 1);
    ASSERT_FALSE(progress.stages.empty());
    EXPECT_EQ(progress.stages.front(), "read");
    EXPECT_EQ(progress.stages.back(), "check");
    EXPECT_EQ(from_memory.self_intersections, 0);
    Options unchecked;
    EXPECT_EQ(extract(memory, unchecked).self_intersections, -1);  // no hook: not checked
}

TEST(Extract, KeepsTheCtAndCropsACtInMemory) {
    const PhantomResult ph = small_phantom();
    Source memory;
    memory.volume16 = &ph.ct;
    Options o;
    o.keep_ct = true;
    const Result whole = extract(memory, o);
    EXPECT_EQ(whole.ct16.geometry().dims, ph.ct.geometry().dims);
    const Dims d = ph.ct.geometry().dims;
    o.crop = CropBox{{2, 2, 2}, {d[0] - 2, d[1] - 2, d[2] - 2}};
    const Result cropped = extract(memory, o);
    EXPECT_EQ(cropped.mesh_grid.dims, (Dims{d[0] - 4, d[1] - 4, d[2] - 4}));
    EXPECT_EQ(cropped.input_grid.dims, d);
    EXPECT_NEAR(cropped.ecv_ml() / whole.ecv_ml(), 1.0, 0.002);
}

TEST(Extract, RefusesBadSourcesAndNamesTheInput) {
    const PhantomResult ph = small_phantom();
    EXPECT_THROW(extract(Source{}), InvalidParameter);  // nothing given
    Source both{{"x.nrrd"}};
    both.volume16 = &ph.ct;
    EXPECT_THROW(extract(both), InvalidParameter);  // two given
    try {
        extract(Source{{"/nonexistent/scan.nrrd"}});
        FAIL() << "no error";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/scan.nrrd"), std::string::npos) << e.what();
    }
    Volume<float> nan(ph.ct.geometry(), 0.0f);
    nan[nan.size() / 2] = std::numeric_limits<float>::quiet_NaN();
    Source s;
    s.volume = &nan;
    s.name = "my array";
    try {
        extract(s);
        FAIL() << "no error";
    } catch (const InvalidParameter& e) {
        EXPECT_NE(std::string(e.what()).find("my array"), std::string::npos) << e.what();
    }
    Volume<int16_t> solid(ph.ct.geometry(), int16_t(2000));  // all bone: no cavity
    Source all_bone;
    all_bone.volume16 = &solid;
    Options o;
    o.method.binarize.isovalue = 300;
    EXPECT_THROW(extract(all_bone, o), NoResult);
}
