#include "coordinator/farm/job_cost.h"

#include <gtest/gtest.h>

#include "coordinator/planner/planner.h"

namespace tcfarm {
namespace {

wire::Result Result(double seconds, uint64_t pixels, bool horizons = false) {
  wire::Result result;
  result.traceSeconds = seconds;
  result.traceCpuSeconds = 2 * seconds;
  result.rgb.assign(pixels * 3, 0.f);
  result.primaryRays = pixels;
  if (horizons) result.horizons.assign(pixels, 1);
  return result;
}

RunningStats Coherence(double share) {
  RunningStats stats;
  stats.Add(share);
  return stats;
}

// A search job of 4 frames of 10 pixels: frames traced plainly in full price brute force.
TEST(JobCost, BruteForceIsPricedByFramesTracedInFull) {
  JobCost cost(10, 4);
  cost.OnPlannerResult(0, Result(1.0, 10));
  cost.OnFrameFinished(0, 10);
  cost.OnPlannerResult(1, Result(0.5, 5));
  cost.OnFrameFinished(1, 5);
  nlohmann::json stats;
  cost.AddTo(stats, Coherence(0.75));
  EXPECT_DOUBLE_EQ(stats["trace_seconds"].get<double>(), 1.5);
  EXPECT_DOUBLE_EQ(stats["trace_cpu_seconds"].get<double>(), 3.0);
  EXPECT_EQ(stats["tasks"], 2);
  EXPECT_EQ(stats["rays"]["primary"], 15);
  const nlohmann::json& figures = stats["cost"];
  EXPECT_EQ(figures["brute_estimate_from"], "frames traced in full");
  EXPECT_DOUBLE_EQ(figures["brute_trace_seconds_estimate"].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(figures["measured_relative_cost"].get<double>(), 3.0 / 8.0);  // CPU basis
  EXPECT_EQ(figures["measured_relative_cost_basis"], "trace cpu seconds");
  EXPECT_DOUBLE_EQ(figures["d"].get<double>(), 0.25);
  // The job's one prediction is its plan's (stats.strategy), not the cost's.
  EXPECT_FALSE(figures.contains("predicted_relative_cost"));
}

// Horizons cost more than the frame they trace, so such a frame prices nothing; reference
// frames (brute force itself) do, and verification is not the job's own cost.
TEST(JobCost, ReferenceFramesPriceBruteForceWhenNoFrameWasTracedPlainly) {
  JobCost cost(10, 4);
  cost.OnPlannerResult(0, Result(3.0, 10, /*horizons=*/true));
  cost.OnFrameFinished(0, 10);
  cost.OnVerificationResult(Result(1.0, 10), /*reference=*/true);
  nlohmann::json stats;
  cost.AddTo(stats, RunningStats{});
  EXPECT_DOUBLE_EQ(stats["trace_seconds"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(stats["verify_trace_seconds"].get<double>(), 1.0);
  EXPECT_EQ(stats["cost"]["brute_estimate_from"], "reference frames");
  EXPECT_DOUBLE_EQ(stats["cost"]["brute_trace_seconds_estimate"].get<double>(), 4.0);
  EXPECT_FALSE(stats["cost"].contains("d"));  // no coherence yet
}

// The span follows the tasks' chains: a chain's steps one after the other, each as long
// as its longest task; chains side by side after the prelude.
TEST(JobCost, SpanIsTheLongestChainAfterThePrelude) {
  JobCost cost(10, 4);
  cost.OnPlannerResult(0, Result(0.5, 2), TraceTask::kPreludeChain, 0);
  cost.OnPlannerResult(0, Result(1.0, 5), 0, 0);
  cost.OnPlannerResult(0, Result(2.0, 5), 0, 0);  // same step: runs beside the other
  cost.OnPlannerResult(1, Result(1.0, 5), 0, 1);
  cost.OnPlannerResult(2, Result(2.5, 5), 1, 0);
  nlohmann::json stats;
  cost.AddTo(stats, RunningStats{});
  const nlohmann::json& parallelism = stats["parallelism"];
  EXPECT_EQ(parallelism["basis"], "trace cpu seconds");
  EXPECT_DOUBLE_EQ(parallelism["work_seconds"].get<double>(), 2 * 7.0);
  EXPECT_DOUBLE_EQ(parallelism["span_seconds"].get<double>(), 2 * (0.5 + 3.0));  // chain 0: 2 + 1
  EXPECT_DOUBLE_EQ(parallelism["parallelism"].get<double>(), 2.0);
}

// An exact job prices its segment starts and its other frames in brute-force frames.
TEST(JobCost, AnExactJobMeasuresItsSegmentPrices) {
  JobCost cost(10, 4);
  EXPECT_FALSE(cost.MeasuredSegmentPrices());
  cost.OnPlannerResult(0, Result(3.0, 10, /*horizons=*/true));
  cost.OnFrameFinished(0, 10);
  cost.OnPlannerResult(1, Result(0.4, 2, /*horizons=*/true));
  cost.OnFrameFinished(1, 2);
  cost.OnFrameFinished(2, 0);  // all copied
  EXPECT_FALSE(cost.MeasuredSegmentPrices());  // no brute-force price yet
  cost.OnVerificationResult(Result(1.0, 10), /*reference=*/true);
  const std::optional<SegmentPrices> prices = cost.MeasuredSegmentPrices();
  ASSERT_TRUE(prices);
  EXPECT_DOUBLE_EQ(prices->startPrice, 3.0);
  EXPECT_DOUBLE_EQ(prices->framePrice, 0.2);  // (0.4 + 0) / 2 frames
  nlohmann::json stats;
  cost.AddTo(stats, RunningStats{});
  EXPECT_DOUBLE_EQ(stats["cost"]["segment_start_price"].get<double>(), 3.0);
}

// On a scene where every pixel changes every frame, exact traces its later frames in full
// as well: they are priced as later frames all the same, by where its segments start.
TEST(JobCost, AnExactJobPricesLaterFramesTracedInFullAsLaterFrames) {
  JobCost cost(10, 4, /*segmentLength=*/4);
  cost.OnPlannerResult(0, Result(3.0, 10, /*horizons=*/true));
  cost.OnFrameFinished(0, 10);
  cost.OnPlannerResult(1, Result(1.2, 10, /*horizons=*/true));
  cost.OnFrameFinished(1, 10);
  cost.OnPlannerResult(2, Result(1.0, 10));  // none left to find at the segment's end
  cost.OnFrameFinished(2, 10);
  cost.OnVerificationResult(Result(1.0, 10), /*reference=*/true);
  const std::optional<SegmentPrices> prices = cost.MeasuredSegmentPrices();
  ASSERT_TRUE(prices);
  EXPECT_DOUBLE_EQ(prices->startPrice, 3.0);
  EXPECT_DOUBLE_EQ(prices->framePrice, 1.1);
}

// The measured relative cost counts every part of the job's tracing on workers: its
// traces, spot checks, the audit's reference frames and repairs; the parts sum to it.
TEST(JobCost, TheMeasuredCostCountsEveryPartAndThePartsSumToIt) {
  JobCost cost(10, 4);
  cost.OnPlannerResult(0, Result(3.0, 10, /*horizons=*/true));
  cost.OnFrameFinished(0, 10);
  cost.OnPlannerResult(1, Result(0.4, 2, /*horizons=*/true));
  cost.OnFrameFinished(1, 2);
  cost.OnVerificationResult(Result(0.25, 1), /*reference=*/false);  // a spot check
  cost.OnVerificationResult(Result(1.0, 10), /*reference=*/true);   // the audit's frame
  cost.OnRepairResult(Result(0.5, 10));
  nlohmann::json stats;
  cost.AddTo(stats, RunningStats{});
  const nlohmann::json& figures = stats["cost"];
  const nlohmann::json& parts = figures["cpu_seconds_by_part"];
  EXPECT_DOUBLE_EQ(parts["traces"].get<double>(), 2 * 3.4);
  EXPECT_DOUBLE_EQ(parts["spot_checks"].get<double>(), 2 * 0.25);
  EXPECT_DOUBLE_EQ(parts["audit"].get<double>(), 2 * 1.0);
  EXPECT_DOUBLE_EQ(parts["repairs"].get<double>(), 2 * 0.5);
  double sum = 0;
  for (const auto& [part, seconds] : parts.items()) sum += seconds.get<double>();
  const double brute = figures["brute_trace_cpu_seconds_estimate"].get<double>();
  EXPECT_DOUBLE_EQ(brute, 2 * 4.0);  // the reference frame, for 4 frames
  EXPECT_DOUBLE_EQ(figures["measured_relative_cost"].get<double>(), sum / brute);
  EXPECT_DOUBLE_EQ(figures["measured_trace_relative_cost"].get<double>(), 2 * 3.4 / brute);
  EXPECT_DOUBLE_EQ(figures["seconds_by_part"]["audit"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(figures["measured_relative_cost_wall"].get<double>(), (3.4 + 0.25 + 1.0 + 0.5) / 4.0);
  // The trace figures the record had before stay what they were.
  EXPECT_DOUBLE_EQ(stats["trace_cpu_seconds"].get<double>(), 2 * 3.4);
  EXPECT_DOUBLE_EQ(stats["verify_trace_cpu_seconds"].get<double>(), 2 * 1.25);
}

}  // namespace
}  // namespace tcfarm
