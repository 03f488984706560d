#include "coordinator/planner/exact_planner.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

namespace tcfarm {
namespace {

constexpr const char* kPlannerName = "exact planner";

void Check(bool condition, const std::string& what) { planner_internal::Check(condition, kPlannerName, what); }

void ValidateOptions(const PlannerOptions& options) {
  planner_internal::ValidateCommonOptions(options);
  planner_internal::RequireOption(options.binWidth >= 1, "binWidth", options.binWidth,
                                  ">= 1 (the segment length; 1 traces every pixel)");
}

std::string PixelName(uint32_t pixel, int frame) {
  return "pixel " + std::to_string(pixel) + " of frame " + std::to_string(frame);
}

}  // namespace

ExactPlanner::ExactPlanner(const PlannerOptions& options) : options_(options) {
  ValidateOptions(options);
  pixelCount_ = static_cast<uint32_t>(options.width) * static_cast<uint32_t>(options.height);
  for (long long first = 0; first < options.frameCount; first += options.binWidth) {
    const int last = static_cast<int>(std::min<long long>(first + options.binWidth, options.frameCount) - 1);
    // A resumed segment starts at its first frame not in the store.
    int start = static_cast<int>(first);
    while (start <= last && planner_internal::AllKept(options, start, start)) ++start;
    if (start <= last) segmentFrames_.emplace_back(start, last);
  }
  StartSegments();
}

std::vector<TraceTask> ExactPlanner::TakeReadyTasks() { return TakeAll(readyTasks_); }

std::vector<FinishedFrame> ExactPlanner::TakeFinishedFrames() { return TakeAll(finished_); }

bool ExactPlanner::Done() const {
  return nextSegment_ == segmentFrames_.size() && segments_.empty() && finished_.empty();
}

bool ExactPlanner::OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* horizons,
                            size_t horizonCount) {
  auto found = pendingTasks_.find(taskId);
  if (found == pendingTasks_.end()) {
    if (taskId != 0 && taskId < nextTaskId_) return false;  // completed before: a re-delivery
    throw std::invalid_argument("result for unknown task id " + std::to_string(taskId) + "; ids issued are 1 .. " +
                                std::to_string(nextTaskId_ - 1));
  }
  {
    // Everything is checked before anything changes, so a rejected result changes nothing.
    const PendingTask& task = found->second;
    planner_internal::ValidateRgb(taskId, task.frame, task.pixels.size(), rgb, floatCount);
    if (task.window > 0) {
      planner_internal::ValidateHorizons(taskId, task.frame, task.window, task.pixels.size(), horizons,
                                         horizonCount);
    }
  }
  const PendingTask task = std::move(found->second);
  pendingTasks_.erase(found);

  auto segment = segments_.find(task.segment);
  Check(segment != segments_.end() && segment->second.frame == task.frame,
        "task " + std::to_string(taskId) + " at frame " + std::to_string(task.frame) + " belongs to no segment at it");
  WriteResult(segment->second, task, rgb, horizons);
  if (--segment->second.tasksLeft == 0) CompleteFrame(task.segment);
  return true;
}

void ExactPlanner::StartSegments() {
  while (segments_.size() < static_cast<size_t>(options_.maxLiveBins) && nextSegment_ < segmentFrames_.size()) {
    StartSegment(nextSegment_++);
  }
}

void ExactPlanner::StartSegment(size_t index) {
  Segment& segment = segments_[index];
  segment.first = segmentFrames_[index].first;
  segment.last = segmentFrames_[index].second;
  segment.frame = segment.first;
  // Nothing is known at a segment's first frame: it is traced in full. Its pixels take
  // memory from the first result on (WriteResult): a job waiting for workers holds none.
  segment.tracing = PixelSet::Full(pixelCount_);
  IssueTasks(index, segment);
}

// Every trace of the segment's current frame is in: finish frames (copying where
// nothing is traced) until one has pixels to trace, or the segment ends.
void ExactPlanner::CompleteFrame(size_t index) {
  Segment& segment = segments_.at(index);
  for (;;) {
    FinishFrame(segment);
    if (++segment.frame > segment.last) {
      segments_.erase(index);
      StartSegments();
      return;
    }
    segment.tracing = PixelsToTraceAt(segment);
    if (!segment.tracing.empty()) {
      IssueTasks(index, segment);
      return;
    }
  }
}

PixelSet ExactPlanner::PixelsToTraceAt(const Segment& segment) const {
  PixelSetBuilder pixels;
  const int32_t* nextTrace = segment.nextTrace.data();
  // Most pixels are due later: a block's earliest due frame (a loop the compiler
  // vectorizes) rules out the whole block at once.
  constexpr uint32_t kBlock = 64;
  for (uint32_t begin = 0; begin < pixelCount_; begin += kBlock) {
    const uint32_t end = std::min(pixelCount_, begin + kBlock);
    int32_t earliest = INT32_MAX;
    for (uint32_t pixel = begin; pixel < end; ++pixel) earliest = std::min(earliest, nextTrace[pixel]);
    if (earliest > segment.frame) continue;
    for (uint32_t pixel = begin; pixel < end; ++pixel) {
      if (nextTrace[pixel] > segment.frame) continue;
      if (nextTrace[pixel] < segment.frame) {
        Check(false, PixelName(pixel, segment.frame) + " was due at frame " + std::to_string(nextTrace[pixel]) +
                         " and has no value");
      }
      pixels.Add(pixel);
    }
  }
  return pixels.Build();
}

void ExactPlanner::IssueTasks(size_t index, Segment& segment) {
  // Any later frame of the segment may be the horizon; none beyond it is of use.
  const int window = segment.last - segment.frame;
  std::vector<PixelSet> chunks = planner_internal::SplitForWorkers(segment.tracing, options_);
  Check(!chunks.empty(), "empty trace at frame " + std::to_string(segment.frame));
  segment.tasksLeft = chunks.size();
  for (PixelSet& chunk : chunks) {
    const uint64_t taskId = nextTaskId_++;
    pendingTasks_[taskId] = PendingTask{index, segment.frame, window, chunk};
    readyTasks_.push_back(TraceTask{taskId, segment.frame, std::move(chunk), window, static_cast<int>(index),
                                    segment.frame - segment.first});
  }
}

void ExactPlanner::WriteResult(Segment& segment, const PendingTask& task, const float* rgb, const int32_t* horizons) {
  if (segment.nextTrace.empty()) {
    segment.rgb.assign(size_t{pixelCount_} * 3, 0.0f);
    segment.nextTrace.assign(pixelCount_, segment.first);
  }
  float* values = segment.rgb.data();
  int32_t* nextTrace = segment.nextTrace.data();
  size_t i = 0;  // the result's index of the span's first pixel
  for (const Span& span : task.pixels.spans()) {
    for (uint32_t pixel = span.begin; pixel != span.end; ++pixel) {
      if (nextTrace[pixel] != task.frame) {
        Check(false, PixelName(pixel, task.frame) + " is traced but was due at frame " +
                         std::to_string(nextTrace[pixel]));
      }
    }
    // A span's values lie side by side in the result as in the frame.
    std::memcpy(values + size_t{span.begin} * 3, rgb + i * 3, size_t{span.size()} * 3 * sizeof(float));
    if (task.window > 0) {
      std::memcpy(nextTrace + span.begin, horizons + i, size_t{span.size()} * sizeof(int32_t));
    } else {
      // At the segment's last frame there is nothing left to be valid for.
      std::fill(nextTrace + span.begin, nextTrace + span.end, task.frame + 1);
    }
    i += span.size();
  }
}

void ExactPlanner::FinishFrame(Segment& segment) {
  FinishedFrame frame;
  frame.frame = segment.frame;
  // The segment goes on from these values, so the frame is a copy of them.
  if (options_.frameBuffers) frame.rgb = options_.frameBuffers->Take(segment.rgb.size());
  frame.rgb.assign(segment.rgb.begin(), segment.rgb.end());
  frame.traced.assign(pixelCount_, 0);
  for (const Span& span : segment.tracing.spans()) {
    for (uint32_t pixel = span.begin; pixel != span.end; ++pixel) {
      // Each traced pixel has its value: its next trace lies after this frame.
      if (segment.nextTrace[pixel] <= segment.frame) {
        Check(false, PixelName(pixel, segment.frame) + " finishes without its traced value");
      }
    }
    std::fill(frame.traced.begin() + span.begin, frame.traced.begin() + span.end, uint8_t{1});
  }
  frame.tracedCount = segment.tracing.size();
  tracedPixels_ += frame.tracedCount;
  copiedPixels_ += pixelCount_ - frame.tracedCount;
  segment.tracing = PixelSet();
  finished_.push_back(std::move(frame));
}

}  // namespace tcfarm
