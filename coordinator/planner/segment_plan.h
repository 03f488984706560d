// How many segments `auto` cuts an exact job into: a cost model, not the farm's size.
//
// A segment starts with a full trace that also finds every pixel's horizon over the
// segment: it costs a few brute-force frames (startPrice). Each later frame traces only
// the pixels due there (framePrice, in brute-force frames). More segments buy
// parallelism (segments run at once) and cost CPU; a frame's pixels, spread over all the
// workers (PlannerOptions::workers), buy parallelism for nothing. So the model takes the
// fewest segments whose predicted parallelism (work / span) covers the workers, and never
// more than cost kExtraCostBudget above one segment's CPU: on a growing farm the job's
// CPU cost stays flat, and parallelism comes from within frames.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace tcfarm {

// Where a job's segment prices come from: an exact job's measurement of the same scene,
// the farm's last exact job of the same kind of scene (PriceBook), or these priors.
enum class PriceSource { kScene, kFarm, kPrior };
// "scene", "farm" or "prior": as the job record names it.
const char* PriceSourceName(PriceSource source);

// In brute-force frames. Measured on the paper's scenes (exact jobs report theirs,
// `stats.cost.segment_start_price` and `frame_price`); the farm feeds what it measured to
// later jobs (PriceBook), these are the priors before any.
struct SegmentPrices {
  double startPrice = 3.0;
  double framePrice = 0.3;
  PriceSource source = PriceSource::kPrior;
};

// The most extra CPU, against one segment, that more segments may cost.
constexpr double kExtraCostBudget = 0.05;

struct SegmentPlan {
  int segments = 1;
  int length = 1;  // frames a segment (the last may be shorter)
  double predictedRelativeCost = 1;  // against brute force, CPU
  double predictedParallelism = 1;   // work / span
  SegmentPrices prices;
  nlohmann::json ToJson() const;
  // As ToJson wrote it; missing fields keep their defaults.
  static SegmentPlan FromJson(const nlohmann::json& json);
};

// frameCount >= 1; workers: live now (at least 1 is assumed); pixelsPerFrame: the frame's.
SegmentPlan PlanSegments(int frameCount, int workers, uint64_t pixelsPerFrame, const SegmentPrices& prices = {});
// The model's CPU cost, against brute force, of frameCount frames cut in segments of
// `length` frames (the last may be shorter): an exact job asked for by name.
double SegmentsRelativeCost(int frameCount, int length, const SegmentPrices& prices = {});

}  // namespace tcfarm
