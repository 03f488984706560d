// A running job's records in the job store, kept in step with its files: a frame handed
// to the writer is recorded only once its files are in place, and the job's plan is saved
// before any frame is recorded (a frame recorded under no plan could be resumed under
// another). Records the store refuses (disk full) stay owed for the next Flush. Owned by
// the job's run; not thread-safe.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "coordinator/jobs/job_store.h"

namespace tcfarm {

class FrameRecords {
 public:
  // framesToForget: recorded frames whose files are gone; recorded: frames recorded
  // before this run (kept ones).
  FrameRecords(uint64_t jobId, uint64_t pixelsPerFrame, std::vector<int> framesToForget, int recorded)
      : jobId_(jobId), pixelsPerFrame_(pixelsPerFrame), framesToForget_(std::move(framesToForget)),
        recorded_(recorded) {}

  // The frame (its absolute number) went to the writer with this many traced pixels.
  void Writing(int frame, uint64_t traced) { writing_[frame] = traced; }
  // Its files are in place: it is owed a record. Ignored for a frame not Writing.
  void Written(int frame);
  // The writer failed and is done: the frames still writing will never be in place.
  void DropWriting() { writing_.clear(); }
  // The plan to save before the next frame's record.
  void SavePlan(nlohmann::json plan) { planToSave_ = std::move(plan); }

  // Records what is owed: the plan, frames to forget, written frames. False, keeping them
  // owed, while the store refuses writes (blocked() says why); other store errors throw.
  bool Flush(JobStore& store);

  bool Owed() const { return planToSave_.has_value() || !framesToForget_.empty() || !unrecorded_.empty(); }
  bool AnyWriting() const { return !writing_.empty(); }
  // The frames with the writer, ascending.
  std::vector<int> WritingFrames() const;
  const std::string& blocked() const { return blocked_; }
  int recorded() const { return recorded_; }  // kept ones included

 private:
  struct FrameRecord {
    int frame = 0;
    uint64_t traced = 0;
  };
  void Record(JobStore& store);

  uint64_t jobId_;
  uint64_t pixelsPerFrame_;
  std::map<int, uint64_t> writing_;  // frames with the writer, with their traced pixels
  std::deque<FrameRecord> unrecorded_;
  std::optional<nlohmann::json> planToSave_;
  std::vector<int> framesToForget_;
  int recorded_;
  std::string blocked_;
};

}  // namespace tcfarm
