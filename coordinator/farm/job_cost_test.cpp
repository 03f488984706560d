#include "farm/job_cost.h"

#include <gtest/gtest.h>

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
  cost.AddTo(stats, Strategy::kSearch, 4, Coherence(0.75));
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
  EXPECT_DOUBLE_EQ(figures["predicted_relative_cost"].get<double>(), Equation3RelativeCost(4, 4, 0.25));
}

// Horizons cost more than the frame they trace, so such a frame prices nothing; reference
// frames (brute force itself) do, and verification is not the job's own cost.
TEST(JobCost, ReferenceFramesPriceBruteForceWhenNoFrameWasTracedPlainly) {
  JobCost cost(10, 4);
  cost.OnPlannerResult(0, Result(3.0, 10, /*horizons=*/true));
  cost.OnFrameFinished(0, 10);
  cost.OnVerificationResult(Result(1.0, 10), /*reference=*/true);
  nlohmann::json stats;
  cost.AddTo(stats, Strategy::kExact, 4, RunningStats{});
  EXPECT_DOUBLE_EQ(stats["trace_seconds"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(stats["verify_trace_seconds"].get<double>(), 1.0);
  EXPECT_EQ(stats["cost"]["brute_estimate_from"], "reference frames");
  EXPECT_DOUBLE_EQ(stats["cost"]["brute_trace_seconds_estimate"].get<double>(), 4.0);
  EXPECT_FALSE(stats["cost"].contains("predicted_relative_cost"));  // no coherence yet
}

}  // namespace
}  // namespace tcfarm
