// The strategies a job may ask for (docs/architecture.md, section 3), their names, and
// the one rule that turns `auto` into one of the others. Parsed once, at submit; from
// then on the coordinator passes the type, never the name.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/planner/bin_width_survey.h"
#include "coordinator/planner/segment_plan.h"

namespace tcfarm {

// kAuto is a request only: ResolveStrategy turns it into one of the others before any
// planner sees it.
enum class Strategy { kSearch, kBrute, kGuarded, kExact, kAuto };

struct StrategyNameEntry {
  Strategy strategy;
  std::string_view name;
};
// The one list of names: the HTTP API validates against it and serves it (GET
// /api/v1/strategies, which the dashboard's menus and `tcfarm strategies` show), the job
// store writes it, and api_server_test checks that proto/openapi.yaml's enums list the same.
// In the API's order; the first is a submission's default.
inline constexpr StrategyNameEntry kStrategyNames[] = {{Strategy::kSearch, "search"},
                                                       {Strategy::kBrute, "brute"},
                                                       {Strategy::kGuarded, "guarded"},
                                                       {Strategy::kExact, "exact"},
                                                       {Strategy::kAuto, "auto"}};
inline constexpr Strategy kDefaultStrategy = kStrategyNames[0].strategy;

// exact and brute promise 0 wrong pixels: any disagreement their checks find is a bug or
// a worker returning wrong values.
constexpr bool PromisesExact(Strategy strategy) { return strategy == Strategy::kExact || strategy == Strategy::kBrute; }

// nullopt for a name not in kStrategyNames (names are case-sensitive).
std::optional<Strategy> StrategyFromString(std::string_view name);
std::string_view StrategyName(Strategy strategy);

// Auto's widest guarded bin: equation 3 keeps falling with n for any d < 1, so the width
// is chosen by a coarse survey of the sequence (planner/bin_width_survey.h) up to this.
// Past it the paper's measured cost has long flattened (Figure 9) while a copied pixel's
// span, and with it the error the guard misses, keeps growing.
constexpr int kAutoWidestBin = 16;

// A strategy auto weighed, and its predicted CPU cost against brute force's (= 1).
struct StrategyCandidate {
  Strategy strategy;
  std::optional<double> predictedRelativeCost;  // none: guarded's, until its survey ran
  // What the prediction rests on: "definition" (brute force), "scene", "farm" or "prior"
  // (exact's segment prices: PriceSource), "survey" (guarded).
  std::string from;
  nlohmann::json ToJson() const;
  static StrategyCandidate FromJson(const nlohmann::json& json);  // throws for an unknown name
};

// The strategy and bin width (segment length for exact) a job runs with; never kAuto.
struct ResolvedStrategy {
  Strategy strategy;
  int binWidth;  // with surveyBinWidth: the widest considered
  std::string reason;
  bool surveyBinWidth = false;  // guarded's width is chosen by a coarse survey (auto)
  std::optional<SegmentPlan> segments;  // auto's exact: the cost model's choice
  // The job's one prediction of its CPU cost against brute force's: the chosen
  // candidate's for auto, the model's for a strategy asked by name where there is one
  // (brute: 1, exact: the segment model); none for search, nor for guarded until its survey.
  std::optional<double> predictedRelativeCost = std::nullopt;
  std::vector<StrategyCandidate> candidates = {};  // what auto weighed; empty for a named strategy
};

// `auto` runs brute force unless another candidate is predicted to cost less than this
// share of it: the prediction's error is about that size, and brute force pays no search.
constexpr double kAutoBruteFromCost = 0.95;

// `auto` predicts what each candidate would cost against brute force (1) and runs the
// cheapest, brute force unless another is predicted under kAutoBruteFromCost. Brute force
// for one frame (nothing to reuse). When nothing but shapes move (every pixel then has a
// horizon to find) the candidate is exact: its segments cut as the cost model says for
// `workers` workers, frames of pixelsPerFrame and `prices` (planner/segment_plan.h). When
// the camera or a light moves it is guarded, whose cost only its coarse survey predicts:
// its width is surveyed up to kAutoWidestBin, and GuardedWidthAfterSurvey falls back to
// brute force's bins of 2. `brute` is the search with bins of 2. Any other strategy runs as
// requested with `binWidth`.
ResolvedStrategy ResolveStrategy(Strategy requested, int binWidth, int frameCount, bool cameraOrLightsChange,
                                 int workers, uint64_t pixelsPerFrame, const SegmentPrices& prices = {});

// What a guarded job's CPU costs against brute force's, per share of the pixels it traces:
// the pixels it traces are the ones that change, dearer than the average pixel, and its
// coarse pass comes on top. Measured (relative CPU cost over traced share, the widths auto
// picks): 1.18 on the paper's one sphere, 1.20 on its twelve, 1.38 on its terrain flyover
// (tests/bench/report/paper_table.md), 1.64 on a textured turntable at 1920x1080.
constexpr double kGuardedCostPerTracedShare = 1.3;

// Auto's guarded once its survey ran: the width the survey chose, or 2 (every frame a bin
// end: brute force) when even that width is predicted to cost kAutoBruteFromCost of brute
// force's CPU or more, the survey's coarse pass being all it spent.
int GuardedWidthAfterSurvey(const BinWidthChoice& choice);
// The predicted relative CPU cost of guarded at `width`: the survey's traced share priced
// at kGuardedCostPerTracedShare, at most 1 (every pixel traced costs what brute force
// does); none if not surveyed.
std::optional<double> SurveyPrediction(const BinWidthChoice& choice, int width);

}  // namespace tcfarm
