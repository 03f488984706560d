#include "coordinator/planner/auto_guarded_planner.h"

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>

#include "coordinator/planner/strategy.h"

namespace tcfarm {
namespace {

CoarseGuard ValidatedGuard(const PlannerOptions& options) {
  planner_internal::ValidateCommonOptions(options);
  planner_internal::RequireOption(options.binWidth >= 2, "binWidth", options.binWidth,
                                  ">= 2 (the widest bin considered)");
  planner_internal::RequireOption(options.coarseTile >= 1, "coarseTile", options.coarseTile, ">= 1");
  return CoarseGuard(static_cast<uint32_t>(options.width), static_cast<uint32_t>(options.height),
                     static_cast<uint32_t>(options.coarseTile), options.tolerance);
}

}  // namespace

// Three bins of the widest width: enough to see how changes fall in time, few enough that
// the survey's samples stay a small, bounded share of the job's memory.
int AutoGuardedPlanner::SurveyFrames(int frameCount, int widestBin) {
  return std::min(frameCount, 3 * (widestBin - 1) + 1);
}

AutoGuardedPlanner::AutoGuardedPlanner(const PlannerOptions& options)
    : options_(options), guard_(ValidatedGuard(options)) {
  survey_.width = static_cast<uint32_t>(options.width);
  survey_.height = static_cast<uint32_t>(options.height);
  survey_.tile = static_cast<uint32_t>(options.coarseTile);
  survey_.tolerance = options.tolerance;
  const int frames = SurveyFrames(options.frameCount, options.binWidth);
  surveyedFrames_ = frames;
  // Each frame's samples take memory from its first result on (OnResult).
  survey_.samples.assign(static_cast<size_t>(frames), {});
  chunks_ = guard_.Samples().Split(options.maxTaskPixels);
  size_t offset = 0;
  for (const PixelSet& chunk : chunks_) {
    chunkOffsets_.push_back(offset);
    offset += 3 * size_t{chunk.size()};
  }
  // Task id: the bit, then frame * chunks + chunk.
  for (int frame = 0; frame < frames; ++frame) {
    for (size_t chunk = 0; chunk < chunks_.size(); ++chunk) {
      const uint64_t index = static_cast<uint64_t>(frame) * chunks_.size() + chunk;
      readyTasks_.push_back(TraceTask{kSurveyTask | index, frame, chunks_[chunk], 0, TraceTask::kPreludeChain, 0});
    }
  }
  surveyed_.assign(size_t(frames) * chunks_.size(), false);
  surveyLeft_ = surveyed_.size();
}

void AutoGuardedPlanner::SetWorkers(int workers) {
  options_.workers = workers;  // for the guarded planner it makes after the survey
  if (guarded_) guarded_->SetWorkers(workers);
}

std::vector<TraceTask> AutoGuardedPlanner::TakeReadyTasks() {
  if (guarded_) return guarded_->TakeReadyTasks();
  return TakeAll(readyTasks_);
}

bool AutoGuardedPlanner::OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* horizons,
                                  size_t horizonCount) {
  if ((taskId & kSurveyTask) == 0) {
    if (!guarded_) {
      throw std::invalid_argument("result for unknown task id " + std::to_string(taskId) +
                                  "; only survey tasks are issued yet");
    }
    return guarded_->OnResult(taskId, rgb, floatCount, horizons, horizonCount);
  }
  const uint64_t index = taskId & ~kSurveyTask;
  if (index >= surveyed_.size()) {
    throw std::invalid_argument("result for unknown survey task id " + std::to_string(taskId) + "; " +
                                std::to_string(surveyed_.size()) + " survey tasks were issued");
  }
  if (surveyed_[index]) return false;  // a re-delivery
  const size_t frame = index / chunks_.size(), chunk = index % chunks_.size();
  planner_internal::ValidateRgb(taskId, static_cast<int>(frame), chunks_[chunk].size(), rgb, floatCount);
  std::vector<float>& samples = survey_.samples[frame];
  if (samples.empty()) samples.resize(3 * size_t{guard_.Samples().size()});
  std::copy(rgb, rgb + floatCount, samples.begin() + static_cast<std::ptrdiff_t>(chunkOffsets_[chunk]));
  surveyed_[index] = true;
  if (--surveyLeft_ == 0) StartGuarded();
  return true;
}

void AutoGuardedPlanner::StartGuarded() {
  choice_ = ChooseGuardedBinWidth(survey_, options_.binWidth);
  runWidth_ = GuardedWidthAfterSurvey(choice_);
  PlannerOptions chosen = options_;
  chosen.binWidth = runWidth_;
  // The survey is the guarded planner's coarse pass over those frames; the planner
  // takes the samples over.
  guarded_ = std::make_unique<GuardedPlanner>(chosen, std::move(survey_.samples));
  survey_.samples.clear();
}

std::vector<FinishedFrame> AutoGuardedPlanner::TakeFinishedFrames() {
  return guarded_ ? guarded_->TakeFinishedFrames() : std::vector<FinishedFrame>{};
}

bool AutoGuardedPlanner::Done() const { return guarded_ && guarded_->Done(); }

uint64_t AutoGuardedPlanner::TracedPixels() const { return guarded_ ? guarded_->TracedPixels() : 0; }

uint64_t AutoGuardedPlanner::CopiedPixels() const { return guarded_ ? guarded_->CopiedPixels() : 0; }

size_t AutoGuardedPlanner::LiveFrames() const { return guarded_ ? guarded_->LiveFrames() : 0; }

}  // namespace tcfarm
