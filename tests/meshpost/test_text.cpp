// The string helpers shared by the libraries and the CLI (meshpost/text.h).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "meshpost/text.h"

using namespace meshpost::text;

TEST(Text, CaseAndTrim) {
    EXPECT_EQ(lower("CT Head.NII.GZ"), "ct head.nii.gz");
    EXPECT_EQ(upper("ct"), "CT");
    EXPECT_EQ(trim("  seed-mode\t"), "seed-mode");
    EXPECT_EQ(trim(std::string("ORIGINAL\\PRIMARY \0", 18)), "ORIGINAL\\PRIMARY");  // DICOM padding
    EXPECT_EQ(trim("\r\n"), "");
    EXPECT_EQ(trim(""), "");
    EXPECT_EQ(trim("a b"), "a b");
}

TEST(Text, Extensions) {
    EXPECT_TRUE(ends_with("skull.nii.gz", ".nii.gz"));
    EXPECT_FALSE(ends_with("gz", ".nii.gz"));
    EXPECT_EQ(lower_extension("out/Mesh.STL"), ".stl");
    EXPECT_EQ(lower_extension("scan.nii.gz"), ".gz");
    EXPECT_EQ(lower_extension("run.v2/mesh"), "");  // a dot in a folder name is not an extension
    EXPECT_EQ(lower_extension("mesh"), "");
}

TEST(Text, SplitWordsAndPoints) {
    EXPECT_EQ(split("1 - 64", " - "), (std::vector<std::string>{"1", "64"}));
    EXPECT_EQ(split("a,,b", ","), (std::vector<std::string>{"a", "", "b"}));
    EXPECT_EQ(split("abc", ","), (std::vector<std::string>{"abc"}));
    EXPECT_EQ(words("  --iso  200\t300 "), (std::vector<std::string>{"--iso", "200", "300"}));
    EXPECT_TRUE(words(" \t").empty());
    EXPECT_EQ(point({1, -2.5, 0}), "(1, -2.5, 0)");
}
