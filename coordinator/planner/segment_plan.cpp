#include "coordinator/planner/segment_plan.h"

#include <algorithm>
#include <cmath>

#include "coordinator/planner/planner.h"

namespace tcfarm {
namespace {

// How many workers a trace of `share` of a frame's pixels can keep busy at once.
double SpreadOf(double share, uint64_t pixelsPerFrame, int workers) {
  const double tasks = std::max(1.0, std::floor(share * double(pixelsPerFrame) / PlannerOptions::kMinTaskPixels));
  return std::min(double(workers), tasks);
}

// In brute-force frames: each segment's start, then every later frame, then the audit's
// brute-force trace of the last frame (every exact job checks it bit for bit), which the
// job's measured cost counts too.
double SegmentsWork(int frameCount, int segments, const SegmentPrices& p) {
  constexpr double kAuditFrames = 1;
  return segments * p.startPrice + (frameCount - segments) * p.framePrice + kAuditFrames;
}

SegmentPlan Predict(int segments, int frameCount, int workers, uint64_t pixelsPerFrame, const SegmentPrices& p) {
  SegmentPlan plan;
  plan.length = (frameCount + segments - 1) / segments;
  plan.segments = segments = (frameCount + plan.length - 1) / plan.length;  // the cut's own count
  plan.prices = p;
  const double work = SegmentsWork(frameCount, segments, p);
  plan.predictedRelativeCost = work / frameCount;
  // The longest chain: one segment's frames, one after the other, each spread over the
  // workers its segment has (segments share them).
  const int perSegment = std::max(1, workers / segments);
  const double startSpan = p.startPrice / SpreadOf(1.0, pixelsPerFrame, perSegment);
  const double frameSpan = p.framePrice / SpreadOf(std::min(1.0, p.framePrice), pixelsPerFrame, perSegment);
  plan.predictedParallelism = work / (startSpan + (plan.length - 1) * frameSpan);
  return plan;
}

}  // namespace

double SegmentsRelativeCost(int frameCount, int length, const SegmentPrices& prices) {
  frameCount = std::max(1, frameCount);
  const int segments = (frameCount + std::max(1, length) - 1) / std::max(1, length);
  return SegmentsWork(frameCount, segments, prices) / frameCount;
}

const char* PriceSourceName(PriceSource source) {
  switch (source) {
    case PriceSource::kScene:
      return "scene";
    case PriceSource::kFarm:
      return "farm";
    case PriceSource::kPrior:
      break;
  }
  return "prior";
}

SegmentPlan PlanSegments(int frameCount, int workers, uint64_t pixelsPerFrame, const SegmentPrices& prices) {
  frameCount = std::max(1, frameCount);
  workers = std::max(1, workers);
  const SegmentPlan one = Predict(1, frameCount, workers, pixelsPerFrame, prices);
  SegmentPlan chosen = one;
  for (int segments = 2; segments <= std::min(frameCount, workers); ++segments) {
    if (chosen.predictedParallelism >= workers) break;  // enough: more would cost CPU for nothing
    const SegmentPlan more = Predict(segments, frameCount, workers, pixelsPerFrame, prices);
    if (more.predictedRelativeCost > one.predictedRelativeCost * (1 + kExtraCostBudget)) break;
    if (more.length == chosen.length) continue;  // the same cut
    chosen = more;
  }
  return chosen;
}

nlohmann::json SegmentPlan::ToJson() const {
  return {{"segments", segments},
          {"length", length},
          {"predicted_relative_cost", predictedRelativeCost},
          {"predicted_parallelism", predictedParallelism},
          {"segment_start_price", prices.startPrice},
          {"frame_price", prices.framePrice},
          {"prices_from", PriceSourceName(prices.source)}};
}

SegmentPlan SegmentPlan::FromJson(const nlohmann::json& json) {
  SegmentPlan plan;
  if (!json.is_object()) return plan;
  plan.segments = json.value("segments", plan.segments);
  plan.length = json.value("length", plan.length);
  plan.predictedRelativeCost = json.value("predicted_relative_cost", plan.predictedRelativeCost);
  plan.predictedParallelism = json.value("predicted_parallelism", plan.predictedParallelism);
  plan.prices.startPrice = json.value("segment_start_price", plan.prices.startPrice);
  plan.prices.framePrice = json.value("frame_price", plan.prices.framePrice);
  const std::string from = json.value("prices_from", std::string());
  for (PriceSource source : {PriceSource::kScene, PriceSource::kFarm}) {
    if (from == PriceSourceName(source)) plan.prices.source = source;
  }
  return plan;
}

}  // namespace tcfarm
