// resolve(): the user's parameters made concrete once, and what the extraction then runs with.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "endocast/phantom.h"
#include "endocast/pipeline.h"
#include "test_helpers.h"

using namespace endocast;
using endocast::testing::grid;
using endocast::testing::to_float;

namespace {

// Air, tissue and bone in thirds along x: an automatic isovalue exists.
Volume<float> three_levels(const Geometry& g) {
    Volume<float> ct(g, 0.f);
    for (int64_t z = 0; z < g.dims[2]; ++z)
        for (int64_t y = 0; y < g.dims[1]; ++y)
            for (int64_t x = 0; x < g.dims[0]; ++x) ct(x, y, z) = x < g.dims[0] / 3 ? -1000.f : x < 2 * g.dims[0] / 3 ? 40.f : 1500.f;
    return ct;
}

}  // namespace

TEST(Resolve, IsovalueAndLengthsInMmAndVoxels) {
    const Volume<float> ct = three_levels(grid(30, 10, 10, {0.5, 0.8, 1.2}));
    ExtractParams p;
    ResolvedParams r = resolve(ct, p);
    std::string rule;
    EXPECT_EQ(r.isovalue, automatic_isovalue(ct, &rule));
    EXPECT_EQ(r.isovalue_rule, rule);
    EXPECT_TRUE(r.isovalue_automatic);
    EXPECT_EQ(r.smallest_spacing_mm, 0.5);  // voxels are of the smallest spacing
    EXPECT_EQ(r.void_radius_voxels, 6.0);
    EXPECT_DOUBLE_EQ(r.void_radius_mm, 3.0);
    EXPECT_EQ(r.seed_scale, p.seeds.scale);
    EXPECT_EQ(r.surface, SurfaceMode::Iso);

    p.binarize.isovalue = 300;
    p.void_fill.radius_mm = 2.0;
    p.surface = SurfaceMode::HalfMax;
    r = resolve(ct, p);
    EXPECT_EQ(r.isovalue, 300);
    EXPECT_FALSE(r.isovalue_automatic);
    EXPECT_EQ(r.isovalue_rule, "given");
    EXPECT_EQ(r.void_radius_mm, 2.0);
    EXPECT_DOUBLE_EQ(r.void_radius_voxels, 4.0);
    EXPECT_EQ(r.surface, SurfaceMode::HalfMax);
}

TEST(Resolve, BadParametersAreRefusedBeforeAnyWork) {
    const Volume<float> ct = three_levels(grid(30, 10, 10));
    ExtractParams p;
    p.binarize.isovalue = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(resolve(ct, p), InvalidParameter);
    p.binarize.isovalue = 300;
    p.seeds.scale = 1.0;
    EXPECT_THROW(resolve(ct, p), InvalidParameter);
    p.seeds.scale = 0.9;
    p.void_fill.radius_voxels = -1;
    EXPECT_THROW(resolve(ct, p), InvalidParameter);
    p.void_fill.radius_voxels = 6;
    EXPECT_NO_THROW(resolve(ct, p));
    const Volume<float> flat(grid(8, 8, 8), 5.f);  // no automatic isovalue in a constant volume
    EXPECT_THROW(resolve(flat, ExtractParams{}), NoResult);
}

TEST(Resolve, TheExtractionRunsWithWhatResolveGives) {
    PhantomParams pp;
    pp.preset = PhantomPreset::Dry;
    pp.spacing = {2, 2, 2};
    const PhantomResult ph = generate_phantom(pp);
    const Volume<float> ct = to_float(ph.ct);
    ExtractParams p;
    p.void_fill.radius_voxels = 3;
    const ResolvedParams want = resolve(ct, p);
    const ExtractionResult r = extract_endocast(ct, p);
    EXPECT_EQ(r.params.isovalue, want.isovalue);
    EXPECT_EQ(r.params.isovalue_rule, want.isovalue_rule);
    EXPECT_EQ(r.params.void_radius_mm, 6.0);
    EXPECT_EQ(r.params.void_radius_voxels, 3.0);
    EXPECT_EQ(r.params.seed_mode, SeedMode::Auto);
    EXPECT_NEAR(r.ecv_ml / ph.true_ecv_ml, 1.0, 0.02);
}
