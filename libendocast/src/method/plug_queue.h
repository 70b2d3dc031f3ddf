#pragma once
// The queues of creases.cpp's plug flood (split_plug): entries (a member's id c, a side s) taken
// largest rank first (the member's distance to the bone, other space's plus a lead), then other
// space first, then the smaller id. An entry's rank depends on its member and side only; the flood
// queues a member at most once per side, so no two entries are equal. Internal header.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

#include "kernels/quaternary_heap.h"

namespace endocast::plug_queue {

constexpr uint8_t kIn = 1, kOut = 2;  // the sides: the endocast, other space

// The general one: a max-heap of entries as two whole numbers compared high then low, the rank's
// bits (a rank is > 0 or +inf, whose bits order as the numbers do; + 0.0 makes a -0 +0), then the
// side's bit and the id counted down.
class RankHeap {
public:
    RankHeap(const std::vector<float>& dist, double lead_mm) : dist_(dist), lead_(lead_mm) {}
    void add(uint32_t c, uint8_t s) { heap_.add(entry(c, s)); }
    void heapify() { heap_.heapify(); }
    bool empty() const { return heap_.empty(); }
    void push(uint32_t c, uint8_t s) { heap_.push(entry(c, s)); }
    std::pair<uint32_t, uint8_t> pop() {
        const Entry e = heap_.pop();
        return {uint32_t(kId - (e.lo & kId)), (e.lo & kOutBit) ? kOut : kIn};
    }

private:
    struct Entry {
        uint64_t hi, lo;
    };
    static constexpr uint64_t kOutBit = uint64_t(1) << 63, kId = kOutBit - 1;
    Entry entry(uint32_t c, uint8_t s) const {
        const double rank = double(dist_[c]) + (s == kOut ? lead_ : 0.0) + 0.0;
        uint64_t bits = 0;
        std::memcpy(&bits, &rank, sizeof bits);
        return Entry{bits, (s == kOut ? kOutBit : 0) | (kId - uint64_t(c))};
    }
    struct Below {
        bool operator()(const Entry& a, const Entry& c) const { return a.hi != c.hi ? a.hi < c.hi : a.lo < c.lo; }
    };
    const std::vector<float>& dist_;
    double lead_;
    QuaternaryHeap<Entry, Below> heap_{Below{}};
};

// The same order from two max-heaps of 64-bit entries, one per side (half the bytes per entry, one
// comparison per step): the distance's bits high (float, > 0 or +inf: ordered as the numbers), the
// id counted down low. Within a side the rank orders as the distance when adding the lead keeps
// distinct distances apart in double: so it does when every distance is > 0 (not NaN) and the lead
// plus the largest finite distance is below 2^28 times the smallest (two floats differ by at least
// 2^-24 of the smaller, the sum rounds by at most 2^-53 of itself): `fits`, else use RankHeap. The
// heads of the two are compared by their ranks, a tie going to other space.
class SideHeaps {
public:
    static bool fits(const std::vector<float>& dist, double lead_mm) {
        float lo = std::numeric_limits<float>::infinity(), hi = 0;
        for (const float d : dist) {
            if (!(d > 0)) return false;  // 0, negative or NaN
            lo = std::min(lo, d);
            if (d < std::numeric_limits<float>::infinity()) hi = std::max(hi, d);
        }
        return std::isfinite(lead_mm) && lead_mm >= 0 && lead_mm + double(hi) < 0x1p28 * double(lo);
    }
    SideHeaps(const std::vector<float>& dist, double lead_mm) : dist_(dist), lead_(lead_mm) {}
    void add(uint32_t c, uint8_t s) { heap(s).add(entry(c)); }
    void heapify() {
        out_.heapify();
        in_.heapify();
    }
    bool empty() const { return out_.empty() && in_.empty(); }
    void push(uint32_t c, uint8_t s) { heap(s).push(entry(c)); }
    std::pair<uint32_t, uint8_t> pop() {
        bool take_out = !out_.empty();
        if (take_out && !in_.empty()) take_out = double(dist_[id(out_.top())]) + lead_ >= double(dist_[id(in_.top())]);
        if (take_out) return {id(out_.pop()), kOut};
        return {id(in_.pop()), kIn};
    }

private:
    using Heap = QuaternaryHeap<uint64_t, std::less<uint64_t>>;
    static constexpr uint32_t kTop = std::numeric_limits<uint32_t>::max();
    Heap& heap(uint8_t s) { return s == kOut ? out_ : in_; }
    uint64_t entry(uint32_t c) const {
        uint32_t bits = 0;
        std::memcpy(&bits, &dist_[c], sizeof bits);
        return uint64_t(bits) << 32 | (kTop - c);
    }
    static uint32_t id(uint64_t e) { return kTop - uint32_t(e); }
    const std::vector<float>& dist_;
    double lead_;
    Heap out_{std::less<uint64_t>{}}, in_{std::less<uint64_t>{}};
};

}  // namespace endocast::plug_queue
