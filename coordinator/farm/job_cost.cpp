#include "coordinator/farm/job_cost.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "coordinator/planner/planner.h"

namespace tcfarm {
void JobCost::OnPlannerResult(int frame, const wire::Result& result, int chain, int step) {
  const TaskTime time = TimeOfResult(result);
  frameTraceTime_[frame] += time;
  TaskTime& longest = longestTask_[chain][step];
  longest.wall = std::max(longest.wall, time.wall);
  longest.cpu = std::max(longest.cpu, time.cpu);
  if (!result.horizons.empty()) framesWithHorizons_.insert(frame);
  OnAnyResult(result, time);
}

void JobCost::OnVerificationResult(const wire::Result& result, bool reference) {
  const TaskTime time = TimeOfResult(result);
  verifyTime_ += time;
  if (reference) {
    referenceTime_ += time;
    referencePixels_ += result.rgb.size() / 3;
  }
  OnAnyResult(result, time);
}

void JobCost::OnAnyResult(const wire::Result& result, const TaskTime& time) {
  traceTime_ += time;
  cpuReported_ = cpuReported_ && result.traceCpuSeconds.has_value();
  rays_[0] += result.primaryRays;
  rays_[1] += result.shadowRays;
  rays_[2] += result.reflectionRays;
  rays_[3] += result.refractionRays;
  ++results_;
}

void JobCost::OnFrameFinished(int frame, uint64_t tracedCount) {
  const bool full = tracedCount == pixelsPerFrame_, horizons = framesWithHorizons_.count(frame) > 0;
  if (segmentLength_ > 0) {
    Count(frame % segmentLength_ == 0 ? startFrames_ : laterFrames_,
          frame % segmentLength_ == 0 ? startFrameTime_ : laterFrameTime_, frame);
  } else if (full && !horizons) {
    Count(fullFrames_, fullFrameTime_, frame);
  } else if (full) {
    Count(startFrames_, startFrameTime_, frame);
  } else {
    Count(laterFrames_, laterFrameTime_, frame);  // copies only: nothing, and counted so
  }
  frameTraceTime_.erase(frame);
  framesWithHorizons_.erase(frame);
}

void JobCost::Count(int& frames, TaskTime& time, int frame) {
  ++frames;
  time += frameTraceTime_[frame];
}

void JobCost::AddTo(nlohmann::json& stats, const RunningStats& frameToFrame) const {
  stats["trace_seconds"] = traceTime_.wall - verifyTime_.wall;
  stats["verify_trace_seconds"] = verifyTime_.wall;
  if (cpuReported_ && results_ > 0) {
    stats["trace_cpu_seconds"] = traceTime_.cpu - verifyTime_.cpu;
    stats["verify_trace_cpu_seconds"] = verifyTime_.cpu;
  }
  stats["tasks"] = results_;
  stats["rays"] = {{"primary", rays_[0]}, {"shadow", rays_[1]}, {"reflection", rays_[2]},
                   {"refraction", rays_[3]}};
  stats["cost"] = Figures(frameToFrame);
  if (results_ > 0) stats["parallelism"] = Parallelism();
}

TaskTime JobCost::BruteEstimate(std::string* from) const {
  if (referencePixels_ > 0) {
    const double scale = double(pixelsPerFrame_) * frames_ / double(referencePixels_);
    if (from) *from = "reference frames";
    return {referenceTime_.wall * scale, referenceTime_.cpu * scale};
  }
  if (fullFrames_ > 0) {
    if (from) *from = "frames traced in full";
    return {fullFrameTime_.wall / fullFrames_ * frames_, fullFrameTime_.cpu / fullFrames_ * frames_};
  }
  return {};
}

std::optional<SegmentPrices> JobCost::MeasuredSegmentPrices() const {
  const double bruteFrame = Basis(BruteEstimate()) / frames_;
  if (bruteFrame <= 0 || startFrames_ == 0 || laterFrames_ == 0) return std::nullopt;
  return SegmentPrices{Basis(startFrameTime_) / startFrames_ / bruteFrame,
                       Basis(laterFrameTime_) / laterFrames_ / bruteFrame};
}

// Chains run side by side after the prelude; a chain's steps one after the other, each
// as long as its longest task.
nlohmann::json JobCost::Parallelism() const {
  double prelude = 0, longestChain = 0;
  for (const auto& [chain, steps] : longestTask_) {
    double span = 0;
    for (const auto& [step, longest] : steps) span += Basis(longest);
    if (chain == TraceTask::kPreludeChain) {
      prelude = span;
    } else {
      longestChain = std::max(longestChain, span);
    }
  }
  const double work = Basis(traceTime_ - verifyTime_), span = prelude + longestChain;
  return {{"work_seconds", work},
          {"span_seconds", span},
          {"parallelism", span > 0 ? work / span : 1.0},
          {"basis", cpuReported_ ? "trace cpu seconds" : "trace seconds"}};
}

std::map<std::string, TaskTime> JobCost::Parts() const {
  return {{"traces", traceTime_ - verifyTime_},
          {"spot_checks", verifyTime_ - referenceTime_},
          {"audit", referenceTime_},
          {"repairs", repairTime_}};
}

// Measured relative cost: everything the job traced over what brute force would have,
// estimated from its reference frames when it has any (brute force itself), else from the
// frames it traced plainly in full (bin ends), which cost what brute force pays per frame.
// CPU time where every worker reported it: it does not count waiting for shared cores.
nlohmann::json JobCost::Figures(const RunningStats& frameToFrame) const {
  nlohmann::json cost;
  if (frameToFrame.count > 0) cost["d"] = 1 - frameToFrame.Mean();
  std::string from;
  const TaskTime brute = BruteEstimate(&from);
  if (!from.empty()) cost["brute_estimate_from"] = from;
  if (const std::optional<SegmentPrices> prices = MeasuredSegmentPrices()) {
    cost["segment_start_price"] = prices->startPrice;
    cost["frame_price"] = prices->framePrice;
  }
  TaskTime job;
  nlohmann::json wallParts, cpuParts;
  for (const auto& [part, time] : Parts()) {
    job += time;
    wallParts[part] = time.wall;
    cpuParts[part] = time.cpu;
  }
  const TaskTime traces = traceTime_ - verifyTime_;
  cost["seconds_by_part"] = wallParts;
  if (cpuReported_ && results_ > 0) cost["cpu_seconds_by_part"] = cpuParts;
  if (brute.wall > 0) {
    cost["brute_trace_seconds_estimate"] = brute.wall;
    cost["measured_relative_cost_wall"] = job.wall / brute.wall;
    cost["measured_relative_cost"] = job.wall / brute.wall;
    cost["measured_trace_relative_cost"] = traces.wall / brute.wall;
    cost["measured_relative_cost_basis"] = "trace seconds";
  }
  if (cpuReported_ && brute.cpu > 0) {
    cost["brute_trace_cpu_seconds_estimate"] = brute.cpu;
    cost["measured_relative_cost"] = job.cpu / brute.cpu;
    cost["measured_trace_relative_cost"] = traces.cpu / brute.cpu;
    cost["measured_relative_cost_basis"] = "trace cpu seconds";
  }
  return cost;
}

}  // namespace tcfarm
