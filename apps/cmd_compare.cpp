// `endocast compare`: surface deviation between two meshes (e.g. automatic vs manual endocast),
// optionally after a rigid alignment; JSON report, colour-coded PLY and histogram PNG.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "commands.h"
#include "endocast/errors.h"
#include "endocast/qc.h"
#include "meshpost/cgal/deviation.h"
#include "meshpost/io.h"
#include "meshpost/text.h"
#include "meshpost/register.h"

namespace endocast::cli {
namespace {

using meshpost::text::lower_extension;

struct CompareOptions {
    std::string a, b, align = "none", report, colored, histogram;
    double scale = 1.0;
};

/// Colour of a distance: blue at 0, green at scale/2, red at >= scale (linear in between).
std::array<uint8_t, 3> ramp(double d, double scale) {
    const double t = std::clamp(d / scale, 0.0, 1.0);
    double r, g, b;
    if (t < 0.5) {
        r = 0;
        g = t / 0.5;
        b = 1 - g;
    } else {
        r = (t - 0.5) / 0.5;
        g = 1 - r;
        b = 0;
    }
    auto u8 = [](double x) { return static_cast<uint8_t>(std::lround(255.0 * x)); };
    return {u8(r), u8(g), u8(b)};
}

/// Binary little-endian PLY with per-vertex colours (uchar red, green, blue) and the distance as
/// `quality` (float, mm), written to a temporary file and renamed.
void write_colored_ply(const meshpost::TriangleMesh& m, const std::vector<double>& dist, double scale,
                       const std::string& path) {
    std::ostringstream header;
    header << "ply\nformat binary_little_endian 1.0\ncomment endocast compare: distance to the other mesh, mm; "
              "colour blue 0 -> green "
           << scale / 2 << " -> red >= " << scale << " mm\nelement vertex " << m.vertices.size()
           << "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
              "property uchar blue\nproperty float quality\nelement face "
           << m.faces.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    std::string buf = header.str();
    buf.reserve(buf.size() + m.vertices.size() * 19 + m.faces.size() * 13);
    auto put = [&](const void* p, size_t n) { buf.append(static_cast<const char*>(p), n); };
    for (size_t i = 0; i < m.vertices.size(); ++i) {
        const float xyz[3] = {float(m.vertices[i][0]), float(m.vertices[i][1]), float(m.vertices[i][2])};
        const auto rgb = ramp(dist[i], scale);
        const float q = float(dist[i]);
        put(xyz, 12);
        put(rgb.data(), 3);
        put(&q, 4);
    }
    for (const auto& f : m.faces) {
        const uint8_t n = 3;
        const int32_t idx[3] = {int32_t(f[0]), int32_t(f[1]), int32_t(f[2])};
        put(&n, 1);
        put(idx, 12);
    }
    meshpost::write_file_atomic(path, buf);  // binary-safe: the stream is opened in binary mode
}

/// A "nice" tick step (1, 2 or 5 times a power of ten) for about `n` ticks over `range`.
double nice_step(double range, int n) {
    const double raw = range / n, p = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * p >= raw) return m * p;
    return 10 * p;
}

/// PNG of the area-weighted distance distributions of both directions, with the colour scale.
void write_histogram(const meshpost::DeviationResult& d, double scale, const std::string& a_name,
                     const std::string& b_name, const std::string& path) {
    const int W = 960, H = 560, left = 80, right = 30, top = 50, bottom = 110;
    const int pw = W - left - right, ph = H - top - bottom;
    const int bins = 60;
    const double hi = std::max({scale, d.a_to_b.p95, d.b_to_a.p95}) * 1.2;
    auto histogram = [&](const std::vector<double>& x, const std::vector<double>& w) {
        std::vector<double> h(bins, 0.0);
        double total = 0;
        for (size_t i = 0; i < x.size(); ++i) {
            const int k = std::min(bins - 1, static_cast<int>(x[i] / hi * bins));
            h[k] += w[i];
            total += w[i];
        }
        if (total > 0)
            for (double& v : h) v /= total;
        return h;
    };
    const auto ha = histogram(d.a_distances, d.a_weights), hb = histogram(d.b_distances, d.b_weights);
    const double ymax = std::max(*std::max_element(ha.begin(), ha.end()), *std::max_element(hb.begin(), hb.end())) * 1.1;
    cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
    const cv::Scalar black(0, 0, 0), grey(200, 200, 200), ca(200, 90, 30), cb(30, 60, 220);  // BGR
    auto X = [&](double v) { return left + static_cast<int>(std::lround(v / hi * pw)); };
    auto Y = [&](double v) { return top + ph - static_cast<int>(std::lround(v / ymax * ph)); };
    const int font = cv::FONT_HERSHEY_SIMPLEX;
    // Grid and ticks.
    const double xs = nice_step(hi, 8), ys = nice_step(ymax, 5);
    for (double v = 0; v <= hi + 1e-12; v += xs) {
        cv::line(img, {X(v), top}, {X(v), top + ph}, grey, 1);
        std::ostringstream s;
        s << std::setprecision(3) << v;
        cv::putText(img, s.str(), {X(v) - 12, top + ph + 20}, font, 0.45, black, 1, cv::LINE_AA);
    }
    for (double v = 0; v <= ymax + 1e-12; v += ys) {
        cv::line(img, {left, Y(v)}, {left + pw, Y(v)}, grey, 1);
        std::ostringstream s;
        s << std::setprecision(3) << 100 * v << "%";
        cv::putText(img, s.str(), {8, Y(v) + 5}, font, 0.45, black, 1, cv::LINE_AA);
    }
    // Step curves of both directions.
    auto curve = [&](const std::vector<double>& h, const cv::Scalar& c) {
        std::vector<cv::Point> pts;
        for (int k = 0; k < bins; ++k) {
            const double x0 = hi * k / bins, x1 = hi * (k + 1) / bins;
            pts.push_back({X(x0), Y(h[k])});
            pts.push_back({X(x1), Y(h[k])});
        }
        cv::polylines(img, pts, false, c, 2, cv::LINE_AA);
    };
    curve(ha, ca);
    curve(hb, cb);
    cv::rectangle(img, {left, top}, {left + pw, top + ph}, black, 1);
    // Colour scale under the axis: blue 0 -> green scale/2 -> red >= scale.
    for (int px = 0; px < pw; ++px) {
        const auto rgb = ramp(hi * px / pw, scale);
        cv::line(img, {left + px, top + ph + 30}, {left + px, top + ph + 42}, cv::Scalar(rgb[2], rgb[1], rgb[0]), 1);
    }
    cv::putText(img, "distance to the other surface (mm); colour scale 0 / " + [&] {
        std::ostringstream s;
        s << std::setprecision(3) << scale / 2 << " / >= " << scale;
        return s.str();
    }() + " mm", {left, top + ph + 70}, font, 0.5, black, 1, cv::LINE_AA);
    auto legend = [&](int row, const cv::Scalar& c, const std::string& text, const meshpost::DistanceStats& st) {
        std::ostringstream s;
        s << std::fixed << std::setprecision(3) << text << ": mean " << st.mean << ", p95 " << st.p95 << ", max "
          << st.max << " mm";
        cv::line(img, {left + 10, 18 + row * 18}, {left + 40, 18 + row * 18}, c, 3);
        cv::putText(img, s.str(), {left + 48, 23 + row * 18}, font, 0.45, black, 1, cv::LINE_AA);
    };
    legend(0, ca, "A -> B (" + a_name + ")", d.a_to_b);
    legend(1, cb, "B -> A (" + b_name + ")", d.b_to_a);
    cv::putText(img, "fraction of area", {W - 170, top + 15}, font, 0.45, black, 1, cv::LINE_AA);

    meshpost::write_file_atomic(path, encode_png(img));
}

std::string basename(const std::string& p) {
    const auto s = p.find_last_of('/');
    return s == std::string::npos ? p : p.substr(s + 1);
}

nlohmann::json stats_json(const meshpost::DistanceStats& s) {
    return {{"mean", s.mean}, {"rms", s.rms}, {"median", s.median}, {"p95", s.p95}, {"max", s.max}, {"samples", s.samples}};
}

void run_compare(const CompareOptions& o, const GlobalOptions& g) {
    if (!o.colored.empty() && lower_extension(o.colored) != ".ply")
        throw InvalidParameter("--colored " + o.colored + ": the coloured mesh is written as .ply");
    if (!o.histogram.empty() && lower_extension(o.histogram) != ".png")
        throw InvalidParameter("--histogram " + o.histogram + ": the histogram is written as .png");
    if (!(o.scale > 0) || !std::isfinite(o.scale)) throw InvalidParameter("--scale must be > 0 mm");
    meshpost::TriangleMesh a = meshpost::read_mesh(o.a);
    const meshpost::TriangleMesh b = meshpost::read_mesh(o.b);
    if (a.faces.empty()) throw IoError(o.a + ": the mesh has no faces");
    if (b.faces.empty()) throw IoError(o.b + ": the mesh has no faces");

    nlohmann::json j;
    j["tool"] = "endocast compare";
    j["a"] = o.a;
    j["b"] = o.b;
    j["align"] = o.align;
    std::ostringstream human;
    human << std::fixed;
    if (o.align == "rigid") {
        meshpost::RegisterResult reg;
        try {
            reg = meshpost::register_rigid(a, b);
        } catch (const meshpost::InvalidMesh& e) {
            throw IoError(std::string("--align rigid: ") + e.what());
        }
        a = meshpost::transformed(a, reg.transform);
        const auto& R = reg.transform.rotation;
        const auto& t = reg.transform.translation;
        j["alignment"] = {{"rotation", {{R[0][0], R[0][1], R[0][2]}, {R[1][0], R[1][1], R[1][2]}, {R[2][0], R[2][1], R[2][2]}}},
                          {"translation", {t[0], t[1], t[2]}},
                          {"rmse", reg.rmse_mm},
                          {"rotation_deg", reg.transform.angle_deg()},
                          {"iterations", reg.iterations},
                          {"converged", reg.converged},
                          {"pairs", reg.pairs}};
        human << std::setprecision(4) << "rigid alignment of A to B: rotation " << reg.transform.angle_deg()
              << " deg, translation (" << t[0] << ", " << t[1] << ", " << t[2] << ") mm, rmse " << reg.rmse_mm
              << " mm, " << reg.iterations << " ICP iterations" << (reg.converged ? "" : " (not converged)") << "\n";
    }
    meshpost::DeviationParams dp;
    dp.keep_samples = !o.histogram.empty();
    dp.vertex_distances = !o.colored.empty();
    meshpost::DeviationResult d;
    try {
        d = meshpost::surface_deviation(a, b, dp);
    } catch (const meshpost::InvalidMesh& e) {
        throw IoError(e.what());
    }
    j["a_to_b"] = stats_json(d.a_to_b);
    j["b_to_a"] = stats_json(d.b_to_a);
    j["hausdorff"] = d.hausdorff_mm;
    j["samples"] = d.a_to_b.samples + d.b_to_a.samples;
    j["sample_spacing_mm"] = d.sample_spacing_mm;
    j["sampling_error_bound_mm"] = d.sampling_error_bound_mm;
    j["scale_mm"] = o.scale;
    j["units"] = "mm";
    j["outputs"] = {{"colored", o.colored}, {"histogram", o.histogram}};

    if (!o.colored.empty()) write_colored_ply(a, d.a_vertex_distances, o.scale, o.colored);
    if (!o.histogram.empty()) write_histogram(d, o.scale, basename(o.a), basename(o.b), o.histogram);
    if (!o.report.empty()) meshpost::write_file_atomic(o.report, j.dump(2) + "\n");

    if (!g.quiet) {
        auto line = [&](const char* name, const meshpost::DistanceStats& s) {
            human << std::setprecision(4) << name << ": mean " << s.mean << ", rms " << s.rms << ", median "
                  << s.median << ", p95 " << s.p95 << ", max " << s.max << " mm (" << s.samples << " samples)\n";
        };
        line("A -> B", d.a_to_b);
        line("B -> A", d.b_to_a);
        human << "Hausdorff " << d.hausdorff_mm << " mm; sample spacing " << d.sample_spacing_mm
              << " mm, sampled maxima low by at most " << d.sampling_error_bound_mm << " mm\n";
        if (!o.colored.empty()) human << "wrote " << o.colored << "\n";
        if (!o.histogram.empty()) human << "wrote " << o.histogram << "\n";
        if (!o.report.empty()) human << "wrote " << o.report << "\n";
        std::cout << human.str();
    }
}

}  // namespace

void setup_compare(CLI::App& app, const GlobalOptions& g) {
    auto o = std::make_shared<CompareOptions>();
    auto* sub = app.add_subcommand(
        "compare",
        "Distances between two surfaces, both directions, sampled over the faces (not only the "
        "vertices): mean, rms, median, p95, max and Hausdorff in mm, area-weighted, with the bound "
        "on the sampling error. Optionally aligns A to B rigidly first.");
    sub->add_option("A", o->a, "First mesh (.stl, .ply, .obj, .off); aligned and coloured")->required();
    sub->add_option("B", o->b, "Second mesh (the reference)")->required();
    sub->add_option("--align", o->align,
                    "none, or rigid: align A to B (centroids and principal axes, then point-to-plane ICP)")
        ->check(CLI::IsMember({"none", "rigid"}))
        ->capture_default_str();
    sub->add_option("--report", o->report, "JSON report: a_to_b, b_to_a, hausdorff, samples, alignment");
    sub->add_option("--colored", o->colored,
                    "Write A (aligned) as a .ply with per-vertex colours: blue 0 -> green scale/2 -> red >= scale");
    sub->add_option("--histogram", o->histogram, "Write a .png of the distance distributions");
    sub->add_option("--scale", o->scale, "Distance in mm shown red in --colored (and the histogram's colour bar)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub->callback([o, &g] { run_compare(*o, g); });
}

}  // namespace endocast::cli
