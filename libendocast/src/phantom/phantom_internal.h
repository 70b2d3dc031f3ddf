#pragma once
#include <functional>
// Internals shared by the phantom generators (phantom.cpp: the ellipsoidal braincase;
// phantom/skull_base.cpp: the anatomical skull base): small vector helpers, the counter-based
// noise, Hounsfield units, and the implicit model of the skull-base cavity behind
// phantom_cavity_signed_distance.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
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

/// The most voxels a phantom may have: rendered whole (< 2^31: the int16 CT in memory) or in slabs
/// (< 2^40). Throws InvalidParameter naming the size otherwise.
void check_phantom_voxels(const Dims& dims, bool slabs);

/// Renders slices [0, geom.dims[2]) with render(k0, k1, dst) (dst: the slices' voxels, x fastest):
/// whole into res.ct when `sink` is empty, else in slabs of at most `slab_voxels` (at least a slice)
/// handed to `sink`.
void render_phantom_ct(const Geometry& geom, int64_t slab_voxels, const PhantomSlabSink& sink, PhantomResult& res,
                       const std::function<void(int64_t, int64_t, int16_t*)>& render);

}  // namespace phantom_detail

/// One primitive of the skull-base cavity function (phantom frame, mm): an ellipsoid (centre,
/// orthonormal local axes, semi-axes; k0 = |D^-1 x|, k1 = |D^-2 x| in local coordinates x) with
/// the distance-like value k0 (k0 - 1) / k1 outside (exact zero set, unit gradient on it) and
/// rmin (k0 - 1) inside (gradient <= 1), a capsule or an axis-aligned rounded box (exact
/// distances).
struct SkullBasePrim {
    enum class Kind { Ellipsoid, Capsule, Box };
    Kind kind = Kind::Ellipsoid;
    Vec3 c{0, 0, 0};                                         ///< centre / capsule start, mm
    std::array<Vec3, 3> axes{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};  ///< ellipsoid local axes
    Vec3 r{1, 1, 1};                                         ///< semi-axes / box half sizes, mm
    Vec3 b{0, 0, 0};                                         ///< capsule end, mm
    double radius = 0;                                       ///< capsule / box rounding radius, mm
    /// Value (mm, negative inside) and its gradient g.
    double eval(const Vec3& q, Vec3& g) const;
    /// A lower bound of the value at q (mm), cheap (for skipping terms that cannot matter).
    double lower_bound(const Vec3& q) const;
};

/// The truth cavity of the skull-base phantom: {f < 0} for f a sequence of smooth (polynomial
/// smooth-min, blend radius k mm) unions and subtractions of primitives, optionally
/// cut by the crop half-space. Immutable after construction: thread-safe.
struct SkullBaseModel {
    enum class Op { First, Union, Subtract };
    struct Term {
        Op op;
        SkullBasePrim prim;
        double k;  ///< blend radius, mm
    };
    std::vector<Term> terms;
    Vec3 box_lo{0, 0, 0}, box_hi{0, 0, 0};  ///< phantom-frame box holding the cavity, mm
    double lipschitz = 3.0;                 ///< bound on |grad f| (checked by the tests)
    Vec3 centre{0, 0, 0};                   ///< world mm of the phantom-frame origin
    double cs = 1, sn = 0;                  ///< tilt: world = centre + Rx(tilt) q
    bool cropped = false;
    Vec3 plane_n{0, 0, 1};                  ///< phantom frame: the cavity keeps n.q >= plane_h
    double plane_h = 0;

    /// The cavity function f (mm, distance-like near its zero set) and its gradient.
    double eval(const Vec3& q, Vec3& g) const;
    /// Signed distance (mm, negative inside) of a phantom-frame point to the truth surface
    /// (crop included).
    double signed_distance(const Vec3& q) const;
    Vec3 to_phantom(const Vec3& world) const;
    Vec3 to_world(const Vec3& q) const;
    Vec3 dir_to_world(const Vec3& v) const;
};

}  // namespace endocast
