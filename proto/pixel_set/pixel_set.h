// Pixel sets: the pixels of one frame that a task covers, as run-length spans.
//
// A set is a sorted list of disjoint, non-adjacent half-open spans [begin, end) of
// linear pixel indices (index = y * width + x). That canonical form is what travels
// over the wire, makes equality a plain comparison of spans, and lets every set
// operation be one linear merge over the spans rather than over the pixels: the
// coordinator's planners build and split millions of pixels per second.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace tcfarm {

struct Span {
  uint32_t begin = 0;
  uint32_t end = 0;  // one past the last pixel

  uint32_t size() const { return end - begin; }
  friend bool operator==(const Span& a, const Span& b) { return a.begin == b.begin && a.end == b.end; }
  friend bool operator!=(const Span& a, const Span& b) { return !(a == b); }
};

class PixelSet {
 public:
  PixelSet() = default;  // the empty set

  // Every pixel of a frame of pixelCount pixels.
  static PixelSet Full(uint32_t pixelCount);

  // Validates spans that came from outside (the wire): each span must be non-empty,
  // lie inside [0, pixelCount), and start after the previous one ends. Adjacent spans
  // ([0,4) then [4,9)) are merged, since they are harmless and canonicalizing is cheap.
  // Throws std::invalid_argument naming the offending span.
  static PixelSet FromSpans(std::vector<Span> spans, uint32_t pixelCount);

  // Indices must be strictly ascending; throws std::invalid_argument otherwise.
  static PixelSet FromSortedIndices(const std::vector<uint32_t>& indices);

  const std::vector<Span>& spans() const { return spans_; }
  uint64_t size() const { return size_; }  // number of pixels
  bool empty() const { return spans_.empty(); }
  bool Contains(uint32_t index) const;  // O(log spans)

  PixelSet Union(const PixelSet& other) const;
  PixelSet Intersection(const PixelSet& other) const;
  PixelSet Difference(const PixelSet& other) const;  // this minus other

  // Calls callback(uint32_t index) for every pixel in ascending order.
  template <typename Callback>
  void ForEach(Callback&& callback) const {
    for (const Span& span : spans_) {
      for (uint32_t index = span.begin; index != span.end; ++index) callback(index);
    }
  }

  // Consecutive chunks of at most maxPixels pixels each that cover the set in
  // ascending order; every chunk but the last holds exactly maxPixels. Throws
  // std::invalid_argument when maxPixels is 0.
  std::vector<PixelSet> Split(uint32_t maxPixels) const;

  friend bool operator==(const PixelSet& a, const PixelSet& b) { return a.spans_ == b.spans_; }
  friend bool operator!=(const PixelSet& a, const PixelSet& b) { return !(a == b); }

 private:
  friend class PixelSetBuilder;
  PixelSet(std::vector<Span> canonicalSpans, uint64_t size) : spans_(std::move(canonicalSpans)), size_(size) {}

  std::vector<Span> spans_;
  uint64_t size_ = 0;
};

// Builds a set from pixels or spans given in ascending order, merging runs as they
// come: the cheap way to collect the result of a per-pixel test.
class PixelSetBuilder {
 public:
  // index must exceed every index added so far (and be below UINT32_MAX, so that the
  // span's end fits); throws std::invalid_argument otherwise.
  void Add(uint32_t index) {
    if (!spans_.empty() && spans_.back().end == index && index != UINT32_MAX) {
      ++spans_.back().end;  // the common case: extends the current run
      ++size_;
      return;
    }
    AddFirstOfRun(index);
  }

  // Adds [begin, end); begin must be at or after the end of everything added so far.
  // An empty span is ignored. Throws std::invalid_argument otherwise.
  void AddSpan(uint32_t begin, uint32_t end);

  uint64_t size() const { return size_; }

  // Returns the set and leaves the builder empty.
  PixelSet Build();

 private:
  void AddFirstOfRun(uint32_t index);

  std::vector<Span> spans_;
  uint64_t size_ = 0;
};

}  // namespace tcfarm
