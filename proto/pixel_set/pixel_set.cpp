#include "proto/pixel_set/pixel_set.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace tcfarm {
namespace {

std::string SpanText(const Span& span) {
  return "[" + std::to_string(span.begin) + ", " + std::to_string(span.end) + ")";
}

// Appends a span to canonical output, merging it with the last one when they touch
// or overlap. Spans must arrive in ascending order of begin.
void AppendMerging(std::vector<Span>& out, uint64_t& size, Span span) {
  if (!out.empty() && span.begin <= out.back().end) {
    if (span.end > out.back().end) {
      size += span.end - out.back().end;
      out.back().end = span.end;
    }
    return;
  }
  out.push_back(span);
  size += span.size();
}

}  // namespace

PixelSet PixelSet::Full(uint32_t pixelCount) {
  if (pixelCount == 0) return PixelSet();
  return PixelSet({Span{0, pixelCount}}, pixelCount);
}

PixelSet PixelSet::FromSpans(std::vector<Span> spans, uint32_t pixelCount) {
  std::vector<Span> canonical;
  canonical.reserve(spans.size());
  uint64_t size = 0;
  for (size_t i = 0; i < spans.size(); ++i) {
    const Span& span = spans[i];
    const std::string where = "pixel set span " + std::to_string(i) + " " + SpanText(span);
    if (span.begin >= span.end) throw std::invalid_argument(where + " is empty or reversed; expected begin < end");
    if (span.end > pixelCount) {
      throw std::invalid_argument(where + " is out of range; expected end <= " + std::to_string(pixelCount) +
                                  " (the frame's pixel count)");
    }
    if (!canonical.empty() && span.begin < canonical.back().end) {
      throw std::invalid_argument(where + " overlaps or precedes the span before it " + SpanText(spans[i - 1]) +
                                  "; expected sorted, disjoint spans");
    }
    AppendMerging(canonical, size, span);
  }
  return PixelSet(std::move(canonical), size);
}

PixelSet PixelSet::FromSortedIndices(const std::vector<uint32_t>& indices) {
  PixelSetBuilder builder;
  for (uint32_t index : indices) builder.Add(index);
  return builder.Build();
}

bool PixelSet::Contains(uint32_t index) const {
  // The first span ending after index is the only one that can hold it.
  auto it = std::upper_bound(spans_.begin(), spans_.end(), index,
                             [](uint32_t value, const Span& span) { return value < span.end; });
  return it != spans_.end() && it->begin <= index;
}

PixelSet PixelSet::Union(const PixelSet& other) const {
  std::vector<Span> out;
  out.reserve(spans_.size() + other.spans_.size());
  uint64_t size = 0;
  auto a = spans_.begin(), b = other.spans_.begin();
  while (a != spans_.end() || b != other.spans_.end()) {
    const bool takeA = b == other.spans_.end() || (a != spans_.end() && a->begin <= b->begin);
    AppendMerging(out, size, takeA ? *a++ : *b++);
  }
  return PixelSet(std::move(out), size);
}

PixelSet PixelSet::Intersection(const PixelSet& other) const {
  std::vector<Span> out;
  uint64_t size = 0;
  auto a = spans_.begin(), b = other.spans_.begin();
  while (a != spans_.end() && b != other.spans_.end()) {
    const uint32_t begin = std::max(a->begin, b->begin);
    const uint32_t end = std::min(a->end, b->end);
    if (begin < end) AppendMerging(out, size, Span{begin, end});
    // The span that ends first cannot meet anything further in the other list.
    if (a->end < b->end) {
      ++a;
    } else {
      ++b;
    }
  }
  return PixelSet(std::move(out), size);
}

PixelSet PixelSet::Difference(const PixelSet& other) const {
  std::vector<Span> out;
  out.reserve(spans_.size());
  uint64_t size = 0;
  auto b = other.spans_.begin();
  for (const Span& span : spans_) {
    uint32_t cursor = span.begin;  // start of the part of span not yet decided
    while (b != other.spans_.end() && b->end <= cursor) ++b;
    auto cut = b;
    for (; cut != other.spans_.end() && cut->begin < span.end; ++cut) {
      if (cut->begin > cursor) AppendMerging(out, size, Span{cursor, cut->begin});
      cursor = std::max(cursor, cut->end);
      // A subtracted span that reaches past this one may cut the next one too.
      if (cut->end > span.end) break;
    }
    b = cut;
    if (cursor < span.end) AppendMerging(out, size, Span{cursor, span.end});
  }
  return PixelSet(std::move(out), size);
}

std::vector<PixelSet> PixelSet::Split(uint32_t maxPixels) const {
  if (maxPixels == 0) throw std::invalid_argument("PixelSet::Split: maxPixels is 0; expected >= 1");
  std::vector<PixelSet> chunks;
  chunks.reserve(static_cast<size_t>((size_ + maxPixels - 1) / maxPixels));
  PixelSetBuilder chunk;
  for (Span span : spans_) {
    while (span.begin < span.end) {
      const uint32_t room = static_cast<uint32_t>(maxPixels - chunk.size());
      const uint32_t take = std::min(room, span.size());
      chunk.AddSpan(span.begin, span.begin + take);
      span.begin += take;
      if (chunk.size() == maxPixels) chunks.push_back(chunk.Build());
    }
  }
  if (chunk.size() > 0) chunks.push_back(chunk.Build());
  return chunks;
}

void PixelSetBuilder::AddFirstOfRun(uint32_t index) {
  if (index == UINT32_MAX) {
    throw std::invalid_argument("pixel index 4294967295 is out of range; expected an index below 2^32 - 1");
  }
  AddSpan(index, index + 1);
}

void PixelSetBuilder::AddSpan(uint32_t begin, uint32_t end) {
  if (begin > end) throw std::invalid_argument("pixel span " + SpanText(Span{begin, end}) + " is reversed");
  if (begin == end) return;
  if (!spans_.empty() && begin < spans_.back().end) {
    throw std::invalid_argument("pixel span " + SpanText(Span{begin, end}) + " does not come after " +
                                SpanText(spans_.back()) + "; expected ascending, disjoint pixels");
  }
  if (!spans_.empty() && begin == spans_.back().end) {
    spans_.back().end = end;
  } else {
    spans_.push_back(Span{begin, end});
  }
  size_ += end - begin;
}

PixelSet PixelSetBuilder::Build() {
  PixelSet set(std::move(spans_), size_);
  spans_.clear();
  size_ = 0;
  return set;
}

}  // namespace tcfarm
