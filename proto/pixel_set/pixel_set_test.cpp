#include "proto/pixel_set/pixel_set.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <ostream>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace tcfarm {

// Readable failure messages for span lists.
void PrintTo(const Span& span, std::ostream* out) { *out << "[" << span.begin << ", " << span.end << ")"; }

namespace {

using Spans = std::vector<Span>;

std::vector<uint32_t> Indices(const PixelSet& set) {
  std::vector<uint32_t> out;
  set.ForEach([&](uint32_t index) { out.push_back(index); });
  return out;
}

// Asserts the canonical form every operation must produce: non-empty, sorted,
// disjoint, non-adjacent spans whose sizes add up to size().
void ExpectCanonical(const PixelSet& set) {
  uint64_t size = 0;
  for (size_t i = 0; i < set.spans().size(); ++i) {
    const Span& span = set.spans()[i];
    EXPECT_LT(span.begin, span.end) << "span " << i;
    if (i > 0) {
      EXPECT_GT(span.begin, set.spans()[i - 1].end) << "span " << i;
    }
    size += span.size();
  }
  EXPECT_EQ(set.size(), size);
  EXPECT_EQ(set.empty(), size == 0);
}

std::string ThrownMessage(const std::function<void()>& action) {
  try {
    action();
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "(nothing thrown)";
}

TEST(PixelSet, DefaultIsEmpty) {
  PixelSet set;
  EXPECT_TRUE(set.empty());
  EXPECT_EQ(set.size(), 0u);
  EXPECT_FALSE(set.Contains(0));
  EXPECT_TRUE(Indices(set).empty());
  EXPECT_EQ(set, PixelSet::Full(0));
}

TEST(PixelSet, FullCoversEveryPixel) {
  PixelSet set = PixelSet::Full(12);
  EXPECT_EQ(set.spans(), (Spans{{0, 12}}));
  EXPECT_EQ(set.size(), 12u);
  EXPECT_TRUE(set.Contains(0));
  EXPECT_TRUE(set.Contains(11));
  EXPECT_FALSE(set.Contains(12));
}

TEST(PixelSet, FullOfLargestFrame) {
  PixelSet set = PixelSet::Full(UINT32_MAX);
  EXPECT_EQ(set.size(), uint64_t{UINT32_MAX});
  EXPECT_TRUE(set.Contains(UINT32_MAX - 1));
  EXPECT_FALSE(set.Contains(UINT32_MAX));
}

TEST(PixelSet, FromSpansKeepsCanonicalSpans) {
  PixelSet set = PixelSet::FromSpans({{2, 4}, {6, 7}, {9, 10}}, 10);
  EXPECT_EQ(set.spans(), (Spans{{2, 4}, {6, 7}, {9, 10}}));
  EXPECT_EQ(set.size(), 4u);
  EXPECT_EQ(Indices(set), (std::vector<uint32_t>{2, 3, 6, 9}));
}

TEST(PixelSet, FromSpansMergesAdjacentSpans) {
  PixelSet set = PixelSet::FromSpans({{0, 4}, {4, 6}, {6, 7}, {9, 10}}, 10);
  EXPECT_EQ(set.spans(), (Spans{{0, 7}, {9, 10}}));
  EXPECT_EQ(set.size(), 8u);
}

TEST(PixelSet, FromSpansRejectsMalformedWireInput) {
  EXPECT_THROW(PixelSet::FromSpans({{3, 3}}, 10), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSpans({{5, 3}}, 10), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSpans({{5, 11}}, 10), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSpans({{0, 1}}, 0), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSpans({{4, 6}, {1, 2}}, 10), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSpans({{4, 6}, {5, 8}}, 10), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSpans({{4, 6}, {4, 6}}, 10), std::invalid_argument);
  EXPECT_NO_THROW(PixelSet::FromSpans({}, 0));
}

TEST(PixelSet, FromSpansMessagesSayWhichSpanAndWhy) {
  EXPECT_EQ(ThrownMessage([] { PixelSet::FromSpans({{0, 2}, {5, 11}}, 10); }),
            "pixel set span 1 [5, 11) is out of range; expected end <= 10 (the frame's pixel count)");
  EXPECT_EQ(ThrownMessage([] { PixelSet::FromSpans({{4, 6}, {5, 8}}, 10); }),
            "pixel set span 1 [5, 8) overlaps or precedes the span before it [4, 6); expected sorted, disjoint "
            "spans");
  EXPECT_EQ(ThrownMessage([] { PixelSet::FromSpans({{7, 7}}, 10); }),
            "pixel set span 0 [7, 7) is empty or reversed; expected begin < end");
}

TEST(PixelSet, FromSortedIndices) {
  PixelSet set = PixelSet::FromSortedIndices({0, 1, 2, 5, 7, 8});
  EXPECT_EQ(set.spans(), (Spans{{0, 3}, {5, 6}, {7, 9}}));
  EXPECT_EQ(set.size(), 6u);
  EXPECT_EQ(PixelSet::FromSortedIndices({}), PixelSet());
  EXPECT_EQ(PixelSet::FromSortedIndices({UINT32_MAX - 1}).spans(), (Spans{{UINT32_MAX - 1, UINT32_MAX}}));
}

TEST(PixelSet, FromSortedIndicesRejectsUnsortedDuplicateOrTooLarge) {
  EXPECT_THROW(PixelSet::FromSortedIndices({3, 2}), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSortedIndices({3, 3}), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSortedIndices({0, 1, 1}), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSortedIndices({UINT32_MAX}), std::invalid_argument);
  EXPECT_THROW(PixelSet::FromSortedIndices({UINT32_MAX - 1, UINT32_MAX}), std::invalid_argument);
}

TEST(PixelSetBuilder, MergesRunsAndSpans) {
  PixelSetBuilder builder;
  builder.Add(1);
  builder.AddSpan(2, 5);
  builder.AddSpan(7, 7);  // empty: ignored
  builder.Add(8);
  builder.AddSpan(9, 10);
  EXPECT_EQ(builder.size(), 6u);
  PixelSet set = builder.Build();
  EXPECT_EQ(set.spans(), (Spans{{1, 5}, {8, 10}}));
  EXPECT_EQ(builder.size(), 0u);
  EXPECT_TRUE(builder.Build().empty());
  EXPECT_THROW(builder.AddSpan(5, 4), std::invalid_argument);
}

TEST(PixelSet, ContainsAtSpanBoundaries) {
  PixelSet set = PixelSet::FromSpans({{2, 4}, {6, 7}}, 10);
  const std::vector<bool> expected = {false, false, true, true, false, false, true, false, false, false};
  for (uint32_t i = 0; i < expected.size(); ++i) EXPECT_EQ(set.Contains(i), expected[i]) << i;
  EXPECT_FALSE(set.Contains(UINT32_MAX));
}

TEST(PixelSet, UnionMergesTouchingAndOverlappingSpans) {
  PixelSet a = PixelSet::FromSpans({{0, 2}, {5, 8}, {20, 21}}, 30);
  PixelSet b = PixelSet::FromSpans({{2, 3}, {6, 10}, {12, 13}}, 30);
  PixelSet u = a.Union(b);
  EXPECT_EQ(u.spans(), (Spans{{0, 3}, {5, 10}, {12, 13}, {20, 21}}));
  EXPECT_EQ(u.size(), 3u + 5u + 1u + 1u);
  EXPECT_EQ(b.Union(a), u);
  EXPECT_EQ(a.Union(PixelSet()), a);
  EXPECT_EQ(PixelSet().Union(a), a);
  EXPECT_EQ(a.Union(a), a);
}

TEST(PixelSet, IntersectionKeepsCommonPixels) {
  PixelSet a = PixelSet::FromSpans({{0, 4}, {6, 12}}, 20);
  PixelSet b = PixelSet::FromSpans({{3, 7}, {8, 9}, {11, 15}}, 20);
  PixelSet i = a.Intersection(b);
  EXPECT_EQ(i.spans(), (Spans{{3, 4}, {6, 7}, {8, 9}, {11, 12}}));
  EXPECT_EQ(i.size(), 4u);
  EXPECT_EQ(b.Intersection(a), i);
  EXPECT_TRUE(a.Intersection(PixelSet()).empty());
  EXPECT_EQ(a.Intersection(a), a);
  EXPECT_TRUE(PixelSet::FromSpans({{0, 2}}, 5).Intersection(PixelSet::FromSpans({{2, 4}}, 5)).empty());
}

TEST(PixelSet, DifferenceCutsSpansThatReachAcrossSeveralSpans) {
  PixelSet a = PixelSet::FromSpans({{0, 4}, {6, 12}, {14, 16}}, 20);
  PixelSet b = PixelSet::FromSpans({{2, 7}, {9, 10}, {11, 15}}, 20);
  PixelSet d = a.Difference(b);
  EXPECT_EQ(d.spans(), (Spans{{0, 2}, {7, 9}, {10, 11}, {15, 16}}));
  EXPECT_EQ(d.size(), 6u);
  EXPECT_EQ(b.Difference(a).spans(), (Spans{{4, 6}, {12, 14}}));
  EXPECT_EQ(a.Difference(PixelSet()), a);
  EXPECT_TRUE(a.Difference(a).empty());
  EXPECT_TRUE(a.Difference(PixelSet::Full(20)).empty());
  EXPECT_EQ(PixelSet::Full(20).Difference(a).spans(), (Spans{{4, 6}, {12, 14}, {16, 20}}));
}

TEST(PixelSet, SplitIntoChunksInOrder) {
  PixelSet set = PixelSet::FromSpans({{0, 3}, {5, 10}, {12, 13}}, 20);
  std::vector<PixelSet> chunks = set.Split(4);
  ASSERT_EQ(chunks.size(), 3u);
  EXPECT_EQ(chunks[0].spans(), (Spans{{0, 3}, {5, 6}}));
  EXPECT_EQ(chunks[1].spans(), (Spans{{6, 10}}));
  EXPECT_EQ(chunks[2].spans(), (Spans{{12, 13}}));
}

TEST(PixelSet, SplitEdgeCases) {
  EXPECT_TRUE(PixelSet().Split(5).empty());
  EXPECT_THROW(PixelSet::Full(3).Split(0), std::invalid_argument);
  std::vector<PixelSet> whole = PixelSet::Full(8).Split(8);
  ASSERT_EQ(whole.size(), 1u);
  EXPECT_EQ(whole[0], PixelSet::Full(8));
  std::vector<PixelSet> singles = PixelSet::Full(3).Split(1);
  ASSERT_EQ(singles.size(), 3u);
  for (uint32_t i = 0; i < 3; ++i) EXPECT_EQ(singles[i].spans(), (Spans{{i, i + 1}}));
  EXPECT_EQ(PixelSet::Full(5).Split(UINT32_MAX).size(), 1u);
}

TEST(PixelSet, EqualityComparesPixels) {
  EXPECT_EQ(PixelSet::FromSpans({{1, 3}, {3, 5}}, 9), PixelSet::FromSortedIndices({1, 2, 3, 4}));
  EXPECT_NE(PixelSet::FromSpans({{1, 3}}, 9), PixelSet::FromSpans({{1, 4}}, 9));
  EXPECT_NE(PixelSet::FromSpans({{1, 3}}, 9), PixelSet());
}

PixelSet RandomSet(std::mt19937& rng, uint32_t universe, std::set<uint32_t>& reference) {
  // Runs of random length make both long spans and isolated pixels.
  std::uniform_int_distribution<uint32_t> runLength(1, 6);
  std::bernoulli_distribution inside(0.45);
  PixelSetBuilder builder;
  for (uint32_t index = 0; index < universe;) {
    const uint32_t end = std::min(universe, index + runLength(rng));
    if (inside(rng)) {
      builder.AddSpan(index, end);
      for (uint32_t i = index; i < end; ++i) reference.insert(i);
    }
    index = end;
  }
  return builder.Build();
}

std::vector<uint32_t> Sorted(const std::set<uint32_t>& set) { return {set.begin(), set.end()}; }

TEST(PixelSet, RandomizedAgainstStdSet) {
  std::mt19937 rng(20240917);
  for (int round = 0; round < 500; ++round) {
    const uint32_t universe = std::uniform_int_distribution<uint32_t>(0, 120)(rng);
    std::set<uint32_t> refA, refB;
    PixelSet a = RandomSet(rng, universe, refA);
    PixelSet b = RandomSet(rng, universe, refB);
    ASSERT_EQ(Indices(a), Sorted(refA));

    std::set<uint32_t> refUnion = refA, refIntersection, refDifference;
    refUnion.insert(refB.begin(), refB.end());
    for (uint32_t i : refA) (refB.count(i) ? refIntersection : refDifference).insert(i);

    const PixelSet u = a.Union(b), i = a.Intersection(b), d = a.Difference(b);
    ExpectCanonical(u);
    ExpectCanonical(i);
    ExpectCanonical(d);
    ASSERT_EQ(Indices(u), Sorted(refUnion)) << "round " << round;
    ASSERT_EQ(Indices(i), Sorted(refIntersection)) << "round " << round;
    ASSERT_EQ(Indices(d), Sorted(refDifference)) << "round " << round;
    for (uint32_t index = 0; index <= universe; ++index) ASSERT_EQ(a.Contains(index), refA.count(index) == 1);

    // The wire round trip and the index constructor agree with the builder.
    ASSERT_EQ(PixelSet::FromSpans(a.spans(), universe), a);
    ASSERT_EQ(PixelSet::FromSortedIndices(Sorted(refA)), a);

    const uint32_t maxPixels = std::uniform_int_distribution<uint32_t>(1, 10)(rng);
    std::vector<uint32_t> rejoined;
    std::vector<PixelSet> chunks = a.Split(maxPixels);
    for (size_t c = 0; c < chunks.size(); ++c) {
      ExpectCanonical(chunks[c]);
      ASSERT_LE(chunks[c].size(), maxPixels);
      if (c + 1 < chunks.size()) {
        ASSERT_EQ(chunks[c].size(), maxPixels);
      }
      chunks[c].ForEach([&](uint32_t index) { rejoined.push_back(index); });
    }
    ASSERT_EQ(rejoined, Sorted(refA));
  }
}

}  // namespace
}  // namespace tcfarm
