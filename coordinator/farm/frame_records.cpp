#include "coordinator/farm/frame_records.h"

namespace tcfarm {

void FrameRecords::Written(int frame) {
  const auto traced = writing_.find(frame);
  if (traced == writing_.end()) return;  // never ours to record (none such today)
  unrecorded_.push_back({frame, traced->second});
  writing_.erase(traced);
}

bool FrameRecords::Flush(JobStore& store) {
  try {
    Record(store);
  } catch (const JobStoreFullError& e) {
    blocked_ = e.what();
    return false;
  }
  blocked_.clear();
  return true;
}

// The plan first: a frame recorded under no plan could be resumed under another one.
void FrameRecords::Record(JobStore& store) {
  if (planToSave_) {
    store.SetPlan(jobId_, *planToSave_);
    planToSave_.reset();
  }
  if (!framesToForget_.empty()) {
    store.ForgetFrames(jobId_, framesToForget_);
    framesToForget_.clear();
  }
  // A frame is counted only after it is in the folder and its record is committed.
  while (!unrecorded_.empty()) {
    const FrameRecord& record = unrecorded_.front();
    if (store.RecordFrame(jobId_, record.frame, record.traced, pixelsPerFrame_ - record.traced)) ++recorded_;
    unrecorded_.pop_front();
  }
}

std::vector<int> FrameRecords::WritingFrames() const {
  std::vector<int> frames;
  for (const auto& [frame, traced] : writing_) frames.push_back(frame);
  return frames;
}

}  // namespace tcfarm
