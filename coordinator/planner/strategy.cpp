#include "coordinator/planner/strategy.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

namespace tcfarm {

std::optional<Strategy> StrategyFromString(std::string_view name) {
  for (const StrategyNameEntry& entry : kStrategyNames) {
    if (entry.name == name) return entry.strategy;
  }
  return std::nullopt;
}

std::string_view StrategyName(Strategy strategy) {
  for (const StrategyNameEntry& entry : kStrategyNames) {
    if (entry.strategy == strategy) return entry.name;
  }
  return "unknown";
}

nlohmann::json StrategyCandidate::ToJson() const {
  nlohmann::json json = {{"strategy", std::string(StrategyName(strategy))},
                         {"predicted_relative_cost", nullptr},
                         {"from", from}};
  if (predictedRelativeCost) json["predicted_relative_cost"] = *predictedRelativeCost;
  return json;
}

StrategyCandidate StrategyCandidate::FromJson(const nlohmann::json& json) {
  const std::string name = json.value("strategy", std::string());
  const std::optional<Strategy> strategy = StrategyFromString(name);
  if (!strategy) throw std::invalid_argument("a stored candidate names no strategy this coordinator knows: " + name);
  StrategyCandidate candidate{*strategy, std::nullopt, json.value("from", std::string())};
  const auto predicted = json.find("predicted_relative_cost");
  if (predicted != json.end() && predicted->is_number()) candidate.predictedRelativeCost = predicted->get<double>();
  return candidate;
}

namespace {

// Brute force: the search with bins of 2, every pixel of every frame. It is the unit.
ResolvedStrategy Brute(std::string why) {
  ResolvedStrategy brute{Strategy::kBrute, 2, std::move(why), false, {}};
  brute.predictedRelativeCost = 1.0;
  return brute;
}

StrategyCandidate BruteCandidate() { return {Strategy::kBrute, 1.0, "definition"}; }

std::string PricesInWords(PriceSource source) {
  switch (source) {
    case PriceSource::kScene:
      return "segment prices measured on this scene";
    case PriceSource::kFarm:
      return "segment prices of the farm's last exact job of this kind of scene";
    case PriceSource::kPrior:
      break;
  }
  return "the prior segment prices";
}

// A strategy asked for by name: the model's prediction where there is one.
ResolvedStrategy AsRequested(Strategy requested, int binWidth, int frameCount, const SegmentPrices& prices) {
  ResolvedStrategy resolved{requested, binWidth, "as requested", false, {}};
  if (requested == Strategy::kExact) resolved.predictedRelativeCost = SegmentsRelativeCost(frameCount, binWidth, prices);
  return resolved;
}

// Nothing but shapes move: exact, unless brute force is predicted cheaper.
ResolvedStrategy AutoForStillViews(int frameCount, int workers, uint64_t pixelsPerFrame, const SegmentPrices& prices) {
  const SegmentPlan plan = PlanSegments(frameCount, workers, pixelsPerFrame, prices);
  const std::vector<StrategyCandidate> candidates = {
      BruteCandidate(), {Strategy::kExact, plan.predictedRelativeCost, PriceSourceName(prices.source)}};
  char why[320];
  if (plan.predictedRelativeCost >= kAutoBruteFromCost) {
    std::snprintf(why, sizeof why,
                  "camera and lights are static, but exact is predicted to cost %.3f of brute force's CPU (%s; "
                  "at least %.2f): every pixel traced",
                  plan.predictedRelativeCost, PricesInWords(prices.source).c_str(), kAutoBruteFromCost);
    ResolvedStrategy brute = Brute(why);
    brute.candidates = candidates;
    return brute;
  }
  std::snprintf(why, sizeof why,
                "camera and lights are static: exact, %d segment%s of %d frames for %d worker%s (predicted "
                "relative CPU cost %.3f from %s, parallelism %.1f; frames spread over the workers)",
                plan.segments, plan.segments == 1 ? "" : "s", plan.length, std::max(1, workers),
                workers == 1 ? "" : "s", plan.predictedRelativeCost, PricesInWords(prices.source).c_str(),
                plan.predictedParallelism);
  ResolvedStrategy exact{Strategy::kExact, plan.length, why, false, plan};
  exact.predictedRelativeCost = plan.predictedRelativeCost;
  exact.candidates = candidates;
  return exact;
}

}  // namespace

ResolvedStrategy ResolveStrategy(Strategy requested, int binWidth, int frameCount, bool cameraOrLightsChange,
                                 int workers, uint64_t pixelsPerFrame, const SegmentPrices& prices) {
  if (requested == Strategy::kBrute) return Brute("every pixel of every frame");
  if (requested != Strategy::kAuto) return AsRequested(requested, binWidth, frameCount, prices);
  if (frameCount == 1) return Brute("one frame: nothing to reuse, every pixel traced");
  if (!cameraOrLightsChange) return AutoForStillViews(frameCount, workers, pixelsPerFrame, prices);
  ResolvedStrategy guarded{Strategy::kGuarded, std::clamp(frameCount, 2, kAutoWidestBin),
                           "the camera or a light moves: guarded search, its bin width chosen by a coarse survey",
                           /*surveyBinWidth=*/true, {}};
  guarded.candidates = {BruteCandidate(), {Strategy::kGuarded, std::nullopt, "survey"}};
  return guarded;
}

std::optional<double> SurveyPrediction(const BinWidthChoice& choice, int width) {
  for (const auto& [surveyed, share] : choice.predicted) {
    if (surveyed == width) return std::min(1.0, share * kGuardedCostPerTracedShare);
  }
  return std::nullopt;
}

int GuardedWidthAfterSurvey(const BinWidthChoice& choice) {
  const std::optional<double> best = SurveyPrediction(choice, choice.binWidth);
  return best && *best >= kAutoBruteFromCost ? 2 : choice.binWidth;
}

}  // namespace tcfarm
