// Microbenchmarks of the pipeline stages on a synthetic skull (the `human` phantom, deterministic),
// sized by the benchmark argument (voxels along x = y; z = 0.6 x). Counters report voxels per
// second. Run: build/bench/endocast_bench [--benchmark_filter=EDT] [--benchmark_repetitions=3]
// Thread count: OMP_NUM_THREADS. I/O benchmarks read ../shared/data when present.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <map>
#include <memory>

#include "endocast/stages/binarize.h"
#include "endocast/stages/components.h"
#include "endocast/stages/distance.h"
#include "endocast/io.h"
#include "endocast/stages/polygonize.h"
#include "endocast/stages/morphology.h"
#include "endocast/phantom.h"
#include "endocast/stages/seeds.h"
#include "endocast/stages/watershed.h"
#include "meshpost/cgal/self_intersections.h"
#include "meshpost/topology.h"

using namespace endocast;

namespace {

// Everything the stages need, computed once per size.
struct Fixture {
    Volume<float> ct;
    double iso = 0;
    Volume<uint8_t> bone, filled, labels;
    Volume<float> dist;
    SeedResult seeds;
    meshpost::TriangleMesh mesh;
};

const Fixture& fixture(int64_t n) {
    static std::map<int64_t, std::unique_ptr<Fixture>> cache;
    auto& f = cache[n];
    if (f) return *f;
    f = std::make_unique<Fixture>();
    PhantomParams pp;
    pp.size = {n, n, n * 3 / 5};
    const double s = 220.0 / double(n);  // the same head at every size
    pp.spacing = {s, s, s * 5.0 / 3.0};
    PhantomResult ph = generate_phantom(pp);
    f->ct = Volume<float>(ph.ct.geometry());
    for (size_t i = 0; i < f->ct.size(); ++i) f->ct[i] = ph.ct[i];
    f->iso = ph.suggested_iso;
    BinarizeParams bp;
    bp.isovalue = f->iso;
    f->bone = binarize(f->ct, bp).bone;
    f->filled = fill_voids(f->bone).bone;
    f->dist = distance_transform(f->filled);
    f->seeds = place_seeds(f->filled, f->dist);
    f->labels = watershed(f->seeds.labels, f->dist).labels;
    PolygonizeParams pol;
    pol.isovalue = f->iso;
    f->mesh = polygonize(f->ct, f->labels, pol).mesh;
    return *f;
}

void voxels(benchmark::State& st, size_t v) {
    st.counters["voxels"] = double(v);
    st.counters["voxels_per_s"] = benchmark::Counter(double(v), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Binarize(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    BinarizeParams bp;
    bp.isovalue = f.iso;
    for (auto _ : st) benchmark::DoNotOptimize(binarize(f.ct, bp));
    voxels(st, f.ct.size());
}

void BM_Components26(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    for (auto _ : st) benchmark::DoNotOptimize(connected_components(f.bone, Connectivity::Vertex26));
    voxels(st, f.bone.size());
}

void BM_EDT(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    for (auto _ : st) benchmark::DoNotOptimize(distance_transform(f.filled));
    voxels(st, f.filled.size());
}

// Ball closing (the void fill) for radius r voxels: the time must not depend on r.
void BM_BallClosing(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    VoidFillParams p;
    p.radius_voxels = double(st.range(1));
    for (auto _ : st) benchmark::DoNotOptimize(fill_voids(f.bone, p));
    voxels(st, f.bone.size());
}

void BM_Watershed(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    for (auto _ : st) benchmark::DoNotOptimize(watershed(f.seeds.labels, f.dist));
    voxels(st, f.dist.size());
}

void BM_Polygonize(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    PolygonizeParams p;
    p.isovalue = f.iso;
    for (auto _ : st) benchmark::DoNotOptimize(polygonize(f.ct, f.labels, p));
    voxels(st, f.ct.size());
    st.counters["faces"] = double(f.mesh.faces.size());
}

void BM_Topology(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    for (auto _ : st) benchmark::DoNotOptimize(meshpost::analyze_topology(f.mesh));
    st.counters["faces"] = double(f.mesh.faces.size());
}

void BM_SelfIntersections(benchmark::State& st) {
    const Fixture& f = fixture(st.range(0));
    for (auto _ : st) benchmark::DoNotOptimize(meshpost::find_self_intersections(f.mesh));
    st.counters["faces"] = double(f.mesh.faces.size());
}

void read_bench(benchmark::State& st, const std::string& rel) {
    const std::string path = std::string(ENDOCAST_SHARED_DATA) + "/" + rel;
    if (!std::filesystem::exists(path)) {
        st.SkipWithError(("missing " + path).c_str());
        for (auto _ : st) {
        }
        return;
    }
    size_t v = 0;
    for (auto _ : st) {
        ReadResult r = read_volume({path});
        v = r.volume.size();
        benchmark::DoNotOptimize(r);
    }
    voxels(st, v);
}
void BM_ReadNrrdCThead(benchmark::State& st) { read_bench(st, "cthead/cthead.nhdr"); }
void BM_ReadDicomHeadphantom(benchmark::State& st) { read_bench(st, "headphantom-dicom"); }

}  // namespace

BENCHMARK(BM_Binarize)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Components26)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_EDT)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_BallClosing)->Args({256, 3})->Args({256, 6})->Args({256, 12})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Watershed)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Polygonize)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Topology)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SelfIntersections)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ReadNrrdCThead)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
BENCHMARK(BM_ReadDicomHeadphantom)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

BENCHMARK_MAIN();
