#include <gtest/gtest.h>

#include <cmath>

#include "endocast/errors.h"
#include "endocast/qc.h"
#include "../meshpost/test_meshes.h"
#include "test_helpers.h"

#include <opencv2/imgcodecs.hpp>

using namespace endocast;

namespace {

/// A 64 x 64 x 40 CT of 1 x 1 x 2 mm voxels: soft tissue (100) in a ball of radius 12 mm at the
/// centre, bone (1000) around; the mask is the ball.
struct Ball {
    Volume<float> ct;
    Volume<uint8_t> mask;
};

Ball ball(double radius_mm = 12.0) {
    const Geometry g = endocast::testing::grid(64, 64, 40, {1, 1, 2});
    Ball b{Volume<float>(g, 1000.0f), Volume<uint8_t>(g)};
    for (int64_t z = 0; z < 40; ++z)
        for (int64_t y = 0; y < 64; ++y)
            for (int64_t x = 0; x < 64; ++x) {
                const double dx = x - 31.5, dy = y - 31.5, dz = (z - 19.5) * 2.0;
                if (dx * dx + dy * dy + dz * dz <= radius_mm * radius_mm) {
                    b.ct(x, y, z) = 100.0f;
                    b.mask(x, y, z) = 1;
                }
            }
    return b;
}

bool is_contour(const cv::Vec3b& px, const QcParams& p) { return px == p.contour_bgr; }

}  // namespace

TEST(Qc, EveryPanelHasTheOutlineWhereTheMaskEnds) {
    const Ball b = ball();
    QcParams p;
    p.isovalue = 550;
    const cv::Mat img = render_qc(b.ct, b.mask, meshpost::TriangleMesh{}, p);
    const std::vector<cv::Rect> panels = qc_panels(p);
    ASSERT_EQ(panels.size(), 3u + 6u + 3u);
    EXPECT_EQ(img.cols, 3 * 400 + 2 * 4);
    EXPECT_EQ(img.rows, panels.back().br().y);
    for (size_t n = 0; n < 9; ++n) {
        SCOPED_TRACE("panel " + std::to_string(n));
        const cv::Mat panel = img(panels[n]);
        size_t count = 0;
        for (int y = 0; y < panel.rows; ++y)
            for (int x = 0; x < panel.cols; ++x) count += is_contour(panel.at<cv::Vec3b>(y, x), p);
        EXPECT_GT(count, 50u);
    }
    // The three planes go through the ball's centre; with square mm pixels the outline is a circle
    // of 12 mm in each, also in the coronal and sagittal planes where voxels are 2 mm tall. The
    // planes are cropped to the mask's box (i, j: 20..43, k: 14..25) grown by 0.35 x its extent,
    // at least 4 voxels: i, j 12..51 = 40 mm, k 10..29 = 40 mm, so 400 px / 40 mm in each.
    const double scale[3] = {10.0, 10.0, 10.0};
    for (size_t n = 0; n < 3; ++n) {
        SCOPED_TRACE("plane " + std::to_string(n));
        const cv::Mat panel = img(panels[n]);
        const double r_px = 12.0 * scale[n], voxel_px = (n == 0 ? 1.0 : 2.0) * scale[n];
        size_t count = 0, near = 0;
        for (int y = 0; y < panel.rows; ++y)
            for (int x = 0; x < panel.cols; ++x) {
                if (!is_contour(panel.at<cv::Vec3b>(y, x), p)) continue;
                ++count;
                const double r = std::hypot(x + 0.5 - 200.0, y + 0.5 - 200.0);
                near += std::abs(r - r_px) <= voxel_px + 2.0;
            }
        EXPECT_GT(count, size_t(2 * 3.14 * r_px));  // closed outline around the circle
        EXPECT_EQ(near, count);
    }
    // Grey window from the tissue (100) and the isovalue (550): tissue dark grey, bone white.
    const cv::Vec3b centre = img(panels[0]).at<cv::Vec3b>(200, 200), corner = img(panels[0]).at<cv::Vec3b>(30, 390);
    EXPECT_NEAR(centre[0], 255.0 * (100 - (100 - 225)) / (1000 - (100 - 225)), 2);
    EXPECT_EQ(corner[0], 255);
}

TEST(Qc, EmptyMaskStillDrawsAndBadParametersThrow) {
    Ball b = ball();
    Volume<uint8_t> empty(b.ct.geometry());
    const cv::Mat img = render_qc(b.ct, empty, meshpost::TriangleMesh{}, QcParams{});
    EXPECT_EQ(img.type(), CV_8UC3);
    QcParams p;
    p.row_slices = 0;
    EXPECT_THROW(render_qc(b.ct, b.mask, {}, p), InvalidParameter);
    p = QcParams{};
    p.window_low = 5;
    p.window_high = 5;
    EXPECT_THROW(render_qc(b.ct, b.mask, {}, p), InvalidParameter);
    const Volume<uint8_t> other(endocast::testing::grid(8, 8, 8));
    EXPECT_THROW(render_qc(b.ct, other, {}, QcParams{}), InvalidParameter);
}

namespace {

/// Orange-ish (the off-bone colour, shaded or anti-aliased): red, little blue, less green. Not the
/// grey CT, the green outline, the white labels nor the ivory (bone-coloured) faces.
bool is_off_bone(const cv::Vec3b& px) { return px[2] > 60 && px[0] * 4 < px[2] && px[1] < px[2]; }

size_t count_off_bone(const cv::Mat& img) {
    size_t n = 0;
    for (int y = 0; y < img.rows; ++y)
        for (int x = 0; x < img.cols; ++x) n += is_off_bone(img.at<cv::Vec3b>(y, x));
    return n;
}

}  // namespace

TEST(Qc, FacesNotOnBoneAreOrangeInTheMeshViewsOnly) {
    const Ball b = ball();
    // The ball's surface (world centre 31.5, 31.5, 39 mm), its upper half flagged not on bone.
    const meshpost::TriangleMesh m = meshpost::test::icosphere(12.0, 3, {31.5, 31.5, 39.0});
    QcParams p;
    p.isovalue = 550;
    const cv::Mat plain = render_qc(b.ct, b.mask, m, p);
    EXPECT_EQ(count_off_bone(plain), 0u);
    std::vector<uint8_t> on_bone(m.faces.size(), 1);
    p.face_on_bone = &on_bone;
    // All on bone: the same picture as without flags, no second colour, no legend.
    EXPECT_EQ(cv::norm(render_qc(b.ct, b.mask, m, p), plain, cv::NORM_INF), 0.0);
    for (size_t f = 0; f < m.faces.size(); ++f) {
        double z = 0;
        for (uint32_t v : m.faces[f]) z += m.vertices[v][2] / 3.0;
        on_bone[f] = z < 39.0;
    }
    const cv::Mat img = render_qc(b.ct, b.mask, m, p);
    const std::vector<cv::Rect> panels = qc_panels(p);
    for (size_t n = 0; n < 9; ++n) EXPECT_EQ(count_off_bone(img(panels[n])), 0u) << "slice panel " << n;
    // Left and front views: the upper half orange, the lower half not (the sphere is 15 px/mm, its
    // faces ~2 mm: those across the equator reach ~30 px below it); the top view sees the upper half.
    for (size_t n : {size_t(9), size_t(11)}) {
        const cv::Mat view = img(panels[n]);
        EXPECT_GT(count_off_bone(view(cv::Rect(0, 30, 400, 130))), 20000u) << "mesh view " << n;
        EXPECT_EQ(count_off_bone(view(cv::Rect(0, 240, 400, 130))), 0u) << "mesh view " << n;
    }
    EXPECT_GT(count_off_bone(img(panels[10])), 60000u);
    // The legend line, in the off-bone colour, at the bottom of the left view.
    EXPECT_GT(count_off_bone(img(panels[9])(cv::Rect(0, 375, 400, 25))), 100u);
    EXPECT_EQ(count_off_bone(img(panels[11])(cv::Rect(0, 375, 400, 25))), 0u);
    on_bone.pop_back();
    EXPECT_THROW(render_qc(b.ct, b.mask, m, p), InvalidParameter);
}

// encode_png (libpng) decoded by another decoder (OpenCV's): the same pixels, channel order kept.
TEST(Qc, EncodesAPngThatDecodesToTheSamePixels) {
    for (int type : {CV_8UC1, CV_8UC3, CV_8UC4}) {
        cv::Mat img(13, 21, type);
        cv::randu(img, cv::Scalar::all(0), cv::Scalar::all(256));
        const std::string png = encode_png(img);
        ASSERT_GT(png.size(), 8u);
        EXPECT_EQ(png.substr(1, 3), "PNG");
        const std::vector<uchar> bytes(png.begin(), png.end());
        const cv::Mat back = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
        ASSERT_EQ(back.type(), type);
        EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0.0) << "type " << type;
    }
    EXPECT_THROW(encode_png(cv::Mat()), IoError);
    EXPECT_THROW(encode_png(cv::Mat(4, 4, CV_16UC1)), IoError);
}
