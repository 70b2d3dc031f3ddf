// endocast::extract (endocast.h): the whole method, from a source to a checked mesh.
#include "endocast/endocast.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <iomanip>
#include <memory>
#include <sstream>
#include <thread>

#include "endocast/dicom_series.h"
#include "endocast/stages/bone_contact.h"
#include "endocast/stages/resample.h"
#include "io/slice_source.h"
#include "method/memory.h"
#include "method/refine.h"
#include "meshpost/measure.h"
#include "meshpost/patches.h"

namespace endocast {
namespace {

using Clock = std::chrono::steady_clock;
double seconds(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

// The coarse-to-fine path warns when the cavity's depth spans fewer of its coarse grid's voxels than
// this: the method's accuracy is measured down to ~20 voxels (docs/accuracy.md).
constexpr double kCoarseDepthWarnVoxels = 15.0;

// Forwards to a Progress that may be absent.
struct Log {
    Progress* p;
    void stage(const std::string& s) const { if (p) p->stage(s); }
    void info(const std::string& s) const { if (p) p->info(s); }
};

// A progress callback for a long loop: a line at most every 5 s, "  <verb> <done> of <total>
// <units>, <t> s, about <eta> s left", timed from the callback's creation.
std::function<void(int64_t, int64_t)> eta_lines(const std::string& verb, const std::string& units, Log log) {
    const auto start = Clock::now();
    auto last = std::make_shared<Clock::time_point>(start);
    return [=](int64_t done, int64_t total) {
        const auto now = Clock::now();
        if (seconds(*last, now) < 5 || done >= total || done <= 0) return;
        *last = now;
        const double t = seconds(start, now);
        std::ostringstream m;
        m << std::fixed << std::setprecision(0) << "  " << verb << " " << done << " of " << total << " " << units
          << ", " << t << " s, about " << t * double(total - done) / double(done) << " s left";
        log.info(m.str());
    };
}

// The state of one run between its steps.
struct Run {
    const Options& o;
    Log log;
    ExtractParams p;
    ShrinkParams shrink;
    std::unique_ptr<SliceSource> slices;
    bool coarse_to_fine = false;
    ReadResult in;          // the work grid's CT (float), or its geometry when in ct16
    Volume<int16_t> ct16;
    const Volume<float>* given = nullptr;  // a CT in memory (Source::volume)
    const Volume<int16_t>* given16 = nullptr;
    Result r;
};

// The path: an input read in slabs is planned from its header before anything is read (the
// coarse-to-fine path reads it twice: shrunk, then plane by plane); any other input is checked when
// its header is read (whole grid only); a CT in memory is on the whole grid.
void plan(Run& run) {
    const Options& o = run.o;
    const std::string& what = run.r.paths.front();
    if (!run.given && !run.given16) run.slices = open_slice_source(run.r.paths, o.read);
    if (run.slices) {
        run.r.plan = plan_extract(run.slices->header(), run.shrink, o.refine, o.refine_slab, o.max_memory_mb, what);
    } else if (o.refine != 0) {
        throw InvalidParameter(what + ": --refine needs an input read in slabs (a TIFF stack, raw data, a "
                               "NRRD with raw or gzip data, or an uncompressed MetaImage); convert it to one of these");
    } else if (run.given || run.given16) {
        run.r.plan.reason = "the method runs on the work grid (a CT in memory)";
    } else {
        run.r.plan.reason = "the method runs on the work grid (this input is read whole: the coarse-to-fine path needs "
                            "a TIFF stack, raw data or a NRRD with raw or gzip data)";
    }
    run.coarse_to_fine = run.r.plan.path == ExtractPath::CoarseToFine;
    if (run.coarse_to_fine) {
        if (run.p.surface != SurfaceMode::Iso)
            throw InvalidParameter("--surface " + std::string(to_string(run.p.surface)) +
                                   " is not available on the coarse-to-fine path (--refine, or a grid too large for "
                                   "memory): use --surface iso, or --downsample");
        run.shrink.downsample = run.r.plan.factor;
        run.p.keep_labels = true;
    }
}

void log_input(const Run& run) {
    const ReadResult& in = run.in;
    const Geometry& geo = in.volume.geometry();
    std::ostringstream s;
    s << "  " << in.info.format << " " << in.info.voxel_type << ", " << geo.dims[0] << " x " << geo.dims[1] << " x "
      << geo.dims[2] << " voxels of " << geo.spacing[0] << " x " << geo.spacing[1] << " x " << geo.spacing[2] << " mm";
    if (!in.info.spacing_source.empty()) s << " (voxel size: " << in.info.spacing_source << ")";
    run.log.info(s.str());
    if (run.shrink.crop || run.shrink.downsample != 1)
        run.log.info(in.info.read_path == "slabs"
                         ? "  read in slabs of " + std::to_string(shrink_slab_slices(run.r.input_grid.dims, run.shrink)) +
                               " slices, each cropped/downsampled as it was read (the whole volume was never in memory)"
                         : "  read whole, then cropped/downsampled (this input cannot be read in slabs)");
    for (const auto& series : in.info.series_found)
        if (series.series_uid == in.info.series_uid) run.log.info("  DICOM series " + describe_dicom_series(series));
}

// A CT in memory: cropped and downsampled as asked, else used where it is (no copy).
void take_given(Run& run) {
    const Geometry& g = run.given ? run.given->geometry() : run.given16->geometry();
    run.r.input_grid = g;
    run.in.info.format = "memory";
    run.in.info.voxel_type = run.given ? "float32" : "int16";
    run.in.info.paths = run.r.paths;
    if (!run.shrink.crop && run.shrink.downsample == 1) {
        run.in.volume.geometry() = g;
        return;
    }
    run.in.volume = shrink(run.given ? *run.given : to_float(*run.given16), run.shrink);
    run.given = nullptr;
    run.given16 = nullptr;
}

void read(Run& run) {
    const Options& o = run.o;
    const auto t0 = Clock::now();
    run.log.stage("read");
    run.log.info("path: " + run.r.plan.reason);
    if (run.given || run.given16) {
        take_given(run);
    } else {
        const std::vector<std::string>& inputs = run.r.paths;
        ReadOptions ro = o.read;
        ro.check_header = [&](const VolumeHeader& h) {  // an input read in slabs was checked by plan_extract
            if (!run.slices) check_extract_memory(h, run.shrink, o.max_memory_mb, inputs.front());
        };
        ro.slab_progress = eta_lines("read", "slices", run.log);
        run.log.info("reading " + inputs.front() +
                     (inputs.size() > 1 ? " (+" + std::to_string(inputs.size() - 1) + " files)" : ""));
        // A NRRD of 8- or 16-bit integers read whole comes as int16 straight away (never as float).
        ro.int16 = !run.coarse_to_fine && !run.shrink.crop && run.shrink.downsample == 1 &&
                   run.p.surface == SurfaceMode::Iso;
        run.in = read_shrunk(inputs, ro, run.shrink);
        run.r.input_grid = run.in.input_grid;
    }
    run.r.input = run.in.info;
    // The grid the mesh is on: the work grid, or on the coarse-to-fine path the input (cropped).
    run.r.mesh_grid = run.coarse_to_fine ? shrunk_geometry(run.r.input_grid, {run.shrink.crop, 1})
                                         : run.in.volume.geometry();
    run.r.read_s = seconds(t0, Clock::now());
    log_input(run);
}

// On the work grid, an integer-valued CT (most scans) is kept as int16: the same result (every stage
// compares the samples as floats) in half the memory. Not with --surface half-max (its field is
// built from a float CT) nor on the coarse-to-fine path (a block-averaged grid).
void choose_storage(Run& run) {
    if (run.given || run.given16) {
        run.r.ct_storage = run.given16 ? "int16" : "float32";
        return;
    }
    if (!run.coarse_to_fine && run.p.surface == SurfaceMode::Iso) {
        run.ct16 = run.in.volume16.empty() ? exact_int16(run.in.volume) : std::move(run.in.volume16);
        if (!run.ct16.empty()) {
            run.in.volume = Volume<float>();
            run.in.volume.geometry() = run.ct16.geometry();  // the geometry stays readable
        }
    }
    run.r.ct_storage = run.ct16.empty() ? "float32" : "int16";
}

// The method on the work grid. When nothing needs the CT afterwards, the method takes it over and
// keeps only the bone's box of it.
void run_method(Run& run) {
    choose_storage(run);
    run.p.progress = [&run](const std::string& stage) { run.log.stage(stage); };
    const bool keep_ct = run.o.keep_ct || run.coarse_to_fine;
    run.p.keep_mask = run.p.keep_mask || keep_ct;
    ExtractionResult& m = run.r.method;
    try {
        if (run.given) m = extract_endocast(*run.given, run.p);
        else if (run.given16) m = extract_endocast(*run.given16, run.p);
        else if (keep_ct) m = run.ct16.empty() ? extract_endocast(run.in.volume, run.p) : extract_endocast(run.ct16, run.p);
        else m = run.ct16.empty() ? extract_endocast(std::move(run.in.volume), run.p) : extract_endocast(std::move(run.ct16), run.p);
    } catch (const NoResult& e) {  // name the input: the method's messages cannot
        throw NoResult(run.r.paths.front() + ": " + e.what());
    }
    std::vector<Warning> input;
    for (const std::string& w : run.in.info.warnings) input.push_back({"input", w, {}});
    m.warnings.insert(m.warnings.begin(), input.begin(), input.end());
}

// The coarse-to-fine path's memory check for its fine pass, now that the coarse mesh is known.
void check_refine_memory(const Run& run) {
    const int F = run.r.plan.factor;
    const size_t faces = run.r.method.mesh.faces.size();
    const uint64_t need = estimate_refine_memory_bytes(run.slices->header(), run.shrink.crop, F, run.o.refine_slab,
                                                       uint64_t(faces) * uint64_t(F * F));
    const MemoryLimit& limit = run.r.plan.limit;
    if (limit.bytes != 0 && need > limit.bytes)
        throw OutOfMemory(run.r.paths.front() + ": the coarse-to-fine path's mesh of about " +
                          std::to_string(faces * size_t(F * F)) + " faces needs about " + std::to_string(need >> 20) +
                          " MB of memory (estimate), more than the " + std::to_string(limit.bytes >> 20) +
                          " MB allowed by " + limit.source + "; use a larger --refine factor, or --downsample");
}

// The band re-decided and meshed on the input's grid, plane by plane (refine.h).
RefineResult refine_band(Run& run, const Volume<uint8_t>& classes) {
    ExtractionResult& m = run.r.method;
    RefineParams rp;
    rp.isovalue = m.params.isovalue;
    rp.other_value = m.other_value;
    rp.slab_planes = run.o.refine_slab;
    rp.clip_mesh = &m.mesh;
    rp.progress = eta_lines("refined", "planes", run.log);
    const Geometry& input = run.r.input_grid;
    const Geometry& mesh_grid = run.r.mesh_grid;
    const CropBox box = run.shrink.crop.value_or(CropBox{{0, 0, 0}, input.dims});
    const Dims& d = input.dims;
    std::vector<float> plane(size_t(d[0] * d[1]));
    SliceSource& source = *run.slices;
    const PlaneReader read = [&](int64_t z, float* dst) {
        source.read(box.lo[2] + z, 1, plane.data());
        const int64_t nx = mesh_grid.dims[0];
        for (int64_t y = 0; y < mesh_grid.dims[1]; ++y)
            std::copy_n(plane.data() + size_t((box.lo[1] + y) * d[0] + box.lo[0]), nx, dst + size_t(y * nx));
    };
    return refine_full_resolution(mesh_grid, read, classes, run.r.plan.factor, rp);
}

void warn_coarse_depth(Run& run, const Geometry& coarse) {
    ExtractionResult& m = run.r.method;
    if (m.max_distance_mm >= kCoarseDepthWarnVoxels * coarse.largest_spacing()) return;
    std::ostringstream s;
    s << "the coarse-to-fine path ran the method on " << coarse.spacing[0] << " x " << coarse.spacing[1] << " x "
      << coarse.spacing[2] << " mm voxels (the scan's x " << run.r.plan.factor << "), where the cavity's depth ("
      << m.max_distance_mm << " mm) spans fewer than " << kCoarseDepthWarnVoxels
      << " voxels: the cavity's closures and cuts are decided there "
         "(look at the QC picture; without --refine the whole grid is used when it fits in memory)";
    m.warnings.push_back({"coarse_grid_shallow", s.str(),
                          {{"depth_voxels", m.max_distance_mm / coarse.largest_spacing()},
                           {"min_depth_voxels", kCoarseDepthWarnVoxels}}});
}

// Bone contact of the fine mesh, sampled as the coarse one was (the coarse CT, its probe, its skull).
void fine_bone_contact(Run& run, const PackedMask& skull) {
    ExtractionResult& m = run.r.method;
    BoneContactParams bcp = run.p.bone_contact;
    bcp.offset_mm = m.bone_contact_offset_mm;
    const BoneContact contact = bone_contact(m.mesh, run.in.volume, m.params.isovalue, bcp, skull);
    m.bone_contact = contact.share;
    m.face_on_bone = contact.face_on_bone;
    m.face_on_bone_ct.clear();
    m.face_leaks.clear();  // leak_share stays the coarse surface's
    m.warnings.erase(std::remove_if(m.warnings.begin(), m.warnings.end(),
                                    [](const Warning& w) { return w.code == "bone_contact_low"; }),
                     m.warnings.end());
    if (m.bone_contact < run.p.min_bone_contact)
        m.warnings.push_back({"bone_contact_low",
                              "bone contact " + std::to_string(m.bone_contact) + " of the refined mesh, expected >= " +
                                  std::to_string(run.p.min_bone_contact) + " (look at the QC picture)",
                              {{"bone_contact", m.bone_contact}, {"min_bone_contact", run.p.min_bone_contact},
                               {"probe_mm", m.bone_contact_offset_mm}}});
}

void refine(Run& run) {
    run.log.stage("refine");
    const auto t0 = Clock::now();
    check_refine_memory(run);
    ExtractionResult& m = run.r.method;
    const Volume<uint8_t> classes = refine_classes(m.mask, m.labels, run.in.volume, m.params.isovalue, m.mesh,
                                                   m.face_on_bone_ct);
    const Volume<uint8_t>& coarse_labels = m.labels;
    const PackedMask skull =
        PackedMask::where(coarse_labels.geometry(), [&](size_t i) { return coarse_labels[i] == kBone; });
    m.labels = Volume<uint8_t>();
    RefineResult fine = refine_band(run, classes);
    const Geometry coarse_grid = run.in.volume.geometry();
    run.r.refinement = Refinement{run.r.plan.factor, coarse_grid, m.ecv_ml, fine.box,
                                  int64_t(fine.slabs), int64_t(fine.band_voxels), int64_t(fine.band_endocast_voxels),
                                  int64_t(fine.changed_voxels), int64_t(fine.clipped_voxels),
                                  int64_t(fine.pieces_removed)};
    warn_coarse_depth(run, coarse_grid);
    m.mesh = std::move(fine.mesh);
    m.topology.reset();  // the coarse mesh's
    m.mask_volume_ml = fine.region_volume_ml;
    m.ecv_ml = meshpost::signed_volume_mm3(m.mesh) / 1000.0;
    m.surface_area_mm2 = meshpost::surface_area_mm2(m.mesh);
    fine_bone_contact(run, skull);
    run.r.refine_s = seconds(t0, Clock::now());
}

// The mesh's topology (the extraction's, analysed beside the dips, unless the coarse-to-fine path
// replaced the mesh) and self-intersections: the marching-cubes surface is embedded by construction
// (marching_cubes.h), so only the faces flush_dips moved are tested, against every face near them,
// unless check_all_faces. Options::beside_check runs on a thread of its own meanwhile (one thread:
// before). A failed check is rethrown after it joined.
void check(Run& run) {
    run.log.stage("check");
    const auto t0 = Clock::now();
    const Options& o = run.o;
    Result& r = run.r;
    const meshpost::TriangleMesh& mesh = r.method.mesh;
    std::exception_ptr beside_failed;
    const auto beside = [&] {
        try {
            o.beside_check(mesh);
        } catch (...) {
            beside_failed = std::current_exception();
        }
    };
    std::thread thread;
    if (o.beside_check) {
        if (omp_get_max_threads() > 1) thread = std::thread(beside);
        else beside();
    }
    std::exception_ptr check_failed;
    r.faces_tested = mesh.faces.size();
    try {
        r.topology = r.method.topology ? *r.method.topology : meshpost::analyze_topology(mesh);
        if (o.self_intersections) {
            std::vector<uint8_t> moved;
            if (!o.check_all_faces) {
                moved = run.coarse_to_fine ? std::vector<uint8_t>(mesh.faces.size(), 0)
                                           : meshpost::faces_touching(mesh, r.method.dips.moved_vertices);
                r.faces_tested = size_t(std::count(moved.begin(), moved.end(), uint8_t(1)));
            }
            r.self_intersections = int64_t(o.self_intersections(mesh, o.check_all_faces ? nullptr : &moved));
        }
    } catch (...) {
        check_failed = std::current_exception();
    }
    if (thread.joinable()) thread.join();
    if (check_failed) std::rethrow_exception(check_failed);
    if (beside_failed) std::rethrow_exception(beside_failed);
    r.check_s = seconds(t0, Clock::now());
}

void check_source(const Source& s) {
    const int given = int(!s.paths.empty()) + int(s.volume != nullptr) + int(s.volume16 != nullptr);
    if (given != 1) throw InvalidParameter("extract: give exactly one input (paths, a float CT or an int16 CT)");
    const Volume<float>* v = s.volume;
    if (v && v->empty()) throw InvalidParameter(s.name + ": the CT has no voxels");
    if (s.volume16 && s.volume16->empty()) throw InvalidParameter(s.name + ": the CT has no voxels");
    if (v) {
        const std::string bad = describe_non_finite(*v);
        if (!bad.empty()) throw InvalidParameter(s.name + ": " + bad);
    }
}

}  // namespace

Result extract(const Source& source, const Options& options, Progress* progress) {
    check_source(source);
    Run run{options, Log{progress}, options.method, ShrinkParams{options.crop, options.downsample}, {}, false,
            {}, {}, source.volume, source.volume16, {}};
    run.r.paths = source.paths.empty() ? std::vector<std::string>{source.name} : source.paths;
    plan(run);
    if (progress) progress->planned(run.r.plan);
    read(run);
    run_method(run);
    if (run.coarse_to_fine) refine(run);
    check(run);
    if (options.keep_ct) {
        if (run.given) run.r.ct = *run.given;
        else if (run.given16) run.r.ct16 = *run.given16;
        else if (run.ct16.empty()) run.r.ct = std::move(run.in.volume);
        else run.r.ct16 = std::move(run.ct16);
    }
    return std::move(run.r);
}

}  // namespace endocast
