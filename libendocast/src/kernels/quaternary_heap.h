#pragma once
// QuaternaryHeap: a max-heap with four children per node, for the priority floods that order
// their entries by a key of their own (creases.cpp's split of a plug). Half as deep as a binary
// heap, a node's children side by side in memory (fewer cache lines per level). With distinct keys
// it pops the same sequence as any other max-heap (std::pop_heap's), so it can replace one without
// changing a result. Internal header (kernels/: no io).
#include <algorithm>
#include <cstddef>
#include <vector>

namespace endocast {

template <class T, class Less>
class QuaternaryHeap {
public:
    explicit QuaternaryHeap(Less less) : less_(less) {}
    bool empty() const { return items_.empty(); }
    size_t size() const { return items_.size(); }
    // Items added without order, then heapify() once (Floyd's bottom-up build).
    void add(const T& t) { items_.push_back(t); }
    void heapify() {
        if (items_.size() < 2) return;
        for (size_t i = (items_.size() - 2) / 4 + 1; i-- > 0;) sift_down(i, items_[i]);
    }
    // Adds an item, keeping the heap's order (t by value: it may be one of the heap's own).
    void push(const T t) {
        size_t i = items_.size();
        items_.push_back(t);
        while (i > 0) {
            const size_t parent = (i - 1) / 4;
            if (!less_(items_[parent], t)) break;
            items_[i] = items_[parent];
            i = parent;
        }
        items_[i] = t;
    }
    // The largest item (the heap must not be empty).
    const T& top() const { return items_.front(); }
    // Removes and returns the largest item (the heap must not be empty).
    T pop() {
        const T top = items_.front();
        const T last = items_.back();
        items_.pop_back();
        if (!items_.empty()) sift_down(0, last);
        return top;
    }

private:
    // Places t at i or below, moving the larger children up (t by value: it may be items_[i]).
    void sift_down(size_t i, const T t) {
        const size_t n = items_.size();
        while (true) {
            const size_t first = 4 * i + 1;
            if (first >= n) break;
            size_t best = first;
            const size_t end = std::min(first + 4, n);
            for (size_t c = first + 1; c < end; ++c)
                if (less_(items_[best], items_[c])) best = c;
            if (!less_(t, items_[best])) break;
            items_[i] = items_[best];
            i = best;
        }
        items_[i] = t;
    }
    std::vector<T> items_;
    Less less_;
};

}  // namespace endocast
