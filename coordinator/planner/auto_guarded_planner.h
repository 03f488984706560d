// `auto` when the camera or a light moves: guarded search with a bin width chosen from
// the sequence (bin_width_survey.h). The planner first asks for the guard's coarse
// samples of the first frames (a survey: about 1.6 % of their pixels), chooses the width
// that survey predicts to trace least, then runs GuardedPlanner with it. The surveyed
// samples of frames inside bins are that planner's coarse pass, so no sample is traced
// twice there; those at bin ends are traced again with their frame (a few per mille of
// the survey's frames' pixels).
//
// Only the first frames are surveyed: the survey's memory grows with every frame it
// holds, and the planner's must stay bounded by its live bins.
#pragma once

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "coordinator/planner/bin_width_survey.h"
#include "coordinator/planner/guarded_planner.h"
#include "coordinator/planner/planner.h"

namespace tcfarm {

class AutoGuardedPlanner : public Planner {
 public:
  // options.binWidth is the widest bin considered (>= 2). Throws std::invalid_argument
  // naming a bad option.
  explicit AutoGuardedPlanner(const PlannerOptions& options);

  std::vector<TraceTask> TakeReadyTasks() override;
  bool OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* horizons = nullptr,
                size_t horizonCount = 0) override;
  std::vector<FinishedFrame> TakeFinishedFrames() override;
  bool Done() const override;
  uint64_t TracedPixels() const override;
  uint64_t CopiedPixels() const override;
  size_t LiveFrames() const override;
  void SetWorkers(int workers) override;

  // The width it runs with (2, brute force's, where the survey predicts no width saves
  // enough: GuardedWidthAfterSurvey); 0 while the survey runs.
  int ChosenBinWidth() const { return guarded_ ? runWidth_ : 0; }
  // The survey's choice: each width's predicted traced share of the surveyed frames
  // (empty while surveying), and the width that traces least.
  const BinWidthChoice& SurveyChoice() const { return choice_; }
  const std::vector<std::pair<int, double>>& Predictions() const { return choice_.predicted; }
  int SurveyedFrames() const { return surveyedFrames_; }
  // Frames the survey samples for a job of frameCount frames and the widest bin considered.
  static int SurveyFrames(int frameCount, int widestBin);

 private:
  // Survey task ids carry this bit; GuardedPlanner's ids count up from 1 and never reach it.
  static constexpr uint64_t kSurveyTask = uint64_t{1} << (kPlannerTaskIdBits - 1);

  void StartGuarded();

  PlannerOptions options_;
  CoarseGuard guard_;  // the tiles and samples GuardedPlanner will use
  CoarseSurvey survey_;  // its samples go to the guarded planner once it starts
  int surveyedFrames_ = 0;
  std::vector<PixelSet> chunks_;      // a frame's samples, split as tasks
  std::vector<size_t> chunkOffsets_;  // where each chunk's floats go in a frame's samples
  std::vector<bool> surveyed_;        // per survey task: its result is in
  size_t surveyLeft_ = 0;
  std::vector<TraceTask> readyTasks_;
  BinWidthChoice choice_;
  int runWidth_ = 0;
  std::unique_ptr<GuardedPlanner> guarded_;
};

}  // namespace tcfarm
