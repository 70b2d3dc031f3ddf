#include "endocast/binarize.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include "endocast/components.h"

namespace endocast {
namespace {

struct Range {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -std::numeric_limits<double>::infinity();
};

Range value_range(const Volume<float>& ct) {
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
#pragma omp parallel for schedule(static) reduction(min : lo) reduction(max : hi)
    for (int64_t i = 0; i < int64_t(ct.size()); ++i) {
        lo = std::min(lo, ct[i]);
        hi = std::max(hi, ct[i]);
    }
    return {lo, hi};
}

std::string fmt(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

}  // namespace

double otsu_threshold(const Volume<float>& ct, double above) {
    Range r;
    for (size_t i = 0; i < ct.size(); ++i) {
        const double v = ct[i];
        if (v > above) {
            r.lo = std::min(r.lo, v);
            r.hi = std::max(r.hi, v);
        }
    }
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
    std::vector<double> hist(bins, 0.0);
    for (size_t i = 0; i < ct.size(); ++i) {
        const double v = ct[i];
        if (v > above) hist[size_t(std::lround((v - r.lo) / width))] += 1.0;
    }
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
    return r.lo + (0.5 * double(best_b + last_b) + 0.5) * width;
}

double automatic_isovalue(const Volume<float>& ct, std::string* rule) {
    const double t = otsu_threshold(ct, -std::numeric_limits<double>::infinity());
    double t2 = t;
    try {
        t2 = otsu_threshold(ct, t);
    } catch (const NoResult&) {
        if (rule) *rule = "otsu";
        return t;
    }
    size_t mid = 0, high = 0;
    for (size_t i = 0; i < ct.size(); ++i) {
        if (ct[i] > t2) ++high;
        else if (ct[i] > t) ++mid;
    }
    if (mid >= 2 * high) {
        if (rule) *rule = "otsu-tissue-bone";
        return t2;
    }
    if (rule) *rule = "otsu-air-bone";
    return t;
}

BinarizeResult binarize(const Volume<float>& ct, const BinarizeParams& p) {
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
    if (p.keep_largest_component)
        r.removed_fragment_voxels = keep_largest_component(r.bone, p.connectivity);
    r.bone_voxels = count - r.removed_fragment_voxels;
    return r;
}

}  // namespace endocast
