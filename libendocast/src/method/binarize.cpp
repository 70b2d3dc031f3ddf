// Bone at the isovalue (automatic by Otsu when unset), thin bone recovered, largest component (binarize.h).
#include "endocast/stages/binarize.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <type_traits>
#include <vector>

#include "endocast/stages/components.h"

namespace endocast {
namespace {

struct Range {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -std::numeric_limits<double>::infinity();
};

template <class T>
Range value_range(const Volume<T>& ct) {
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
#pragma omp parallel for schedule(static) reduction(min : lo) reduction(max : hi)
    for (int64_t i = 0; i < int64_t(ct.size()); ++i) {
        lo = std::min(lo, float(ct[i]));
        hi = std::max(hi, float(ct[i]));
    }
    return {lo, hi};
}

std::string fmt(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

// Otsu's threshold from a histogram of `counts.size()` bins of `width` from `lo` (otsu_threshold).
double otsu_from_counts(const std::vector<uint64_t>& counts, double lo, double width) {
    const size_t bins = counts.size();
    std::vector<double> hist(counts.begin(), counts.end());
    double total = 0, sum = 0;
    for (size_t b = 0; b < bins; ++b) {
        total += hist[b];
        sum += double(b) * hist[b];
    }
    double w0 = 0, sum0 = 0, best = -1;
    size_t best_b = 0;
    for (size_t b = 0; b + 1 < bins; ++b) {
        w0 += hist[b];
        sum0 += double(b) * hist[b];
        if (w0 == 0 || w0 == total) continue;
        const double m0 = sum0 / w0, m1 = (sum - sum0) / (total - w0);
        const double between = w0 * (total - w0) * (m0 - m1) * (m0 - m1);
        if (between > best) {
            best = between;
            best_b = b;
        }
    }
    // Empty bins between two modes give a plateau of equal between-class variance: take the
    // middle of the plateau, not its first bin (classes: <= threshold and > threshold).
    size_t last_b = best_b;
    while (last_b + 2 < bins && hist[last_b + 1] == 0) ++last_b;
    return lo + (0.5 * double(best_b + last_b) + 0.5) * width;
}

// A histogram of a CT's values: counts[b] voxels whose value rounds to lo + b * width.
struct Histogram {
    std::vector<uint64_t> counts;
    double lo = 0, width = 1;
    double centre(size_t b) const { return lo + double(b) * width; }
    // The bins whose centres lie in (a, b]: [first, last).
    std::pair<size_t, size_t> bins_in(double a, double b) const {
        size_t first = 0, last = 0;
        while (first < counts.size() && !(centre(first) > a)) ++first;
        last = first;
        while (last < counts.size() && centre(last) <= b) ++last;
        return {first, last};
    }
};

// The bins [first, last) summed in groups of whole bins, about `groups` of them (integer-valued data
// binned per unit then stay free of the aliasing of a finer grouping); a last partial group is dropped.
std::vector<double> grouped(const Histogram& h, size_t first, size_t last, size_t groups) {
    const size_t n = last > first ? last - first : 0;
    if (n == 0) return {};
    const size_t g = (n + groups - 1) / groups;
    std::vector<double> out;
    for (size_t b = first; b + g <= last; b += g) {
        uint64_t sum = 0;
        for (size_t i = b; i < b + g; ++i) sum += h.counts[i];
        out.push_back(double(sum));
    }
    return out;
}

// The histogram's shape around automatic_isovalue's thresholds t < t2 (binarize.h): whether the
// voxels between them form a class of their own (a peak: soft tissue) or the falling tail of the
// bone's partial volumes, and whether the voxels below t hold two classes (air, and soft tissue
// close to it) parted by a valley.
struct HistogramShape {
    uint64_t mid = 0, high = 0;        // voxels in (t, t2] and > t2
    double peak = 0;                   // (t, t2]: highest interior group / the higher end group
    double t0 = 0;                     // Otsu's threshold of the voxels <= t
    uint64_t low_mid = 0, above_t = 0; // voxels in (t0, t] and > t
    double valley = 1;                 // <= t: lowest group between the two classes' modes / the lower mode
};

HistogramShape histogram_shape(const Histogram& h, double t, double t2) {
    HistogramShape s;
    for (size_t b = 0; b < h.counts.size(); ++b) {
        const double x = h.centre(b);
        if (x > t2) s.high += h.counts[b];
        else if (x > t) s.mid += h.counts[b];
        if (x > t) s.above_t += h.counts[b];
    }
    // A peak between t and t2: about 32 groups smoothed over three; the highest of the interior ones
    // (two in from each end) over the higher of the two next to the ends.
    {
        const auto [first, last] = h.bins_in(t, t2);
        const std::vector<double> g = grouped(h, first, last, 32);
        if (g.size() >= 6) {
            std::vector<double> sm(g.size());
            for (size_t i = 0; i < g.size(); ++i)
                sm[i] = (g[i] + (i > 0 ? g[i - 1] : g[i]) + (i + 1 < g.size() ? g[i + 1] : g[i])) / 3.0;
            double inner = 0;
            for (size_t i = 2; i + 2 < sm.size(); ++i) inner = std::max(inner, sm[i]);
            const double ends = std::max(sm[1], sm[sm.size() - 2]);
            s.peak = ends > 0 ? inner / ends : (inner > 0 ? std::numeric_limits<double>::infinity() : 0.0);
        }
    }
    // Below t: Otsu's split t0, and the valley between the modes on either side of it (about 64
    // groups; none when the modes are neighbours, as for one peak split in two).
    {
        const auto [first, last] = h.bins_in(-std::numeric_limits<double>::infinity(), t);
        if (last > first + 1) {
            const std::vector<uint64_t> below(h.counts.begin() + std::ptrdiff_t(first), h.counts.begin() + std::ptrdiff_t(last));
            s.t0 = otsu_from_counts(below, h.centre(first), h.width);
            for (size_t b = first; b < last; ++b)
                if (h.centre(b) > s.t0) s.low_mid += h.counts[b];
            const size_t per = (last - first + 63) / 64;
            const std::vector<double> g = grouped(h, first, last, 64);
            size_t mode_a = g.size(), mode_b = g.size();
            for (size_t i = 0; i < g.size(); ++i) {
                const bool a = h.centre(first + i * per + per - 1) <= s.t0;  // the group's last bin
                size_t& m = a ? mode_a : mode_b;
                if (m == g.size() || g[i] > g[m]) m = i;
            }
            if (mode_a < g.size() && mode_b < g.size() && mode_a < mode_b) {
                double low = std::min(g[mode_a], g[mode_b]);
                const double modes = low;
                for (size_t i = mode_a + 1; i < mode_b; ++i) low = std::min(low, g[i]);
                s.valley = modes > 0 ? low / modes : 1.0;
            }
        }
    }
    return s;
}

// Ratios of automatic_isovalue's tests (binarize.h).
constexpr double kClassRatio = 2.0;   // a class outnumbers the bone twice or more
constexpr double kPeakRatio = 2.0;    // its peak rises twice above its ends
constexpr double kValleyRatio = 0.5;  // the valley below half the lower mode

// The rule from the thresholds and the shape: the isovalue, its rule, the threshold not taken and
// the margin (the smallest factor by which a test deciding the rule cleared its bound).
struct IsovalueChoice {
    double value = 0, other = 0, margin = 0;
    std::string rule;
};

IsovalueChoice choose_isovalue(double t, double t2, const HistogramShape& s) {
    auto ratio = [](double a, double b) { return b > 0 ? a / b : (a > 0 ? std::numeric_limits<double>::infinity() : 0.0); };
    // Each test as the factor by which it passes (>= 1) or fails (< 1).
    const double tissue_class = ratio(double(s.mid), kClassRatio * double(s.high));
    const double tissue_peak = s.peak / kPeakRatio;
    const double low_class = ratio(double(s.low_mid), kClassRatio * double(s.above_t));
    const double low_valley = ratio(kValleyRatio, s.valley);
    IsovalueChoice c;
    if (tissue_class >= 1 && tissue_peak >= 1) {
        c = {t2, t, std::min(tissue_class, tissue_peak), "otsu-tissue-bone"};
        return c;
    }
    const double not_above = 1.0 / std::min(tissue_class, tissue_peak);  // how clearly the first rule failed
    if (low_class >= 1 && low_valley >= 1) {
        c = {t, t2, std::min({low_class, low_valley, not_above}), "otsu-tissue-near-air"};
        return c;
    }
    const double not_below = 1.0 / std::min(low_class, low_valley);
    c = {t, t2, std::min(not_above, not_below), "otsu-air-bone"};
    return c;
}

}  // namespace

template <class T>
double otsu_threshold(const Volume<T>& ct, double above) {
    // The range and the histogram are counted in parallel: integer counts, merged exactly, so the
    // result does not depend on the number of threads.
    const int64_t n = int64_t(ct.size());
    const T* v = ct.data();
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
#pragma omp parallel for schedule(static) reduction(min : lo) reduction(max : hi)
    for (int64_t i = 0; i < n; ++i) {
        const double x = v[i];
        if (x > above) {
            lo = std::min(lo, x);
            hi = std::max(hi, x);
        }
    }
    Range r{lo, hi};
    if (!(r.hi > r.lo)) {
        const Range all = value_range(ct);
        throw NoResult("automatic isovalue (Otsu): fewer than two distinct values above " +
                       fmt(above) + " (data range " + fmt(all.lo) + " .. " + fmt(all.hi) +
                       "), expected air, soft tissue and bone; set the isovalue (--iso)");
    }
    // Integer-valued data get one bin per unit when the range allows; otherwise 4096 bins.
    const double span = r.hi - r.lo;
    const size_t bins = span <= 65535 ? size_t(span) + 1 : 4096;
    const double width = span / double(bins - 1);
    std::vector<uint64_t> counts(bins, 0);
#pragma omp parallel
    {
        std::vector<uint64_t> mine(bins, 0);
#pragma omp for schedule(static) nowait
        for (int64_t i = 0; i < n; ++i) {
            const double x = v[i];
            // Rounded to the nearest bin, halves up (lround's rule for x >= lo, inline).
            if (x > above) ++mine[size_t((x - r.lo) / width + 0.5)];
        }
#pragma omp critical
        for (size_t b = 0; b < bins; ++b) counts[b] += mine[b];
    }
    return otsu_from_counts(counts, r.lo, width);
}

namespace {

// An int16 CT's values counted exactly (index value + 32768), over every voxel and over every 8th
// (empty_space_level's sample), in one pass: Otsu's threshold and the empty space's level from
// them are those of the two-pass loops (the same bins, the same median), for a fraction of the reads.
struct ValueCounts {
    std::vector<uint64_t> all, every8;
};

ValueCounts count_values(const Volume<int16_t>& ct) {
    constexpr size_t kValues = 65536;
    ValueCounts c;
    c.all.assign(kValues, 0);
    c.every8.assign(kValues, 0);
    const int64_t n = int64_t(ct.size());
    const int16_t* v = ct.data();
    // Per thread, in four interleaved tables (equal neighbouring values, common in a scan, would
    // otherwise wait on each other's increment), blocks of 8 voxels (every8: the first of each);
    // whole-number sums, so the counts do not depend on the order.
    const int64_t blocks = n / 8;
#pragma omp parallel
    {
        std::vector<uint64_t> all(4 * kValues, 0), every8(kValues, 0);
        auto at = [&](int64_t i) { return size_t(int32_t(v[i]) + 32768); };
#pragma omp for schedule(static) nowait
        for (int64_t b = 0; b < blocks; ++b) {
            const int64_t i = 8 * b;
            ++every8[at(i)];
            for (int j = 0; j < 8; ++j) ++all[size_t(j & 3) * kValues + at(i + j)];
        }
#pragma omp single nowait
        for (int64_t i = 8 * blocks; i < n; ++i) {
            ++all[at(i)];
            if ((i & 7) == 0) ++every8[at(i)];
        }
#pragma omp critical
        for (size_t k = 0; k < kValues; ++k) {
            c.all[k] += all[k] + all[kValues + k] + all[2 * kValues + k] + all[3 * kValues + k];
            c.every8[k] += every8[k];
        }
    }
    return c;
}

// otsu_threshold(ct, above) from the counts (the same range, bins and rounding: integers span at
// most 65535, one bin per value); NaN for fewer than two distinct values above it.
double otsu_from_values(const ValueCounts& c, double above = -std::numeric_limits<double>::infinity()) {
    int32_t lo = 0, hi = -1;
    for (int32_t k = 0; k < 65536; ++k)
        if (c.all[size_t(k)] && double(k - 32768) > above) {
            if (hi < lo) lo = k;
            hi = k;
        }
    if (!(hi > lo)) return std::numeric_limits<double>::quiet_NaN();  // the caller's loop throws
    const double rlo = double(lo - 32768), span = double(hi - lo);
    const size_t bins = span <= 65535 ? size_t(span) + 1 : 4096;
    const double width = span / double(bins - 1);
    std::vector<uint64_t> counts(bins, 0);
    for (int32_t k = lo; k <= hi; ++k)
        if (c.all[size_t(k)]) counts[size_t((double(k - 32768) - rlo) / width + 0.5)] += c.all[size_t(k)];
    return otsu_from_counts(counts, rlo, width);
}

// empty_space_level(ct, isovalue, t) from the counts.
double empty_space_level_from_values(const ValueCounts& c, double isovalue, double t) {
    size_t mid = 0, high = 0;
    for (int32_t k = 0; k < 65536; ++k) {
        const double x = double(k - 32768);
        if (x >= isovalue) high += c.all[size_t(k)];
        else if (x > t) mid += c.all[size_t(k)];
    }
    const bool tissue = t < isovalue && mid >= 2 * high;
    auto in_class = [&](double x) { return x < isovalue && (tissue ? x > t : x <= t); };
    uint64_t size = 0;
    for (int32_t k = 0; k < 65536; ++k)
        if (in_class(double(k - 32768))) size += c.every8[size_t(k)];
    if (size == 0) return isovalue;
    // The element nth_element puts at size / 2: the value of that rank in increasing order.
    const uint64_t rank = size / 2;
    uint64_t seen = 0;
    for (int32_t k = 0; k < 65536; ++k) {
        if (!in_class(double(k - 32768))) continue;
        seen += c.every8[size_t(k)];
        if (seen > rank) return double(k - 32768);
    }
    return isovalue;  // not reached
}

// The counts as a histogram of one bin per value, from the lowest value present to the highest.
Histogram histogram_of(const ValueCounts& c) {
    Histogram h;
    int32_t lo = 0, hi = -1;
    for (int32_t k = 0; k < 65536; ++k)
        if (c.all[size_t(k)]) {
            if (hi < lo) lo = k;
            hi = k;
        }
    if (hi < lo) return h;
    h.lo = double(lo - 32768);
    h.counts.assign(c.all.begin() + lo, c.all.begin() + hi + 1);
    return h;
}

// automatic_isovalue of an int16 CT from one count of its values (otsu_threshold read every voxel
// twice per threshold, and the classes' sizes once more: five passes): the same thresholds, sizes
// and rule.
double automatic_isovalue_from_values(const Volume<int16_t>& ct, std::string* rule, double* other, double* margin) {
    const ValueCounts c = count_values(ct);
    const double t = otsu_from_values(c);
    if (std::isnan(t)) return otsu_threshold(ct, -std::numeric_limits<double>::infinity());  // throws its message
    const double t2 = otsu_from_values(c, t);
    if (std::isnan(t2)) {  // otsu_threshold(ct, t) would have thrown NoResult
        if (rule) *rule = "otsu";
        if (other) *other = std::numeric_limits<double>::quiet_NaN();
        if (margin) *margin = std::numeric_limits<double>::quiet_NaN();
        return t;
    }
    const IsovalueChoice choice = choose_isovalue(t, t2, histogram_shape(histogram_of(c), t, t2));
    if (rule) *rule = choice.rule;
    if (other) *other = choice.other;
    if (margin) *margin = choice.margin;
    return choice.value;
}

// A float CT's values in 4096 bins over their range (otsu_threshold's rounding).
template <class T>
Histogram histogram_of(const Volume<T>& ct) {
    const Range r = value_range(ct);
    Histogram h;
    if (!(r.hi > r.lo)) return h;
    constexpr size_t kBins = 4096;
    h.lo = r.lo;
    h.width = (r.hi - r.lo) / double(kBins - 1);
    h.counts.assign(kBins, 0);
    const int64_t n = int64_t(ct.size());
    const T* v = ct.data();
#pragma omp parallel
    {
        std::vector<uint64_t> mine(kBins, 0);
#pragma omp for schedule(static) nowait
        for (int64_t i = 0; i < n; ++i) ++mine[size_t((double(v[i]) - r.lo) / h.width + 0.5)];
#pragma omp critical
        for (size_t b = 0; b < kBins; ++b) h.counts[b] += mine[b];
    }
    return h;
}

}  // namespace

template <class T>
double automatic_isovalue(const Volume<T>& ct, std::string* rule, double* other, double* margin) {
    if constexpr (std::is_same_v<T, int16_t>) return automatic_isovalue_from_values(ct, rule, other, margin);
    const double t = otsu_threshold(ct, -std::numeric_limits<double>::infinity());
    double t2 = t;
    try {
        t2 = otsu_threshold(ct, t);
    } catch (const NoResult&) {
        if (rule) *rule = "otsu";
        if (other) *other = std::numeric_limits<double>::quiet_NaN();
        if (margin) *margin = std::numeric_limits<double>::quiet_NaN();
        return t;
    }
    // The classes counted exactly against t and t2 (as the thresholds' own loops); the shape's
    // groups from a histogram of 4096 bins over the data's range.
    size_t mid = 0, high = 0;
    const T* c = ct.data();
#pragma omp parallel for schedule(static) reduction(+ : mid, high)
    for (int64_t i = 0; i < int64_t(ct.size()); ++i) {
        if (c[i] > t2) ++high;
        else if (c[i] > t) ++mid;
    }
    HistogramShape shape = histogram_shape(histogram_of(ct), t, t2);
    shape.mid = mid;
    shape.high = high;
    const IsovalueChoice choice = choose_isovalue(t, t2, shape);
    if (rule) *rule = choice.rule;
    if (other) *other = choice.other;
    if (margin) *margin = choice.margin;
    return choice.value;
}

template <class T>
double empty_space_level(const Volume<T>& ct, double isovalue) {
    return empty_space_level(ct, isovalue, otsu_threshold(ct, -std::numeric_limits<double>::infinity()));
}

template <class T>
double empty_space_level(const Volume<T>& ct, double isovalue, double t) {
    // Otsu's threshold t splits air from the rest; soft tissue (a living head) is the class between
    // t and the isovalue when it outnumbers the bone twice or more (automatic_isovalue's rule),
    // otherwise the empty space is air (a dry skull). Median of every 8th voxel of that class.
    const int64_t n = int64_t(ct.size());
    const T* c = ct.data();
    size_t mid = 0, high = 0;
#pragma omp parallel for schedule(static) reduction(+ : mid, high)
    for (int64_t i = 0; i < n; ++i) {
        if (c[i] >= isovalue) ++high;
        else if (c[i] > t) ++mid;
    }
    const bool tissue = t < isovalue && mid >= 2 * high;
    // The median does not depend on the order in which the samples are gathered.
    std::vector<float> v;
#pragma omp parallel
    {
        std::vector<float> mine;
#pragma omp for schedule(static) nowait
        for (int64_t i = 0; i < n; i += 8)
            if (c[i] < isovalue && (tissue ? c[i] > t : c[i] <= t)) mine.push_back(c[i]);
#pragma omp critical
        v.insert(v.end(), mine.begin(), mine.end());
    }
    if (v.empty()) return isovalue;
    auto m = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), m, v.end());
    return *m;
}

namespace {

// The midpoint of the isovalue and the empty space's level (thin_bone_side_limit's rule).
double side_limit_between(double isovalue, double empty_level) { return 0.5 * (isovalue + empty_level); }

}  // namespace

template <class T>
double thin_bone_side_limit(const Volume<T>& ct, double isovalue) {
    return side_limit_between(isovalue, empty_space_level(ct, isovalue));
}

namespace {

// A plate along one axis: v is no lower than its two neighbours l, r and rises above the higher
// of the two voxels beyond them (the floor, in the empty space: <= side_limit) by at least
// `prominence` of the way from that floor to the isovalue. Without branches (the ridge kernel runs
// it a row at a time, so that the compiler vectorizes it).
inline uint8_t is_plate(float v, float l, float r, float l2, float r2, double isovalue, double prominence,
                        double side_limit) {
    const double floor = std::max(l2, r2);
    return uint8_t((l <= v) & (r <= v) & (floor <= side_limit) & (double(v) - floor >= prominence * (isovalue - floor)));
}

// is_plate's constants in float, for plate_row's first pass.
struct PlateConstants {
    float iso, prominence, side;  // side: the largest float <= side_limit (floor <= side exactly as in double)
    PlateConstants(double isovalue, double prom, double side_limit)
        : iso(float(isovalue)), prominence(float(prom)), side(float(side_limit)) {
        if (double(side) > side_limit) side = std::nextafter(side, -std::numeric_limits<float>::infinity());
    }
};

// m[x] |= is_plate(...) over a row; restrict pointers and the constants as values, so that the
// compiler vectorizes it (a uint8_t store may alias anything otherwise: every sample reloaded).
// The rise test runs in float (four lanes in SSE2, not two): where its difference is within a bound
// of float rounding (far above it: 1e-5 of the magnitudes) of zero, or not a number, the voxel is
// tested again in double (`unsure`, scratch of n). The same voxels as is_plate.
void plate_row(const float* __restrict c, const float* __restrict l, const float* __restrict r,
               const float* __restrict l2, const float* __restrict r2, uint8_t* __restrict m,
               uint8_t* __restrict unsure, int64_t n, const PlateConstants& k, double isovalue,
               double prominence, double side_limit) {
    const float iso = k.iso, prom = k.prominence, side = k.side, pa = 1.0f + std::fabs(k.prominence);
    uint8_t any_unsure = 0;
    for (int64_t x = 0; x < n; ++x) {
        const float v = c[x], floor = std::max(l2[x], r2[x]);
        const uint8_t base = uint8_t((l[x] <= v) & (r[x] <= v) & (floor <= side));
        const float diff = (v - floor) - prom * (iso - floor);
        const float tol = 1e-5f * (std::fabs(v) + std::fabs(floor) + pa * (std::fabs(iso) + std::fabs(floor)) + 1.0f);
        const uint8_t sure = uint8_t(diff > tol), maybe = uint8_t(!(diff < -tol));
        m[x] |= uint8_t(base & sure);
        unsure[x] = uint8_t(base & maybe & uint8_t(!sure));
        any_unsure |= unsure[x];
    }
    if (!any_unsure) return;
    for (int64_t x = 0; x < n; ++x)
        if (unsure[x]) m[x] |= is_plate(c[x], l[x], r[x], l2[x], r2[x], isovalue, prominence, side_limit);
}

// thin_bone_ridges with its side limit given (binarize keeps it for return_thin_bone_tips).
template <class T>
size_t mark_thin_bone_ridges(const Volume<T>& ct, double isovalue, double prominence, double side_limit,
                             Volume<uint8_t>& bone) {
    const Dims& d = ct.dims();
    const float iso = static_cast<float>(isovalue);
    const int64_t nx = d[0], ny = d[1], nz = d[2], plane = d[0] * d[1];
    size_t marked = 0;
#pragma omp parallel reduction(+ : marked)
    {
        std::vector<uint8_t> m(static_cast<size_t>(nx), 0), unsure(static_cast<size_t>(nx), 0);
        const PlateConstants k(isovalue, prominence, side_limit);
        // An int16 CT's planes are read as floats once each into a ring of five (the plane and two
        // either side: the same values; the kernel then vectorizes as on a float CT, and no sample
        // is converted more than once per run). The runs are taken in turn by the threads (a few
        // per thread: the ridges cost more where the bone is, so halves were uneven).
        constexpr int kRing = 5;
        std::vector<float> ring(std::is_same_v<T, float> ? 0 : size_t(kRing * plane));
        std::array<int64_t, kRing> held;
        held.fill(-1);
        auto plane_at = [&](int64_t z) -> const float* {
            if constexpr (std::is_same_v<T, float>) {
                return ct.data() + z * plane;
            } else {
                const size_t slot = size_t(z % kRing);
                float* out = ring.data() + slot * size_t(plane);
                if (held[slot] != z) {
                    const T* src = ct.data() + z * plane;
                    for (int64_t i = 0; i < plane; ++i) out[i] = float(src[i]);
                    held[slot] = z;
                }
                return out;
            }
        };
        const int64_t runs = std::min<int64_t>(nz, 8 * int64_t(omp_get_num_threads()));
#pragma omp for schedule(dynamic, 1)
        for (int64_t run = 0; run < runs; ++run)
        for (int64_t z = nz * run / runs, z_end = nz * (run + 1) / runs; z < z_end; ++z) {
            const float* cz = plane_at(z);
            const bool along_z = z >= 2 && z + 2 < nz;
            const float *zl = nullptr, *zr = nullptr, *zl2 = nullptr, *zr2 = nullptr;
            if (along_z) zl = plane_at(z - 1), zr = plane_at(z + 1), zl2 = plane_at(z - 2), zr2 = plane_at(z + 2);
            for (int64_t y = 0; y < ny; ++y) {
                const int64_t off = nx * y;
                const float* c = cz + off;
                std::fill(m.begin(), m.end(), uint8_t(0));
                if (nx > 4) plate_row(c + 2, c + 1, c + 3, c, c + 4, m.data() + 2, unsure.data(), nx - 4, k, isovalue, prominence,
                                    side_limit);
                if (y >= 2 && y + 2 < ny)
                    plate_row(c, c - nx, c + nx, c - 2 * nx, c + 2 * nx, m.data(), unsure.data(), nx, k, isovalue, prominence,
                              side_limit);
                if (along_z)
                    plate_row(c, zl + off, zr + off, zl2 + off, zr2 + off, m.data(), unsure.data(), nx, k, isovalue, prominence,
                              side_limit);
                uint8_t* b = bone.data() + z * plane + off;
                for (int64_t x = 0; x < nx; ++x)
                    if (m[size_t(x)] && c[x] < iso) {
                        b[x] = 1;
                        ++marked;
                    }
            }
        }
    }
    return marked;
}

}  // namespace

template <class T>
size_t thin_bone_ridges(const Volume<T>& ct, double isovalue, double prominence, Volume<uint8_t>& bone) {
    if (!(prominence > 0)) return 0;
    return mark_thin_bone_ridges(ct, isovalue, prominence, thin_bone_side_limit(ct, isovalue), bone);
}

template <class T>
size_t return_thin_bone_tips(Volume<uint8_t>& labels, const Volume<T>& ct, double isovalue, double prominence,
                             double side_limit) {
    if (!(prominence > 0)) return 0;
    if (labels.dims() != ct.dims())
        throw InvalidParameter("return_thin_bone_tips: labels and CT differ in dimensions");
    const Dims& d = ct.dims();
    const int64_t st[3] = {1, d[0], d[0] * d[1]};
    const float iso = static_cast<float>(isovalue);
    const T* c = ct.data();
    const uint8_t* lab = labels.data();
    // The voxel at i goes back (the rule in binarize.h), decided on the labels as they are.
    auto goes_back = [&](int64_t i) {
        const float v = c[i];
        for (int a = 0; a < 3; ++a) {
            const int64_t s = st[a];
            if (lab[i - s] != kEndocast || lab[i + s] != kEndocast) continue;  // first: most voxels fail here
            if (!is_plate(v, c[i - s], c[i + s], c[i - 2 * s], c[i + 2 * s], isovalue, prominence, side_limit)) continue;
            const int64_t sb = st[(a + 1) % 3], sc = st[(a + 2) % 3];
            for (int u = -1; u <= 1; ++u)
                for (int w = -1; w <= 1; ++w) {
                    if (!u && !w) continue;
                    const int64_t j = i + u * sb + w * sc;
                    if (lab[j - s] == kEndocast && lab[j] == kEndocast && lab[j + s] == kEndocast) return true;
                }
        }
        return false;
    };
    std::vector<int64_t> back;
    // Which rows hold the endocast: a voxel goes back only with the endocast on both sides along an
    // axis, so in its own row (x), in both rows beside it (y) or in both rows above and below (z).
    std::vector<uint8_t> row_e(size_t(d[1] * d[2]), 0);
#pragma omp parallel for schedule(static)
    for (int64_t zy = 0; zy < d[1] * d[2]; ++zy)
        row_e[size_t(zy)] = std::memchr(lab + zy * d[0], kEndocast, size_t(d[0])) != nullptr;
    auto row_may = [&](int64_t y, int64_t z) {
        auto e = [&](int64_t yy, int64_t zz) { return row_e[size_t(yy + d[1] * zz)] != 0; };
        return e(y, z) || (e(y - 1, z) && e(y + 1, z)) || (e(y, z - 1) && e(y, z + 1));
    };
#pragma omp parallel
    {
        std::vector<int64_t> mine;
        // Slices handed out in turn: only those across the endocast cost anything.
#pragma omp for schedule(dynamic, 2) nowait
        for (int64_t z = 2; z < d[2] - 2; ++z)
            for (int64_t y = 2; y < d[1] - 2; ++y) {
                if (!row_may(y, z)) continue;
                for (int64_t x = 2; x < d[0] - 2; ++x) {
                    const int64_t i = x + st[1] * y + st[2] * z;
                    if (lab[i] != kEndocast && c[i] < iso && goes_back(i)) mine.push_back(i);
                }
            }
#pragma omp critical
        back.insert(back.end(), mine.begin(), mine.end());
    }
    for (int64_t i : back) labels[i] = kEndocast;  // the same set in any order
    return back.size();
}

template <class T>
BinarizeResult binarize(const Volume<T>& ct, const BinarizeParams& p) {
    BinarizeResult r;
    if (p.isovalue) {
        if (!std::isfinite(*p.isovalue))
            throw InvalidParameter("isovalue " + fmt(*p.isovalue) + ", expected a finite number");
        r.isovalue = *p.isovalue;
        r.isovalue_rule = "given";
    } else {
        r.isovalue = automatic_isovalue(ct, &r.isovalue_rule);
        r.isovalue_automatic = true;
    }
    const float iso = static_cast<float>(r.isovalue);
    r.bone = Volume<uint8_t>(ct.geometry());
    size_t count = 0;
#pragma omp parallel for schedule(static) reduction(+ : count)
    for (int64_t i = 0; i < int64_t(ct.size()); ++i) {
        const uint8_t b = ct[i] >= iso ? 1 : 0;
        r.bone[i] = b;
        count += b;
    }
    if (count == 0 || count == ct.size()) {  // the data range only for the message
        const Range range = value_range(ct);
        throw NoResult((count == 0 ? "no voxel is >= the isovalue " : "every voxel is >= the isovalue ") +
                       fmt(r.isovalue) + " (data range " + fmt(range.lo) + " .. " + fmt(range.hi) +
                       (count == 0 ? "): expected bone above it" : "): expected empty space below it"));
    }
    if (p.thin_bone_prominence > 0) {  // the side limit once, for the ridges and the pipeline's tips
        double level = 0;
        if constexpr (std::is_same_v<T, int16_t>) {  // one pass over the voxels, the same numbers
            const ValueCounts counts = count_values(ct);
            r.air_threshold = otsu_from_values(counts);
            if (std::isnan(r.air_threshold))  // one value: otsu_threshold's message
                r.air_threshold = otsu_threshold(ct, -std::numeric_limits<double>::infinity());
            level = empty_space_level_from_values(counts, r.isovalue, r.air_threshold);
        } else {
            r.air_threshold = otsu_threshold(ct, -std::numeric_limits<double>::infinity());
            level = empty_space_level(ct, r.isovalue, r.air_threshold);
        }
        r.thin_bone_side_limit = side_limit_between(r.isovalue, level);
        r.thin_bone_voxels = mark_thin_bone_ridges(ct, r.isovalue, p.thin_bone_prominence, r.thin_bone_side_limit, r.bone);
    }
    count += r.thin_bone_voxels;
    if (p.keep_largest_component)
        r.removed_fragment_voxels = keep_largest_component(r.bone, p.connectivity);
    r.bone_voxels = count - r.removed_fragment_voxels;
    return r;
}

// The CT types the pipeline runs on: float (any input) and int16 (integer-valued scans, half the
// memory; every sample is compared as float, so the results are the same).
#define ENDOCAST_BINARIZE_FOR(T)                                                                                  \
    template double automatic_isovalue<T>(const Volume<T>&, std::string*, double*, double*);                             \
    template double otsu_threshold<T>(const Volume<T>&, double);                                                \
    template double empty_space_level<T>(const Volume<T>&, double);                                             \
    template double empty_space_level<T>(const Volume<T>&, double, double);                                     \
    template size_t thin_bone_ridges<T>(const Volume<T>&, double, double, Volume<uint8_t>&);                    \
    template double thin_bone_side_limit<T>(const Volume<T>&, double);                                          \
    template size_t return_thin_bone_tips<T>(Volume<uint8_t>&, const Volume<T>&, double, double, double);       \
    template BinarizeResult binarize<T>(const Volume<T>&, const BinarizeParams&);
ENDOCAST_BINARIZE_FOR(float)
ENDOCAST_BINARIZE_FOR(int16_t)
#undef ENDOCAST_BINARIZE_FOR

}  // namespace endocast
