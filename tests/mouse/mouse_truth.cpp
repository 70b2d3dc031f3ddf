// The carried expert label of the shared mouse scans and the scores against it (mouse_truth.h).
#include "mouse_truth.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>

#include "endocast/io.h"

namespace mouse_truth {
namespace {

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }

nlohmann::json read_json_file(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot open " + path);
    return nlohmann::json::parse(in);
}

}  // namespace

std::map<int, Vec3> read_markups(const std::string& path) {
    const nlohmann::json j = read_json_file(path);
    const auto& m = j.at("markups").at(0);
    const bool ras = m.value("coordinateSystem", std::string("LPS")) == "RAS";
    std::map<int, Vec3> out;
    for (const auto& cp : m.at("controlPoints")) {
        const auto& p = cp.at("position");
        Vec3 v{p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
        if (ras) v = {-v[0], -v[1], v[2]};
        out[std::stoi(cp.at("label").get<std::string>())] = v;
    }
    return out;
}

Vec3 Rigid::operator()(const Vec3& p) const {
    return {R[0] * p[0] + R[1] * p[1] + R[2] * p[2] + t[0], R[3] * p[0] + R[4] * p[1] + R[5] * p[2] + t[1],
            R[6] * p[0] + R[7] * p[1] + R[8] * p[2] + t[2]};
}

std::map<std::string, Rigid> read_frames(const std::string& path) {
    const nlohmann::json j = read_json_file(path);
    std::map<std::string, Rigid> out;
    for (const auto& [name, f] : j.at("frames").items()) {
        Rigid r;
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b) r.R[size_t(3 * a + b)] = f.at("R").at(a).at(b).get<double>();
            r.t[size_t(a)] = f.at("t").at(a).get<double>();
        }
        out[name] = r;
    }
    return out;
}

ThinPlate::ThinPlate(const std::vector<Vec3>& from, const std::vector<Vec3>& to) : from_(from) {
    const size_t n = from.size();
    if (n < 4 || to.size() != n) throw std::runtime_error("thin-plate spline: needs >= 4 matching points");
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(Eigen::Index(n + 4), Eigen::Index(n + 4));
    Eigen::MatrixXd b = Eigen::MatrixXd::Zero(Eigen::Index(n + 4), 3);
    for (size_t i = 0; i < n; ++i) {
        for (size_t j = 0; j < n; ++j) A(Eigen::Index(i), Eigen::Index(j)) = norm(sub(from[i], from[j]));
        const Eigen::Index row = Eigen::Index(i), aff = Eigen::Index(n);
        A(row, aff) = A(aff, row) = 1;
        for (int a = 0; a < 3; ++a) {
            A(row, aff + 1 + a) = A(aff + 1 + a, row) = from[i][size_t(a)];
            b(row, a) = to[i][size_t(a)];
        }
    }
    const Eigen::MatrixXd w = A.fullPivLu().solve(b);
    w_.resize(n + 4);
    for (size_t i = 0; i < n + 4; ++i)
        for (int a = 0; a < 3; ++a) w_[i][size_t(a)] = w(Eigen::Index(i), a);
}

Vec3 ThinPlate::operator()(const Vec3& p) const {
    const size_t n = from_.size();
    Vec3 q{0, 0, 0};
    for (size_t i = 0; i < n; ++i) {
        const double u = norm(sub(p, from_[i]));
        for (int a = 0; a < 3; ++a) q[size_t(a)] += u * w_[i][size_t(a)];
    }
    for (int a = 0; a < 3; ++a)
        q[size_t(a)] += w_[n][size_t(a)] + p[0] * w_[n + 1][size_t(a)] + p[1] * w_[n + 2][size_t(a)] +
                        p[2] * w_[n + 3][size_t(a)];
    return q;
}

Template load_template(const std::string& dir) {
    Template t;
    t.labels = endocast::read_volume({dir + "/low_res_template_UCHAR-label.nii.gz"}).volume;
    t.landmarks = read_markups(dir + "/45_LM-skull.mrk.json");
    const Geometry& g = t.labels.geometry();
    t.anterior_y = std::numeric_limits<double>::infinity();
    Vec3 centre{0, 0, 0};
    size_t n = 0;
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                if (t.labels(x, y, z) != 15.f) continue;
                const Vec3 w = g.index_to_world(double(x), double(y), double(z));
                t.anterior_y = std::min(t.anterior_y, w[1]);
                for (int a = 0; a < 3; ++a) centre[size_t(a)] += w[size_t(a)];
                ++n;
            }
    if (n == 0) throw std::runtime_error(dir + ": the template label holds no voxel of label 15");
    t.label_mm3 = double(n) * g.voxel_volume_mm3();
    for (double& c : centre) c /= double(n);
    const Vec3 ba = t.landmarks.at(50), op = t.landmarks.at(21);
    const Vec3 u = sub(op, ba), ex{1, 0, 0};  // the template's left-right axis
    Vec3 nrm{u[1] * ex[2] - u[2] * ex[1], u[2] * ex[0] - u[0] * ex[2], u[0] * ex[1] - u[1] * ex[0]};
    const double len = norm(nrm);
    for (double& c : nrm) c /= len;
    if (dot(sub(centre, ba), nrm) > 0)
        for (double& c : nrm) c = -c;
    t.fm_point = ba;
    t.fm_normal = nrm;
    return t;
}

std::map<int, Vec3> scan_landmarks(const std::string& markups_path, const std::string& scan_name,
                                   const std::map<std::string, Rigid>& frames) {
    std::map<int, Vec3> lm = read_markups(markups_path);
    const auto f = frames.find(scan_name);
    if (f != frames.end())
        for (auto& [k, p] : lm) p = f->second(p);
    return lm;
}

Carried carry(const Template& tpl, const Geometry& scan, const std::map<int, Vec3>& scan_lm) {
    std::vector<Vec3> s, t;
    for (const auto& [k, p] : tpl.landmarks) {
        const auto it = scan_lm.find(k);
        if (it == scan_lm.end()) continue;
        s.push_back(it->second);
        t.push_back(p);
    }
    Carried c{Volume<uint8_t>(scan, 0), 0, ThinPlate(s, t)};
    // The scan voxels that can carry the label: the box of the label's voxels mapped onto the scan
    // (the inverse spline), grown by 4 voxels.
    const ThinPlate to_scan(t, s);
    const Geometry& tg = tpl.labels.geometry();
    std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
    for (int64_t z = 0; z < tg.dims[2]; ++z)
        for (int64_t y = 0; y < tg.dims[1]; ++y)
            for (int64_t x = 0; x < tg.dims[0]; ++x) {
                if (tpl.labels(x, y, z) != 15.f) continue;
                const Vec3 q = scan.world_to_index(to_scan(tg.index_to_world(double(x), double(y), double(z))));
                for (size_t a = 0; a < 3; ++a) lo[a] = std::min(lo[a], q[a]), hi[a] = std::max(hi[a], q[a]);
            }
    std::array<int64_t, 3> b0{}, b1{};
    for (size_t a = 0; a < 3; ++a) {
        b0[a] = std::max<int64_t>(0, int64_t(std::floor(lo[a])) - 4);
        b1[a] = std::min<int64_t>(scan.dims[a] - 1, int64_t(std::ceil(hi[a])) + 4);
    }
    size_t count = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : count)
    for (int64_t z = b0[2]; z <= b1[2]; ++z)
        for (int64_t y = b0[1]; y <= b1[1]; ++y)
            for (int64_t x = b0[0]; x <= b1[0]; ++x) {
                const Vec3 q = tg.world_to_index(c.to_template(scan.index_to_world(double(x), double(y), double(z))));
                const int64_t i = std::llround(q[0]), j = std::llround(q[1]), k = std::llround(q[2]);
                if (tpl.labels.contains(i, j, k) && tpl.labels(i, j, k) == 15.f) {
                    c.label(x, y, z) = 1;
                    ++count;
                }
            }
    c.label_mm3 = double(count) * scan.voxel_volume_mm3();
    return c;
}

Scores score(const Template& tpl, const Carried& truth, const Volume<uint8_t>& mask, double ecv_ml) {
    if (mask.dims() != truth.label.dims()) throw std::runtime_error("score: the mask is not on the scan's grid");
    const Geometry& g = mask.geometry();
    size_t both = 0, ours = 0, nasal = 0, past = 0;
    double reach = -std::numeric_limits<double>::infinity();
    const int64_t nz = g.dims[2];
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : both, ours, nasal, past) reduction(max : reach)
    for (int64_t z = 0; z < nz; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) {
                if (!mask(x, y, z)) continue;
                ++ours;
                both += truth.label(x, y, z) != 0;
                const Vec3 q = truth.to_template(g.index_to_world(double(x), double(y), double(z)));
                nasal += q[1] < tpl.anterior_y;
                const double s = dot(sub(q, tpl.fm_point), tpl.fm_normal);
                reach = std::max(reach, s);
                past += s > 0;
            }
    size_t label = 0;
    for (size_t i = 0; i < truth.label.size(); ++i) label += truth.label[i] != 0;
    const double v = g.voxel_volume_mm3();
    Scores r;
    r.dice = 2.0 * double(both) / double(ours + label);
    r.label_ml = truth.label_mm3 / 1000.0;
    r.ecv_ml = ecv_ml;
    r.ecv_error = ecv_ml / r.label_ml - 1.0;
    r.nasal_share = double(nasal) * v / truth.label_mm3;
    r.fm_reach_mm = reach;
    r.fm_share = double(past) * v / truth.label_mm3;
    return r;
}

AtlasCt atlas_ct(const Volume<float>& labels, int factor) {
    const Geometry& g = labels.geometry();
    if (factor < 1) throw std::runtime_error("atlas_ct: factor < 1");
    Geometry c = g;
    for (int a = 0; a < 3; ++a) {
        c.dims[size_t(a)] = g.dims[size_t(a)] / factor;
        c.spacing[size_t(a)] = g.spacing[size_t(a)] * factor;
    }
    // The block's centre: voxel (factor - 1) / 2 of the fine grid.
    const double h = 0.5 * (factor - 1);
    c.origin = g.index_to_world(h, h, h);
    Volume<float> bone(c, 0.f);
    AtlasCt out{Volume<int16_t>(c, 0), Volume<uint8_t>(c, 0), 0};
    const double n = double(factor) * factor * factor;
    size_t in15 = 0;
#pragma omp parallel for schedule(static) reduction(+ : in15)
    for (int64_t z = 0; z < c.dims[2]; ++z)
        for (int64_t y = 0; y < c.dims[1]; ++y)
            for (int64_t x = 0; x < c.dims[0]; ++x) {
                size_t b = 0, e = 0;
                for (int k = 0; k < factor; ++k)
                    for (int j = 0; j < factor; ++j)
                        for (int i = 0; i < factor; ++i) {
                            const float l = labels(x * factor + i, y * factor + j, z * factor + k);
                            b += l == 1.f || l == 2.f || l == 21.f;
                            e += l == 15.f;
                        }
                bone(x, y, z) = float(b / n);
                if (2 * e >= size_t(n)) {
                    out.label(x, y, z) = 1;
                    ++in15;
                }
            }
    out.label_mm3 = double(in15) * c.voxel_volume_mm3();
    // Gaussian blur of sigma 0.6 voxel, separable (kernel to 3 sigma), clamped at the border.
    const double sigma = 0.6;
    std::vector<double> w;
    for (int i = -2; i <= 2; ++i) w.push_back(std::exp(-0.5 * i * i / (sigma * sigma)));
    double sum = 0;
    for (double v : w) sum += v;
    for (double& v : w) v /= sum;
    for (int axis = 0; axis < 3; ++axis) {
        Volume<float> next(c, 0.f);
        const int64_t st[3] = {1, c.dims[0], c.dims[0] * c.dims[1]};
#pragma omp parallel for schedule(static)
        for (int64_t z = 0; z < c.dims[2]; ++z)
            for (int64_t y = 0; y < c.dims[1]; ++y)
                for (int64_t x = 0; x < c.dims[0]; ++x) {
                    const int64_t q[3] = {x, y, z};
                    double v = 0;
                    for (int i = -2; i <= 2; ++i) {
                        const int64_t at = std::clamp<int64_t>(q[axis] + i, 0, c.dims[size_t(axis)] - 1);
                        v += w[size_t(i + 2)] * bone[size_t(x + st[1] * y + st[2] * z + (at - q[axis]) * st[axis])];
                    }
                    next(x, y, z) = float(v);
                }
        bone = std::move(next);
    }
    // Noise: a fixed-seed sequence in scan order (the same bytes on every machine).
    std::mt19937_64 rng(1);
    std::normal_distribution<double> noise(0.0, 20.0);
    for (size_t i = 0; i < bone.size(); ++i)
        out.ct[i] = int16_t(std::lround(40.0 + 1460.0 * double(bone[i]) + noise(rng)));
    return out;
}

double dice(const Volume<uint8_t>& a, const Volume<uint8_t>& b) {
    if (a.dims() != b.dims()) throw std::runtime_error("dice: masks of different grids");
    size_t both = 0, na = 0, nb = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        both += a[i] && b[i];
        na += a[i] != 0;
        nb += b[i] != 0;
    }
    return 2.0 * double(both) / double(na + nb);
}

}  // namespace mouse_truth
