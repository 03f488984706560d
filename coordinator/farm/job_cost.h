// What a job's tracing cost the farm, and what it would have cost brute force: the
// figures behind `stats.cost` (the measured relative cost, beside which the job's plan
// carries its prediction: `stats.strategy.predicted_relative_cost`; docs/architecture.md,
// section 3.6), the trace seconds, task and ray counts.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "proto/frame/sequence_analysis.h"
#include "coordinator/planner/segment_plan.h"
#include "proto/wire/wire.h"

namespace tcfarm {

// A task's tracing time: elapsed on the worker, and CPU time of its tracing threads. CPU
// time is what the job costs on a shared machine, where elapsed time also counts waiting
// for the cores.
struct TaskTime {
  double wall = 0;
  double cpu = 0;
  TaskTime& operator+=(const TaskTime& other) {
    wall += other.wall;
    cpu += other.cpu;
    return *this;
  }
  TaskTime operator-(const TaskTime& other) const { return {wall - other.wall, cpu - other.cpu}; }
};

class JobCost {
 public:
  // segmentLength: an exact job's (its segments start at multiples of it); 0 for others.
  JobCost(uint64_t pixelsPerFrame, int frameCount, int segmentLength = 0)
      : pixelsPerFrame_(pixelsPerFrame), frames_(frameCount), segmentLength_(segmentLength) {}

  // A planner task's result; `frame` relative to the job; chain and step as the task
  // had them (TraceTask): the job's span follows its dependencies.
  void OnPlannerResult(int frame, const wire::Result& result, int chain = 0, int step = 0);
  // A verification task's result: a spot check, or a reference frame traced brute force
  // (the audit of what the job promises).
  void OnVerificationResult(const wire::Result& result, bool reference);
  // A frame traced again in full because a distrusted worker's values reached it.
  void OnRepairResult(const wire::Result& result) { repairTime_ += TimeOfResult(result); }
  // The planner finished `frame` with tracedCount of its pixels traced. In an exact job a
  // frame is its segment's start or a later frame by where it lies (a later frame whose
  // every pixel changed is traced in full too); in others one traced plainly in full shows
  // what brute force pays for a frame.
  void OnFrameFinished(int frame, uint64_t tracedCount);

  // What an exact job measured of auto's segment prices (planner/segment_plan.h), in
  // brute-force frames; nullopt before it has a brute-force price and both kinds of frame.
  std::optional<SegmentPrices> MeasuredSegmentPrices() const;

  // Adds trace_seconds, verify_trace_seconds, their CPU seconds (when every worker
  // reported them), tasks, rays, cost: measured against brute force, with every part of
  // the job's tracing (its traces, spot checks, audit and repairs) and the measured
  // frame-to-frame change rate d, and parallelism: the job's work, its span (the longest
  // chain of dependent tasks, in seconds of tracing) and work / span, the most workers it
  // can keep busy.
  void AddTo(nlohmann::json& stats, const RunningStats& frameToFrame) const;

  static TaskTime TimeOfResult(const wire::Result& result) {
    return {result.traceSeconds, result.traceCpuSeconds.value_or(0)};
  }

 private:
  void OnAnyResult(const wire::Result& result, const TaskTime& time);
  // The finished frame's tracing time into one kind of frame's tally.
  void Count(int& frames, TaskTime& time, int frame);
  nlohmann::json Figures(const RunningStats& frameToFrame) const;
  // The tracing the job cost, by part: traces, spot_checks, audit (reference frames), repairs.
  std::map<std::string, TaskTime> Parts() const;
  // Brute force's price of the whole job, from reference frames or frames traced in full.
  TaskTime BruteEstimate(std::string* from = nullptr) const;
  nlohmann::json Parallelism() const;
  double Basis(const TaskTime& time) const { return cpuReported_ ? time.cpu : time.wall; }

  uint64_t pixelsPerFrame_;
  int frames_;
  int segmentLength_;
  TaskTime traceTime_;   // summed over tasks: the tracing time the job cost the farm
  TaskTime verifyTime_;  // of it, spent on verification (spot checks and reference frames)
  TaskTime repairTime_;  // frames traced again after a worker was distrusted (not in traceTime_)
  bool cpuReported_ = true;  // every task's worker reported its CPU time
  std::map<int, TaskTime> frameTraceTime_;  // per unfinished frame, planner tasks only
  std::set<int> framesWithHorizons_;        // unfinished frames some task traced with horizons
  TaskTime fullFrameTime_;  // frames traced plainly in full: brute force's cost per frame
  int fullFrames_ = 0;
  TaskTime referenceTime_;  // reference frames: brute force itself
  uint64_t referencePixels_ = 0;
  uint64_t rays_[4] = {};  // primary, shadow, reflection, refraction
  uint64_t results_ = 0;
  // Frames traced in full with horizons (exact's segment starts), and the others.
  TaskTime startFrameTime_, laterFrameTime_;
  int startFrames_ = 0, laterFrames_ = 0;
  // Per chain, per step: the longest task (CPU seconds where reported, else elapsed).
  std::map<int, std::map<int, TaskTime>> longestTask_;
};

}  // namespace tcfarm
