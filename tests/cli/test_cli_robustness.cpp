#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "cli_helpers.h"

using namespace cli_test;

TEST(CliRobustness, DrySkullPhantomMovesLessThanHalfAVoxelPer400Hu) {
    // Air-filled braincase (like the paper's crania), 1.5 mm voxels to keep the test short.
    const fs::path out = temp_dir("robustness");
    CliRun r = run("phantom " + (out / "dry.nrrd").string() + " --preset dry --spacing 1.5 1.5 1.5 -q");
    ASSERT_EQ(r.status, 0) << r.output;
    const double iso = read_json(out / "dry.json")["suggested_iso"].get<double>();
    r = run("robustness " + (out / "dry.nrrd").string() + " --iso " + std::to_string(iso) +
            " --delta 400 -q --report " + (out / "rob.json").string());
    ASSERT_EQ(r.status, 0) << r.output;
    const auto j = read_json(out / "rob.json");
    ASSERT_EQ(j["runs"].size(), 3u);
    ASSERT_EQ(j["deviations"].size(), 3u);
    for (const auto& run : j["runs"]) {
        EXPECT_TRUE(run["closed_manifold"].get<bool>());
        EXPECT_LT(std::fabs(run["ecv_change_pct"].get<double>()), 3.0);
    }
    // T-400 and T+400 against T: mean deviation <= 0.5 voxel.
    for (int k = 0; k < 2; ++k) {
        const auto& d = j["deviations"][k];
        EXPECT_EQ(d["b_isovalue"].get<double>(), iso);
        EXPECT_LE(d["mean_voxels"].get<double>(), 0.5) << d.dump();
        for (const char* key : {"mean", "p95", "hausdorff", "a_to_b", "b_to_a"}) EXPECT_TRUE(d.contains(key));
    }
    const double vs_t = std::max(j["deviations"][0]["mean"].get<double>(), j["deviations"][1]["mean"].get<double>());
    EXPECT_DOUBLE_EQ(j["max_mean_deviation_vs_reference_mm"].get<double>(), vs_t);
    EXPECT_LE(j["max_mean_deviation_vs_reference_voxels"].get<double>(), 0.5);
    EXPECT_GE(j["max_mean_deviation_mm"].get<double>(), vs_t);  // the extremes pair included
    r = run("robustness " + (out / "dry.nrrd").string() + " --iso 200 --delta -5");
    EXPECT_EQ(r.status, 4) << r.output;
}
