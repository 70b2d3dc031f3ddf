#include <gtest/gtest.h>

#include <cmath>

#include "meshpost/render.h"
#include "test_meshes.h"

using namespace meshpost;
using namespace meshpost::test;

namespace {

const double kPi = std::acos(-1.0);

bool is_background(const cv::Vec3b& px, const RenderParams& p) { return px == p.background; }

}  // namespace

TEST(Render, SphereGivesAShadedDiscOfTheRightRadius) {
    // r = 20 mm at 4 px/mm: a disc of radius 80 px, centred, in every view.
    const TriangleMesh sphere = icosphere(20.0, 5, {100, -50, 30});
    for (ViewSide side : {ViewSide::Left, ViewSide::Right, ViewSide::Front, ViewSide::Back, ViewSide::Top, ViewSide::Bottom}) {
        RenderParams p;
        p.side = side;
        p.width = p.height = 240;
        p.pixels_per_mm = 4.0;
        const cv::Mat img = render_mesh(sphere, p);
        ASSERT_EQ(img.type(), CV_8UC3);
        ASSERT_EQ(img.cols, 240);
        size_t covered = 0, outside_disc = 0, missed_inside = 0;
        for (int y = 0; y < img.rows; ++y)
            for (int x = 0; x < img.cols; ++x) {
                const double r = std::hypot(x + 0.5 - 120, y + 0.5 - 120);
                const bool bg = is_background(img.at<cv::Vec3b>(y, x), p);
                if (!bg) ++covered;
                if (!bg && r > 81.5) ++outside_disc;
                if (bg && r < 78.5) ++missed_inside;  // the icosphere's facets lie inside the sphere
            }
        SCOPED_TRACE(to_string(side));
        EXPECT_EQ(outside_disc, 0u);
        EXPECT_EQ(missed_inside, 0u);
        EXPECT_NEAR(double(covered), kPi * 80 * 80, 0.02 * kPi * 80 * 80);
        // Lambert with a headlight: brightest at the centre (normal towards the viewer), dark at the rim.
        const cv::Vec3b centre = img.at<cv::Vec3b>(120, 120), rim = img.at<cv::Vec3b>(120, 120 + 78);
        EXPECT_NEAR(centre[2], p.colour[2], 2);
        EXPECT_LT(rim[2], centre[2] * 0.6);
        EXPECT_GE(rim[2], int(p.ambient * p.colour[2]) - 1);
    }
}

TEST(Render, FitsTheMeshAndIsDeterministic) {
    const TriangleMesh m = icosphere(5.0, 3, {1e4, 2e4, -3e4});
    RenderParams p;
    p.width = 300;
    p.height = 200;
    p.margin = 0.1;
    const cv::Mat a = render_mesh(m, p), b = render_mesh(m, p);
    EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
    // Fitted to the height: diameter 200 * 0.8 = 160 px; column 150 is covered from row ~20 to ~180.
    int top = -1, bottom = -1;
    for (int y = 0; y < a.rows; ++y)
        if (a.at<cv::Vec3b>(y, 150) != p.background) {
            if (top < 0) top = y;
            bottom = y;
        }
    EXPECT_NEAR(top, 20, 2);
    EXPECT_NEAR(bottom, 179, 2);
}

TEST(Render, RejectsBadSizesAndRendersAnEmptyMeshBlank) {
    RenderParams p;
    p.width = 0;
    EXPECT_THROW(render_mesh(cube(1.0), p), std::invalid_argument);
    p.width = 10;
    p.pixels_per_mm = -1;
    EXPECT_THROW(render_mesh(cube(1.0), p), std::invalid_argument);
    const cv::Mat blank = render_mesh(TriangleMesh{}, RenderParams{});
    EXPECT_EQ(cv::countNonZero(blank.reshape(1) != 255), 0);
}

TEST(Render, MarkedFacesTakeTheSecondColour) {
    // The upper half of a sphere marked, seen from the front: marked pixels above the equator only,
    // the unmarked colour below it, and the same picture as without marks when none is set.
    const TriangleMesh sphere = icosphere(20.0, 4);
    std::vector<uint8_t> marks(sphere.faces.size(), 0);
    RenderParams p;
    p.side = ViewSide::Front;
    p.width = p.height = 200;
    p.pixels_per_mm = 4.0;
    p.face_marks = &marks;
    const cv::Mat plain = render_mesh(sphere, RenderParams{p.side, 200, 200, 4.0});
    EXPECT_EQ(cv::norm(render_mesh(sphere, p), plain, cv::NORM_INF), 0.0);
    for (size_t f = 0; f < sphere.faces.size(); ++f) {
        double z = 0;
        for (uint32_t v : sphere.faces[f]) z += sphere.vertices[v][2];
        marks[f] = z > 0;
    }
    const cv::Mat img = render_mesh(sphere, p);
    auto marked = [&](const cv::Vec3b& px) { return px[2] > 60 && px[0] * 4 < px[2]; };  // orange: no blue
    size_t above = 0, below = 0;
    for (int y = 0; y < img.rows; ++y)
        for (int x = 0; x < img.cols; ++x)
            if (marked(img.at<cv::Vec3b>(y, x))) ++(y < 100 ? above : below);
    EXPECT_GT(above, size_t(0.4 * kPi * 80 * 80));
    EXPECT_EQ(below, 0u);
    EXPECT_TRUE(marked(img.at<cv::Vec3b>(60, 100)));
    EXPECT_FALSE(marked(img.at<cv::Vec3b>(140, 100)));
    marks.pop_back();
    EXPECT_THROW(render_mesh(sphere, p), std::invalid_argument);
}
