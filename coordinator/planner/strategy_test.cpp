#include "coordinator/planner/strategy.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <stdexcept>
#include <string>

namespace tcfarm {
namespace {

constexpr uint64_t kPixels = 640 * 480;

const StrategyCandidate* Find(const ResolvedStrategy& resolved, Strategy strategy) {
  for (const StrategyCandidate& candidate : resolved.candidates) {
    if (candidate.strategy == strategy) return &candidate;
  }
  return nullptr;
}

// Prices this scene measured, at which exact costs more than brute force: auto runs brute
// force, its one prediction is brute force's, and the reason gives exact's figure and its source.
TEST(AutoStrategy, ExactPredictedDearByTheScenesOwnPricesRunsBruteForce) {
  const SegmentPrices measured{3.0, 1.2, PriceSource::kScene};
  const ResolvedStrategy resolved = ResolveStrategy(Strategy::kAuto, 10, 24, false, 4, kPixels, measured);
  EXPECT_EQ(resolved.strategy, Strategy::kBrute);
  ASSERT_TRUE(resolved.predictedRelativeCost);
  EXPECT_DOUBLE_EQ(*resolved.predictedRelativeCost, 1.0);
  const StrategyCandidate* exact = Find(resolved, Strategy::kExact);
  ASSERT_NE(exact, nullptr);
  const double predicted = PlanSegments(24, 4, kPixels, measured).predictedRelativeCost;
  EXPECT_DOUBLE_EQ(*exact->predictedRelativeCost, predicted);
  EXPECT_EQ(exact->from, "scene");
  char figure[16];
  std::snprintf(figure, sizeof figure, "%.3f", predicted);
  EXPECT_NE(resolved.reason.find(figure), std::string::npos) << resolved.reason;
  EXPECT_NE(resolved.reason.find("measured on this scene"), std::string::npos) << resolved.reason;
  ASSERT_NE(Find(resolved, Strategy::kBrute), nullptr);
  EXPECT_DOUBLE_EQ(*Find(resolved, Strategy::kBrute)->predictedRelativeCost, 1.0);
}

// The chosen candidate's prediction is the job's one prediction, in the reason as well.
TEST(AutoStrategy, TheChosenCandidatesPredictionIsTheOneInTheReason) {
  const ResolvedStrategy resolved = ResolveStrategy(Strategy::kAuto, 10, 24, false, 1, kPixels);
  ASSERT_EQ(resolved.strategy, Strategy::kExact);
  ASSERT_TRUE(resolved.predictedRelativeCost && resolved.segments);
  EXPECT_DOUBLE_EQ(*resolved.predictedRelativeCost, resolved.segments->predictedRelativeCost);
  EXPECT_DOUBLE_EQ(*resolved.predictedRelativeCost, *Find(resolved, Strategy::kExact)->predictedRelativeCost);
  EXPECT_EQ(Find(resolved, Strategy::kExact)->from, "prior");
  char figure[16];
  std::snprintf(figure, sizeof figure, "%.3f", *resolved.predictedRelativeCost);
  EXPECT_NE(resolved.reason.find(figure), std::string::npos) << resolved.reason;
}

// A moving camera weighs guarded, whose prediction only its survey makes.
TEST(AutoStrategy, AMovingViewWeighsGuardedByItsSurvey) {
  const ResolvedStrategy resolved = ResolveStrategy(Strategy::kAuto, 10, 24, true, 4, kPixels);
  EXPECT_EQ(resolved.strategy, Strategy::kGuarded);
  EXPECT_FALSE(resolved.predictedRelativeCost);
  const StrategyCandidate* guarded = Find(resolved, Strategy::kGuarded);
  ASSERT_NE(guarded, nullptr);
  EXPECT_FALSE(guarded->predictedRelativeCost);
  EXPECT_EQ(guarded->from, "survey");
  BinWidthChoice cheap{4, {{2, 1.0}, {3, 0.6}, {4, 0.5}}};
  EXPECT_EQ(GuardedWidthAfterSurvey(cheap), 4);
  EXPECT_DOUBLE_EQ(*SurveyPrediction(cheap, 4), 0.5 * kGuardedCostPerTracedShare);
  // 0.75 of the pixels traced, priced: about what brute force costs, so brute force's bins.
  BinWidthChoice dear{3, {{2, 1.0}, {3, 0.75}, {4, 0.97}}};
  EXPECT_EQ(GuardedWidthAfterSurvey(dear), 2);
  EXPECT_DOUBLE_EQ(*SurveyPrediction(dear, 4), 1.0);  // never above brute force's
  EXPECT_FALSE(SurveyPrediction(dear, 9));
}

// A strategy asked by name carries the model's prediction where there is one.
TEST(AutoStrategy, NamedStrategiesCarryTheirModelsPrediction) {
  const SegmentPrices prices{3.0, 0.5};
  const ResolvedStrategy exact = ResolveStrategy(Strategy::kExact, 12, 24, true, 4, kPixels, prices);
  ASSERT_TRUE(exact.predictedRelativeCost);
  // Two segment starts, 22 later frames and the audit's one brute-force frame.
  EXPECT_DOUBLE_EQ(*exact.predictedRelativeCost, (2 * 3.0 + 22 * 0.5 + 1) / 24);
  EXPECT_TRUE(exact.candidates.empty());
  EXPECT_DOUBLE_EQ(*ResolveStrategy(Strategy::kBrute, 10, 24, true, 4, kPixels).predictedRelativeCost, 1.0);
  EXPECT_FALSE(ResolveStrategy(Strategy::kSearch, 10, 24, true, 4, kPixels).predictedRelativeCost);
  EXPECT_FALSE(ResolveStrategy(Strategy::kGuarded, 10, 24, true, 4, kPixels).predictedRelativeCost);
}

TEST(AutoStrategy, CandidatesRoundTripThroughJson) {
  const StrategyCandidate exact{Strategy::kExact, 0.4, "farm"};
  const StrategyCandidate back = StrategyCandidate::FromJson(exact.ToJson());
  EXPECT_EQ(back.strategy, Strategy::kExact);
  EXPECT_DOUBLE_EQ(*back.predictedRelativeCost, 0.4);
  EXPECT_EQ(back.from, "farm");
  const StrategyCandidate unknown = StrategyCandidate::FromJson(StrategyCandidate{Strategy::kGuarded, {}, "survey"}.ToJson());
  EXPECT_FALSE(unknown.predictedRelativeCost);
  EXPECT_THROW(StrategyCandidate::FromJson({{"strategy", "fast"}}), std::invalid_argument);
}

}  // namespace
}  // namespace tcfarm
