#pragma once
#include <functional>
// Internals shared by the phantom generators (phantom.cpp: the ellipsoidal braincase;
// phantom/skull_base.cpp: the anatomical skull base; phantom/rodent.cpp: the mouse): small vector
// helpers, the counter-based noise, Hounsfield units, and the implicit cavity model of the
// anatomical phantoms behind phantom_cavity_signed_distance, with what builds, integrates and
// renders it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "endocast/phantom.h"
#include "kernels/vec3.h"  // add, sub, mul, dot, norm, normalized, cross

namespace endocast {
namespace phantom_detail {

constexpr double kPi = 3.14159265358979323846;

// ---- Hounsfield units -------------------------------------------------------------------------
constexpr double kAir = -1000.0;
constexpr double kBrain = 35.0;
constexpr double kSoftTissue = 30.0;
constexpr double kBoneHu = 1400.0;
constexpr double kSpineBoneHu = 1300.0; // vertebrae, clavicles
constexpr double kFat = -80.0;          // orbital fat
constexpr double kNoiseSigma = 20.0;    // HU
constexpr double kBlurVoxels = 0.6;     // partial-volume blur sigma, voxels
constexpr double kBandSigmas = 4.0;     // blending happens within +-4 sigma of an interface
constexpr double kMarginMm = 10.0;      // automatic grid: air margin around the head, mm

// ---- random numbers: splitmix64, identical on every platform -------------------------------
inline uint64_t splitmix64_mix(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/// Standard normal deviate that depends only on (key, voxel index): Marsaglia's polar method
/// fed by a counter-based splitmix64 stream.
inline double voxel_gaussian(uint64_t key, uint64_t index) {
    uint64_t state = key ^ splitmix64_mix(index * 0xD1B54A32D192ED03ULL + 0x8CB92BA72F3D8DD7ULL);
    for (int attempt = 0; attempt < 32; ++attempt) {
        const uint64_t r = splitmix64_mix(state += 0x9E3779B97F4A7C15ULL);
        const double u = (static_cast<double>(r >> 32) + 0.5) * (2.0 / 4294967296.0) - 1.0;
        const double v =
            (static_cast<double>(r & 0xFFFFFFFFULL) + 0.5) * (2.0 / 4294967296.0) - 1.0;
        const double s = u * u + v * v;
        if (s < 1.0 && s > 0.0) return u * std::sqrt(-2.0 * std::log(s) / s);
    }
    return 0.0;
}

/// The noise key of a seed (the same for every phantom kind).
inline uint64_t noise_key(uint64_t seed) {
    return splitmix64_mix(seed * 0x9E3779B97F4A7C15ULL + 0x2545F4914F6CDD1DULL);
}

inline std::string fmt(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

/// The anatomical skull-base phantom (phantom/skull_base.cpp); p.skull_base is true.
/// generate_phantom / generate_phantom_slabs for the skull-base phantom: `sink` empty renders res.ct
/// whole, else slabs of at most `slab_voxels` handed to `sink` (res.ct left empty).
PhantomResult generate_skull_base_phantom(const PhantomParams& p, int64_t slab_voxels = 0,
                                          const PhantomSlabSink& sink = {});

/// The mouse phantom (phantom/rodent.cpp); p.preset is Mouse. As generate_skull_base_phantom.
PhantomResult generate_rodent_phantom(const PhantomParams& p, int64_t slab_voxels = 0,
                                      const PhantomSlabSink& sink = {});

/// The most voxels a phantom may have: rendered whole (< 2^31: the int16 CT in memory) or in slabs
/// (< 2^40). Throws InvalidParameter naming the size otherwise.
void check_phantom_voxels(const Dims& dims, bool slabs);

/// Renders slices [0, geom.dims[2]) with render(k0, k1, dst) (dst: the slices' voxels, x fastest):
/// whole into res.ct when `sink` is empty, else in slabs of at most `slab_voxels` (at least a slice)
/// handed to `sink`.
void render_phantom_ct(const Geometry& geom, int64_t slab_voxels, const PhantomSlabSink& sink, PhantomResult& res,
                       const std::function<void(int64_t, int64_t, int16_t*)>& render);

}  // namespace phantom_detail

/// One primitive of an implicit cavity function (phantom frame, mm): an ellipsoid (centre,
/// orthonormal local axes, semi-axes; k0 = |D^-1 x|, k1 = |D^-2 x| in local coordinates x) with
/// the distance-like value k0 (k0 - 1) / k1 outside (exact zero set, unit gradient on it) and
/// rmin (k0 - 1) inside (gradient <= 1), a capsule, an axis-aligned rounded box or the half-space
/// {axes[0].(q - c) < 0} (axes[0] unit: its outward normal) (exact distances).
struct SkullBasePrim {
    enum class Kind { Ellipsoid, Capsule, Box, HalfSpace };
    Kind kind = Kind::Ellipsoid;
    Vec3 c{0, 0, 0};                                         ///< centre / capsule start, mm
    std::array<Vec3, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};  ///< ellipsoid local axes
    Vec3 r{1, 1, 1};                                         ///< semi-axes / box half sizes, mm
    Vec3 b{0, 0, 0};                                         ///< capsule end, mm
    double radius = 0;                                       ///< capsule / box rounding radius, mm
    /// Value (mm, negative inside) and its gradient g.
    double eval(const Vec3& q, Vec3& g) const;
    /// A lower bound of the value at q (mm), cheap (for skipping terms that cannot matter);
    /// 1-Lipschitz in q.
    double lower_bound(const Vec3& q) const;
    /// True when a lower bound of the value at q is >= threshold (a cheaper bound tried first).
    bool at_least(const Vec3& q, double threshold) const;
};

/// The truth cavity of the anatomical phantoms (skull base, mouse): {f < 0} for f a sequence of
/// smooth (polynomial smooth-min, blend radius k mm) unions and subtractions of primitives,
/// optionally cut by a half-space (the skull base's crop, the mouse's foramen magnum plane).
/// Immutable after construction: thread-safe.
struct SkullBaseModel {
    enum class Op { First, Union, Subtract };
    struct Term {
        Op op;
        SkullBasePrim prim;
        double k;                ///< blend radius, mm
        bool mirror_x = false;   ///< the prim united with its mirror image (x -> -x), blend k
    };
    std::vector<Term> terms;
    Vec3 box_lo{0, 0, 0}, box_hi{0, 0, 0};  ///< phantom-frame box holding the cavity, mm
    double lipschitz = 3.0;                 ///< bound on |grad f| (checked by the tests)
    Vec3 centre{0, 0, 0};                   ///< world mm of the phantom-frame origin
    double cs = 1, sn = 0;                  ///< tilt: world = centre + Rx(tilt) q
    bool cropped = false;                   ///< cut by the half-space below (any plane)
    Vec3 plane_n{0, 0, 1};                  ///< phantom frame: the cavity keeps n.q >= plane_h
    double plane_h = 0;

    /// The cavity function f (mm, distance-like near its zero set) and its gradient.
    double eval(const Vec3& q, Vec3& g) const;
    /// A lower bound of eval's value (mm, crop ignored) over the ball of `radius` mm around q,
    /// from the primitives' lower bounds: a union lowers f below both operands only where they
    /// lie within its blend radius k of each other, by at most k/4; a subtraction only raises f.
    /// Cheap: for skipping far points.
    double lower_bound(const Vec3& q, double radius = 0.0) const;
    /// Signed distance (mm, negative inside) of a phantom-frame point to the truth surface
    /// (crop included).
    double signed_distance(const Vec3& q) const;
    Vec3 to_phantom(const Vec3& world) const;
    Vec3 to_world(const Vec3& q) const;
    Vec3 dir_to_world(const Vec3& v) const;
};

namespace phantom_detail {

// ---- building, integrating and rendering an implicit phantom (phantom/skull_base.cpp) --------

/// Ellipsoid primitive: centre c, semi-axes r (mm) along x, y, z turned by yaw_deg about z.
SkullBasePrim ellipsoid(const Vec3& c, const Vec3& r, double yaw_deg = 0.0);
/// Capsule primitive: the segment a-b (mm) thickened by radius r (mm).
SkullBasePrim capsule(const Vec3& a, const Vec3& b, double r);
/// Half-space primitive {n.(q - c) < 0} (n normalised here: the outward normal).
SkullBasePrim half_space(const Vec3& c, const Vec3& n);

/// A straight canal through the bone: elliptic cross-section (semi-axes a along v, b across),
/// from `inset` mm inside the inner table along the unit axis u for `length` mm (phantom frame).
struct Canal {
    std::string name;
    Vec3 start{0, 0, 0};  ///< on the inner table
    Vec3 u{0, 0, -1}, v{1, 0, 0}, w{0, 1, 0};
    double a = 1, b = 1, length = 10;
    double inset = 2.0;
    double covering_radius = 1;  ///< the listed disk's radius
    /// Signed distance-like value (mm, negative inside).
    double sd(const Vec3& q) const;
};

/// The inner-table point of the ray from p (inside the cavity) along u: marching by `step` mm,
/// then bisection. Throws std::logic_error when p is not inside.
Vec3 inner_table_point(const SkullBaseModel& m, const Vec3& p, const Vec3& u, double step);

/// The truth volume (mL) of the model's cavity by the adaptive octree with leaves of h mm, and
/// error_ml = |V(h) - V(2h)| (+ 1e-9 relative): the integration converges with h^2, so its own
/// error is about a third of that. `lowest`: the lowest world z of the surface relative to
/// m.centre (mm). Independent of the thread count.
double truth_volume(const SkullBaseModel& m, double h, double& error_ml, double* lowest = nullptr);

/// Spacing after defaults (default_spacing mm where p.spacing is 0); throws InvalidParameter for
/// a negative or non-finite spacing, a negative size, a non-finite origin, a tilt outside
/// [-90, 90], a negative crop, and the ellipsoid phantoms' face options (frontal sinus, orbits,
/// optic canal radius, body), which `kind` (e.g. "skull-base") names in the message.
Vec3 validated_spacing(const PhantomParams& p, double default_spacing, const std::string& kind);

/// The CT grid of an implicit phantom: the phantom-frame box [plo, phi] rotated into the world
/// (m's tilt) for automatic sizes, an explicit size centred on p.grid_centre_mm (per axis); with
/// crop (crop_z > -inf) the lower face half a voxel below crop_z (world z relative to the centre).
/// `centre` receives the world position of the phantom-frame origin. Throws as check_phantom_voxels.
Geometry layout_grid(const PhantomParams& p, const SkullBaseModel& m, const Vec3& plo, const Vec3& phi,
                     const Vec3& spacing, double crop_z, bool slabs, Vec3& centre);

/// The Gaussian partial-volume blur of an interface (sigma mm; 0 = none).
struct EdgeBlur {
    double sigma = 0, band = 0, inv = 0;  ///< mm; band = kBandSigmas sigma; 1 / (sqrt 2 sigma)
    void set_sigma(double s) {
        sigma = s;
        band = kBandSigmas * s;
        inv = s > 0 ? 1.0 / (std::sqrt(2.0) * s) : 0.0;
    }
    /// Blurred indicator of {d < 0} (erfc of a planar edge), or a hard step without blur.
    double step(double d) const {
        if (sigma <= 0) return d < 0 ? 1.0 : (d > 0 ? 0.0 : 0.5);
        if (d <= -band) return 1.0;
        if (d >= band) return 0.0;
        return 0.5 * std::erfc(d * inv);
    }
};

/// Distance estimate (mm) from f and its gradient: f / |grad f| near the surface; f itself where
/// |grad f| < 1 (deep inside a flat subtracted ellipsoid f / |grad f| overestimates it many times).
inline double cavity_distance(double f, const Vec3& g) { return f / std::max(norm(g), 1.0); }

/// Soft regions blended as one union (they may overlap): each adds its blurred weight step(d)
/// and its value; the union's fraction is step of the least d, its value the weighted mean.
struct SoftBlend {
    const EdgeBlur& blur;
    double wsum = 0, vsum = 0, dmin = std::numeric_limits<double>::infinity();
    /// Adds a region at signed distance d (mm, negative inside) with `value`; returns its weight.
    double add(double d, double value) {
        const double w = blur.step(d);
        wsum += w;
        vsum += w * value;
        dmin = std::min(dmin, d);
        return w;
    }
    double fraction() const { return blur.step(dmin); }
    double value() const { return wsum > 0 ? vsum / wsum : 0.0; }
};

/// Renders slices [k0, k1) of geom into dst (their voxels, x fastest), slices in parallel: HU
/// = rd.hu(phantom-frame point) plus noise (kNoiseSigma, keyed by seed and the voxel index),
/// rounded and clamped to int16.
template <class Renderer>
void render_implicit(const Renderer& rd, const SkullBaseModel& m, bool noise, uint64_t seed, const Geometry& geom,
                     int64_t k0, int64_t k1, int16_t* dst) {
    const int64_t nx = geom.dims[0], ny = geom.dims[1];
    const uint64_t key = noise_key(seed);
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t k = k0; k < k1; ++k)
        for (int64_t j = 0; j < ny; ++j)
            for (int64_t i = 0; i < nx; ++i) {
                const Vec3 w = geom.index_to_world(static_cast<double>(i), static_cast<double>(j),
                                                   static_cast<double>(k));
                double v = rd.hu(m.to_phantom(w));
                const uint64_t idx = static_cast<uint64_t>(i + nx * (j + ny * k));
                if (noise) v += kNoiseSigma * voxel_gaussian(key, idx);
                v = std::clamp(std::floor(v + 0.5), -32768.0, 32767.0);
                dst[idx - static_cast<uint64_t>(nx * ny * k0)] = static_cast<int16_t>(v);
            }
}

}  // namespace phantom_detail
}  // namespace endocast
