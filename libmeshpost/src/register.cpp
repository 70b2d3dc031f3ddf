// Rigid alignment: principal-axes initial guesses and point-to-plane ICP (see register.h).
#include "meshpost/register.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace meshpost {
namespace {

using Vec = Eigen::Vector3d;
using Mat = Eigen::Matrix3d;

/// Static k-d tree over a point set (median splits on the widest axis, leaves of <= 8 points).
class KdTree {
public:
    explicit KdTree(const std::vector<Vec>& pts) : pts_(pts), idx_(pts.size()), axis_(pts.size(), 0) {
        for (size_t i = 0; i < idx_.size(); ++i) idx_[i] = static_cast<uint32_t>(i);
        build(0, idx_.size());
    }
    /// Index of the nearest point (smallest index among equally near ones is not guaranteed, but
    /// the traversal is deterministic) and its squared distance.
    std::pair<uint32_t, double> nearest(const Vec& q) const {
        uint32_t best = 0;
        double bd2 = std::numeric_limits<double>::infinity();
        search(0, idx_.size(), q, best, bd2);
        return {best, bd2};
    }

private:
    static constexpr size_t kLeaf = 8;
    void build(size_t lo, size_t hi) {
        if (hi - lo <= kLeaf) return;
        Vec mn = pts_[idx_[lo]], mx = mn;
        for (size_t i = lo; i < hi; ++i) {
            mn = mn.cwiseMin(pts_[idx_[i]]);
            mx = mx.cwiseMax(pts_[idx_[i]]);
        }
        int ax = 0;
        (mx - mn).maxCoeff(&ax);
        const size_t mid = (lo + hi) / 2;
        std::nth_element(idx_.begin() + lo, idx_.begin() + mid, idx_.begin() + hi, [&](uint32_t a, uint32_t b) {
            return pts_[a][ax] < pts_[b][ax] || (pts_[a][ax] == pts_[b][ax] && a < b);
        });
        axis_[mid] = static_cast<uint8_t>(ax);
        build(lo, mid);
        build(mid + 1, hi);
    }
    void search(size_t lo, size_t hi, const Vec& q, uint32_t& best, double& bd2) const {
        if (hi - lo <= kLeaf) {
            for (size_t i = lo; i < hi; ++i) consider(idx_[i], q, best, bd2);
            return;
        }
        const size_t mid = (lo + hi) / 2;
        consider(idx_[mid], q, best, bd2);
        const int ax = axis_[mid];
        const double diff = q[ax] - pts_[idx_[mid]][ax];
        if (diff < 0) {
            search(lo, mid, q, best, bd2);
            if (diff * diff < bd2) search(mid + 1, hi, q, best, bd2);
        } else {
            search(mid + 1, hi, q, best, bd2);
            if (diff * diff < bd2) search(lo, mid, q, best, bd2);
        }
    }
    void consider(uint32_t i, const Vec& q, uint32_t& best, double& bd2) const {
        const double d2 = (pts_[i] - q).squaredNorm();
        if (d2 < bd2 || (d2 == bd2 && i < best)) {
            bd2 = d2;
            best = i;
        }
    }
    const std::vector<Vec>& pts_;
    std::vector<uint32_t> idx_;
    std::vector<uint8_t> axis_;
};

void check_mesh(const TriangleMesh& m, const char* name) {
    if (m.faces.empty()) throw InvalidMesh(std::string("register_rigid: mesh ") + name + " has no faces");
    for (size_t f = 0; f < m.faces.size(); ++f)
        for (uint32_t v : m.faces[f])
            if (v >= m.vertices.size())
                throw InvalidMesh(std::string("register_rigid: mesh ") + name + ": face " + std::to_string(f) +
                                  " references vertex " + std::to_string(v) + " of " +
                                  std::to_string(m.vertices.size()));
    for (size_t v = 0; v < m.vertices.size(); ++v)
        for (double c : m.vertices[v])
            if (!std::isfinite(c))
                throw InvalidMesh(std::string("register_rigid: mesh ") + name + ": vertex " + std::to_string(v) +
                                  " has a non-finite coordinate");
}

Vec vec(const Point& p) { return {p[0], p[1], p[2]}; }

/// Area-weighted centroid and covariance of a surface.
struct Moments {
    Vec centroid;
    Mat covariance;
};

Moments surface_moments(const TriangleMesh& m, const char* name) {
    // Coordinates relative to the first vertex used, for precision far from the origin.
    const Vec ref = vec(m.vertices[m.faces.front()[0]]);
    double A = 0;
    Vec s1 = Vec::Zero();
    Mat s2 = Mat::Zero();
    for (const Face& f : m.faces) {
        const Vec a = vec(m.vertices[f[0]]) - ref, b = vec(m.vertices[f[1]]) - ref, c = vec(m.vertices[f[2]]) - ref;
        const double area = 0.5 * (b - a).cross(c - a).norm();
        const Vec s = a + b + c;
        A += area;
        s1 += area * s / 3.0;
        // Integral of x x^T over the triangle: area / 12 * (sum v v^T + s s^T).
        s2 += area / 12.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
    }
    if (!(A > 0)) throw InvalidMesh(std::string("register_rigid: mesh ") + name + " has zero surface area");
    Moments mo;
    const Vec c = s1 / A;
    mo.covariance = s2 / A - c * c.transpose();
    mo.centroid = c + ref;
    return mo;
}

/// Area-weighted vertex normals (unit, or zero for vertices without area).
std::vector<Vec> vertex_normals(const TriangleMesh& m) {
    std::vector<Vec> n(m.vertices.size(), Vec::Zero());
    for (const Face& f : m.faces) {
        const Vec a = vec(m.vertices[f[0]]), b = vec(m.vertices[f[1]]), c = vec(m.vertices[f[2]]);
        const Vec fn = (b - a).cross(c - a);  // |fn| = 2 area
        for (uint32_t v : f) n[v] += fn;
    }
    for (Vec& x : n) {
        const double l = x.norm();
        x = l > 0 ? Vec(x / l) : Vec::Zero();
    }
    return n;
}

Mat rodrigues(const Vec& w) {
    const double th = w.norm();
    if (th == 0) return Mat::Identity();
    return Eigen::AngleAxisd(th, w / th).toRotationMatrix();
}

struct Icp {
    std::vector<Vec> samples;     // A
    std::vector<Vec> target;      // B vertices
    std::vector<Vec> normals;     // B vertex normals
    const KdTree* tree = nullptr;
    RegisterParams params;

    /// Nearest target vertex of every transformed sample.
    void pair(const Mat& R, const Vec& t, std::vector<Vec>& y, std::vector<uint32_t>& j, std::vector<double>& d) const {
        const long n = static_cast<long>(samples.size());
        y.resize(n);
        j.resize(n);
        d.resize(n);
#pragma omp parallel for schedule(static)
        for (long i = 0; i < n; ++i) {
            y[i] = R * samples[i] + t;
            const auto nn = tree->nearest(y[i]);
            j[i] = nn.first;
            d[i] = std::sqrt(nn.second);
        }
    }

    double mean_distance(const Mat& R, const Vec& t) const {
        std::vector<Vec> y;
        std::vector<uint32_t> j;
        std::vector<double> d;
        pair(R, t, y, j, d);
        double s = 0;
        for (double x : d) s += x;
        return s / double(d.size());
    }

    /// Runs up to `iterations` ICP steps on (R, t); returns the number run, sets rmse, pairs and
    /// converged.
    int run(Mat& R, Vec& t, int iterations, double& rmse, size_t& pairs, bool& converged) const {
        std::vector<Vec> y;
        std::vector<uint32_t> j;
        std::vector<double> d, sorted;
        converged = false;
        int it = 0;
        for (; it < iterations; ++it) {
            pair(R, t, y, j, d);
            sorted = d;
            const size_t mid = sorted.size() / 2;
            std::nth_element(sorted.begin(), sorted.begin() + mid, sorted.end());
            const double thresh = std::max(params.reject_factor * sorted[mid], params.tolerance_mm);
            Vec c = Vec::Zero();
            size_t k = 0;
            for (size_t i = 0; i < y.size(); ++i)
                if (d[i] <= thresh && normals[j[i]].squaredNorm() > 0) {
                    c += y[i];
                    ++k;
                }
            if (k < 6) break;
            c /= double(k);
            Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
            Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
            double r2 = 0, radius = 0;
            for (size_t i = 0; i < y.size(); ++i) {
                if (!(d[i] <= thresh && normals[j[i]].squaredNorm() > 0)) continue;
                const Vec& n = normals[j[i]];
                const Vec p = y[i] - c;
                const double r = n.dot(y[i] - target[j[i]]);
                Eigen::Matrix<double, 6, 1> J;
                J << p.cross(n), n;
                H += J * J.transpose();
                g += J * r;
                r2 += r * r;
                radius = std::max(radius, p.norm());
            }
            rmse = std::sqrt(r2 / double(k));
            pairs = k;
            // Pseudo-inverse: directions the surfaces do not constrain (a sphere's rotations) stay 0.
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(H);
            const auto& ev = es.eigenvalues();
            const double cut = 1e-10 * std::max(ev.maxCoeff(), 0.0);
            Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();
            for (int q = 0; q < 6; ++q)
                if (ev[q] > cut) {
                    const auto u = es.eigenvectors().col(q);
                    x -= u * (u.dot(g) / ev[q]);
                }
            const Vec w = x.head<3>(), tau = x.tail<3>();
            const Mat dR = rodrigues(w);
            R = dR * R;
            t = dR * (t - c) + c + tau;
            const double moved = w.norm() * radius + tau.norm();
            if (moved < params.tolerance_mm) {
                converged = true;
                ++it;
                break;
            }
        }
        // Orthonormalise (accumulated rounding) with the closest rotation.
        Eigen::JacobiSVD<Mat> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
        R = svd.matrixU() * svd.matrixV().transpose();
        return it;
    }
};

}  // namespace

Point RigidTransform::apply(const Point& p) const {
    Point q{};
    for (int i = 0; i < 3; ++i)
        q[i] = rotation[i][0] * p[0] + rotation[i][1] * p[1] + rotation[i][2] * p[2] + translation[i];
    return q;
}

double RigidTransform::angle_deg() const {
    const double c = std::clamp((rotation[0][0] + rotation[1][1] + rotation[2][2] - 1.0) / 2.0, -1.0, 1.0);
    return std::acos(c) * 180.0 / std::acos(-1.0);
}

TriangleMesh transformed(const TriangleMesh& mesh, const RigidTransform& t) {
    TriangleMesh out = mesh;
    for (Point& p : out.vertices) p = t.apply(p);
    return out;
}

RegisterResult register_rigid(const TriangleMesh& moving, const TriangleMesh& fixed, const RegisterParams& params) {
    check_mesh(moving, "A");
    check_mesh(fixed, "B");
    const Moments ma = surface_moments(moving, "A"), mb = surface_moments(fixed, "B");

    Icp icp;
    icp.params = params;
    {
        std::vector<char> used(moving.vertices.size(), 0);
        for (const Face& f : moving.faces)
            for (uint32_t v : f) used[v] = 1;
        std::vector<Vec> all;
        for (size_t v = 0; v < moving.vertices.size(); ++v)
            if (used[v]) all.push_back(vec(moving.vertices[v]));
        const size_t cap = std::max<size_t>(params.max_samples, 16);
        const size_t stride = (all.size() + cap - 1) / cap;
        for (size_t i = 0; i < all.size(); i += std::max<size_t>(stride, 1)) icp.samples.push_back(all[i]);
    }
    const std::vector<Vec> nb = vertex_normals(fixed);
    {
        std::vector<char> used(fixed.vertices.size(), 0);
        for (const Face& f : fixed.faces)
            for (uint32_t v : f) used[v] = 1;
        for (size_t v = 0; v < fixed.vertices.size(); ++v)
            if (used[v]) {
                icp.target.push_back(vec(fixed.vertices[v]));
                icp.normals.push_back(nb[v]);
            }
    }
    const KdTree tree(icp.target);
    icp.tree = &tree;

    // Initial guesses.
    std::vector<Mat> guesses{Mat::Identity()};
    if (params.principal_axes) {
        Eigen::SelfAdjointEigenSolver<Mat> ea(ma.covariance), eb(mb.covariance);
        const Mat EA = ea.eigenvectors(), EB = eb.eigenvectors();
        for (int s = 0; s < 8; ++s) {
            const Eigen::Vector3d signs(s & 1 ? -1 : 1, s & 2 ? -1 : 1, s & 4 ? -1 : 1);
            const Mat R = EB * signs.asDiagonal() * EA.transpose();
            if (R.determinant() > 0) guesses.push_back(R);
        }
    }
    Mat bestR = Mat::Identity();
    Vec bestT = mb.centroid - ma.centroid;
    double best = std::numeric_limits<double>::infinity();
    for (const Mat& R0 : guesses) {
        Mat R = R0;
        Vec t = mb.centroid - R0 * ma.centroid;
        double rmse = 0;
        size_t pairs = 0;
        bool conv = false;
        icp.run(R, t, params.guess_iterations, rmse, pairs, conv);
        const double score = icp.mean_distance(R, t);
        if (score < best) {
            best = score;
            bestR = R;
            bestT = t;
        }
    }

    RegisterResult r;
    r.samples = icp.samples.size();
    r.iterations = icp.run(bestR, bestT, params.max_iterations, r.rmse_mm, r.pairs, r.converged);
    r.mean_distance_mm = icp.mean_distance(bestR, bestT);
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) r.transform.rotation[i][k] = bestR(i, k);
        r.transform.translation[i] = bestT[i];
    }
    return r;
}

}  // namespace meshpost
