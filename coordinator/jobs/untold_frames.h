// Frames recorded as written and not yet told in a frames_written event, per job: the job
// store gathers them so that one event tells several (JobStore::kFramesPerEvent, or those
// older than kFrameEventIntervalMs). Memory only; the job store's lock guards it.
#pragma once

#include <cstdint>
#include <map>
#include <vector>

namespace tcfarm::jobs {

class UntoldFrames {
 public:
  // The job's untold frames, in the order they were recorded; empty for none.
  const std::vector<int>& Of(uint64_t job) const;
  // Adds a frame; the job's first untold frame starts its wait at nowMs.
  void Add(uint64_t job, int frame, int64_t nowMs);
  // Jobs whose first untold frame waited intervalMs or longer at nowMs, ascending.
  std::vector<uint64_t> DueAt(int64_t nowMs, int64_t intervalMs) const;
  // The job has no frames untold: they were told, or the job is gone.
  void Clear(uint64_t job) { untold_.erase(job); }
  // Frames un-recorded: no event is to tell them.
  void Forget(uint64_t job, const std::vector<int>& frames);

 private:
  struct Owed {
    std::vector<int> frames;
    int64_t sinceMs = 0;  // when the first of them was recorded
  };
  std::map<uint64_t, Owed> untold_;
};

}  // namespace tcfarm::jobs
