#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "meshpost/cgal/deviation.h"
#include "meshpost/register.h"
#include "test_meshes.h"

using namespace meshpost;

namespace {

const double kPi = std::acos(-1.0);

/// An egg-like, asymmetric closed surface: an ellipsoid (40 x 30 x 22 mm semi-axes) with a bump.
TriangleMesh asymmetric_shape() {
    TriangleMesh m = test::icosphere(1.0, 5);
    for (Point& p : m.vertices) {
        const double bump = 6.0 * std::exp(-((p[0] - 0.6) * (p[0] - 0.6) + (p[1] - 0.5) * (p[1] - 0.5) + p[2] * p[2]) / 0.08);
        p = {(40.0 + bump) * p[0] + 3.0 * p[1] * p[1], (30.0 + bump) * p[1], (22.0 + 0.5 * bump) * p[2]};
    }
    return m;
}

RigidTransform motion(double deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(deg * kPi / 180.0, axis.normalized()).toRotationMatrix();
    RigidTransform x;
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) x.rotation[i][k] = R(i, k);
        x.translation[i] = t[i];
    }
    return x;
}

/// Rotation angle (deg) and translation difference (mm) between `got` and the inverse of `applied`.
void errors(const RigidTransform& got, const RigidTransform& applied, double& angle_deg, double& trans_mm) {
    Eigen::Matrix3d G, A;
    Eigen::Vector3d g, a;
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) {
            G(i, k) = got.rotation[i][k];
            A(i, k) = applied.rotation[i][k];
        }
        g[i] = got.translation[i];
        a[i] = applied.translation[i];
    }
    const Eigen::Matrix3d Ainv = A.transpose();
    const Eigen::Vector3d ainv = -(Ainv * a);
    const Eigen::Matrix3d E = G * Ainv.transpose();  // identity when G == Ainv
    angle_deg = std::acos(std::clamp((E.trace() - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / kPi;
    trans_mm = (g - ainv).norm();
}

}  // namespace

TEST(Register, RecoversAKnownRigidMotion) {
    const TriangleMesh b = asymmetric_shape();
    const RigidTransform applied = motion(20.0, {1.0, 2.0, 0.5}, {15.0 / std::sqrt(3.0), -15.0 / std::sqrt(3.0), 15.0 / std::sqrt(3.0)});
    EXPECT_NEAR(applied.angle_deg(), 20.0, 1e-9);
    const TriangleMesh a = transformed(b, applied);  // A = B moved by 20 deg and 15 mm
    const RegisterResult r = register_rigid(a, b);
    double angle = 0, trans = 0;
    errors(r.transform, applied, angle, trans);
    EXPECT_LT(angle, 0.1);
    EXPECT_LT(trans, 0.05);
    EXPECT_TRUE(r.converged);
    EXPECT_LT(r.rmse_mm, 1e-3);
    const DeviationResult d = surface_deviation(transformed(a, r.transform), b);
    EXPECT_LT(d.a_to_b.mean, 0.01);
    EXPECT_LT(d.b_to_a.mean, 0.01);
    std::printf("[ numbers  ] rigid 20 deg / 15 mm: rotation error %.3g deg, translation error %.3g mm, rmse %.3g, "
                "mean deviation %.3g / %.3g mm, %d iterations\n",
                angle, trans, r.rmse_mm, d.a_to_b.mean, d.b_to_a.mean, r.iterations);
}

TEST(Register, RecoversALargeRotationThroughPrincipalAxes) {
    const TriangleMesh b = asymmetric_shape();
    const RigidTransform applied = motion(150.0, {0.3, -1.0, 0.7}, {40.0, 5.0, -20.0});
    const TriangleMesh a = transformed(b, applied);
    const RegisterResult r = register_rigid(a, b);
    double angle = 0, trans = 0;
    errors(r.transform, applied, angle, trans);
    EXPECT_LT(angle, 0.1);
    EXPECT_LT(trans, 0.05);
}

TEST(Register, DifferentTessellationsOfTheSameSurface) {
    // A coarse and a fine sphere of the same radius, offset: the alignment brings their centres
    // together (the rotation of a sphere is free).
    const TriangleMesh b = test::icosphere(30.0, 5);
    const TriangleMesh a = test::icosphere(30.0, 3, {4.0, -3.0, 2.0});
    const RegisterResult r = register_rigid(a, b);
    const Point c = r.transform.apply({4.0, -3.0, 2.0});
    EXPECT_NEAR(c[0], 0.0, 0.05);
    EXPECT_NEAR(c[1], 0.0, 0.05);
    EXPECT_NEAR(c[2], 0.0, 0.05);
}

TEST(Register, IdentityForIdenticalMeshes) {
    const TriangleMesh b = asymmetric_shape();
    const RegisterResult r = register_rigid(b, b);
    EXPECT_LT(r.transform.angle_deg(), 1e-6);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(r.transform.translation[i], 0.0, 1e-6);
}

TEST(Register, RejectsBadInput) {
    const TriangleMesh b = test::icosphere(1.0, 1);
    EXPECT_THROW(register_rigid(TriangleMesh{}, b), InvalidMesh);
    TriangleMesh nan = b;
    nan.vertices[3][0] = std::nan("");
    EXPECT_THROW(register_rigid(nan, b), InvalidMesh);
}
