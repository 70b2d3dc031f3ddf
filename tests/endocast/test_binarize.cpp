#include <gtest/gtest.h>

#include <random>

#include "endocast/binarize.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;

namespace {

// Values drawn from classes (value, fraction), with Gaussian noise.
Volume<float> mixture(std::vector<std::pair<double, double>> classes, double sigma, uint32_t seed) {
    Volume<float> v(grid(40, 40, 40));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::normal_distribution<double> n(0, sigma);
    for (size_t i = 0; i < v.size(); ++i) {
        double x = u(rng), acc = 0;
        double val = classes.back().first;
        for (const auto& c : classes) {
            acc += c.second;
            if (x < acc) {
                val = c.first;
                break;
            }
        }
        v[i] = float(std::round(val + n(rng)));
    }
    return v;
}

}  // namespace

TEST(Binarize, OtsuSplitsTwoClasses) {
    const auto v = mixture({{-1000, 0.6}, {1200, 0.4}}, 30, 1);
    const double t = otsu_threshold(v, -1e300);
    EXPECT_GT(t, -800);
    EXPECT_LT(t, 1000);
}

TEST(Binarize, AutomaticIsovalueSeparatesTissueFromBoneWhenTissueIsPresent) {
    // Air, soft tissue (dominant), bone: the bone threshold lies between tissue and bone.
    const auto v = mixture({{-1000, 0.4}, {40, 0.5}, {1200, 0.1}}, 25, 2);
    std::string rule;
    const double t = automatic_isovalue(v, &rule);
    EXPECT_EQ(rule, "otsu-tissue-bone");
    EXPECT_GT(t, 200);
    EXPECT_LT(t, 1100);
}

TEST(Binarize, AutomaticIsovalueOnDrySkullSeparatesAirFromBone) {
    const auto v = mixture({{-1000, 0.85}, {1200, 0.15}}, 25, 3);
    std::string rule;
    const double t = automatic_isovalue(v, &rule);
    EXPECT_EQ(rule, "otsu-air-bone");
    EXPECT_GT(t, -800);
    EXPECT_LT(t, 1000);
}

TEST(Binarize, KeepsLargestBoneComponentAndReportsIso) {
    Volume<float> v(grid(20, 20, 20), 0.0f);
    for (int x = 2; x < 10; ++x)
        for (int y = 2; y < 10; ++y) v(x, y, 5) = 1000;  // 64 voxels
    v(15, 15, 15) = 1000;                                 // a fragment
    BinarizeParams p;
    p.isovalue = 500;
    const auto r = binarize(v, p);
    EXPECT_EQ(r.bone_voxels, 64u);
    EXPECT_EQ(r.removed_fragment_voxels, 1u);
    EXPECT_EQ(r.bone(15, 15, 15), 0);
    EXPECT_EQ(r.isovalue, 500);
    EXPECT_FALSE(r.isovalue_automatic);
}

TEST(Binarize, ErrorsNameTheProblem) {
    Volume<float> v(grid(8, 8, 8), 10.0f);
    BinarizeParams p;
    p.isovalue = 100;
    try {
        binarize(v, p);
        FAIL();
    } catch (const NoResult& e) {
        EXPECT_NE(std::string(e.what()).find("no voxel is >= the isovalue 100"), std::string::npos);
    }
    p.isovalue = 5;
    EXPECT_THROW(binarize(v, p), NoResult);  // all bone
    p.isovalue = std::nan("");
    EXPECT_THROW(binarize(v, p), InvalidParameter);
    p.isovalue.reset();
    EXPECT_THROW(binarize(v, p), NoResult);  // constant volume: no histogram split
}
