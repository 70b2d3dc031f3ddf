// Scale invariance (issue 55): the same voxels with the spacing and origin divided by 25 (human
// anatomy at mouse size, as a mouse at ~40 um is to a human at 1 mm) give the same relative ECV
// error and the same surface distance in voxels, because every length of the method follows the
// cavity's depth or the voxel (derived_lengths, docs/lengths.md).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "test_helpers.h"

using namespace endocast;
using namespace endocast::testing;

namespace {

constexpr double kScale = 1.0 / 25.0;

struct Run {
    double ecv_error = 0;       // relative
    double mean_voxels = 0;     // mean |distance| of the vertices to the truth, in voxels
    double bone_contact = 0;
    std::vector<DerivedLength> lengths;
};

// Extracts `ct` (the phantom's voxels on a grid scaled by `scale`) and measures it against the
// phantom's truth, the mesh scaled back.
Run run(const PhantomResult& ph, double scale) {
    Volume<float> ct = to_float(ph.ct);
    Geometry& g = ct.geometry();
    for (int a = 0; a < 3; ++a) {
        g.spacing[size_t(a)] *= scale;
        g.origin[size_t(a)] *= scale;
    }
    ExtractParams p;
    p.binarize.isovalue = ph.suggested_iso;
    const ExtractionResult r = extract_endocast(ct, p);
    Run out;
    out.ecv_error = r.ecv_ml / (ph.true_ecv_ml * scale * scale * scale) - 1.0;
    const std::vector<double> w = vertex_areas(r.mesh);
    double sum = 0, area = 0;
    for (size_t i = 0; i < r.mesh.vertices.size(); ++i) {
        const auto& v = r.mesh.vertices[i];
        const double d = phantom_cavity_signed_distance(ph, {v[0] / scale, v[1] / scale, v[2] / scale});
        sum += w[i] * std::abs(d);
        area += w[i];
    }
    out.mean_voxels = sum / area / ph.geometry.spacing[0];
    out.bone_contact = r.bone_contact;
    out.lengths = derived_lengths(p, r);
    expect_clean_genus0(r.mesh);
    return out;
}

void expect_scale_free(const PhantomParams& pp, const char* name) {
    const PhantomResult ph = generate_phantom(pp);
    const Run full = run(ph, 1.0), small = run(ph, kScale);
    std::printf("%s: ECV error %+.4f %% / %+.4f %% (x1/25), mean distance %.4f / %.4f voxels, contact %.4f / %.4f\n",
                name, 100 * full.ecv_error, 100 * small.ecv_error, full.mean_voxels, small.mean_voxels,
                full.bone_contact, small.bone_contact);
    EXPECT_NEAR(small.ecv_error, full.ecv_error, 1e-4) << name;
    EXPECT_NEAR(small.mean_voxels, full.mean_voxels, 0.01 * full.mean_voxels + 1e-3) << name;
    EXPECT_NEAR(small.bone_contact, full.bone_contact, 2e-3) << name;
    // Every derived length is the full-size one times the scale.
    ASSERT_EQ(small.lengths.size(), full.lengths.size());
    for (size_t i = 0; i < full.lengths.size(); ++i)
        EXPECT_NEAR(small.lengths[i].mm, kScale * full.lengths[i].mm, 1e-6 * full.lengths[i].mm + 1e-12)
            << name << ": " << full.lengths[i].name;
}

}  // namespace

TEST(ScaleInvariance, HumanPhantomWithSpineAtOneTwentyFifth) {
    PhantomParams pp;
    pp.spine = true;
    pp.spacing = {2, 2, 2};
    expect_scale_free(pp, "human, spine, 2 mm");
}

TEST(ScaleInvariance, SkullBasePhantomAtOneTwentyFifth) {
    PhantomParams pp;
    pp.skull_base = true;
    pp.spacing = {1.5, 1.5, 1.5};
    expect_scale_free(pp, "skull base, living, 1.5 mm");
}
