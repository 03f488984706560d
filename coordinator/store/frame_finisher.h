// Finishes a job's frames off its critical path. While a job renders, each frame is
// stored as a lossless EXR written as fast as it can be (no compression) and nothing
// else: encoding (the EXR's compression, the 8-bit PNG preview) costs several times
// tracing the frame, and on a shared machine it would take the cores the workers trace
// on. Once the job is done, and only while no job renders, the finisher re-encodes each
// frame with the store's compression and writes its preview. Until then the API makes a
// preview on request (EncodePreview), and the EXR is always the lossless master.
//
//   STORE/<job>/.finished   the job's frames are finished (written last)
//
// One background thread; a coordinator that stops leaves the rest for the next one
// (Farm queues completed jobs without the marker at start).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "proto/frame/frame_writer.h"
#include "proto/frame/view_transform.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/frame_store.h"

namespace tcfarm {

// How a job's frames are written while it renders, given how the store keeps them: the
// EXR uncompressed and no preview (when the store keeps EXRs; without an EXR master the
// PNG is the only copy, written at once).
FrameWriterOptions WhileRendering(const FrameWriterOptions& stored);

// How a job's previews show its frames: the view and exposure it was submitted with, kept
// in its options ("view", "exposure") only when they are not the default, so that jobs
// stored before views existed read as standard.
ViewTransform JobPreviewView(const JobSpec& spec);
void SetJobPreviewView(JobSpec& spec, const ViewTransform& view);

// `frame`'s PNG preview made from its EXR through `view`, and kept in its place for the
// next asker when the disk takes it (atomically); nullopt when the EXR is not there.
// Throws FrameIoError when the EXR cannot be read.
std::optional<std::string> EncodePreview(const FrameStore& store, uint64_t job, int frame,
                                         const ViewTransform& view = {});

class FrameFinisher {
 public:
  // stored: the store's format (compression, previews); nothing to do when it keeps no EXR.
  // idleGrace: how long the farm must have been idle before a frame is finished. A frame's
  // encoding cannot be cut short, so without a grace the next job of a batch, submitted as
  // the last one completes, would start beside it (at 1280x720, 0.1 s of a core).
  FrameFinisher(FrameStore store, FrameWriterOptions stored,
                std::chrono::milliseconds idleGrace = kDefaultIdleGrace);
  static constexpr std::chrono::milliseconds kDefaultIdleGrace{1500};
  ~FrameFinisher();
  FrameFinisher(const FrameFinisher&) = delete;
  FrameFinisher& operator=(const FrameFinisher&) = delete;

  // A job whose frames [first, last] are all written; their previews go through `view`.
  // Thread-safe.
  void Add(uint64_t job, int first, int last, const ViewTransform& view = {});
  // While the farm renders a job, and for idleGrace after, finishing waits (between frames).
  void SetFarmBusy(bool busy);
  // The job is being deleted: it leaves the queue, and finishing it stops after the frame
  // at hand, without its marker. Returns once the finisher no longer touches the job's
  // folder (at most a frame's encoding later). Thread-safe.
  void Drop(uint64_t job);
  // Nothing queued or being finished.
  bool Idle() const;
  static bool IsFinished(const FrameStore& store, uint64_t job);
  uint64_t FramesFinished() const { return framesFinished_; }

 private:
  struct Job {
    uint64_t id;
    int first, last;
    ViewTransform view;
  };
  void Run();
  void Finish(const Job& job);
  // Waits until the farm has been idle for idleGrace_; false when the finisher stops or
  // the current job is dropped meanwhile. The caller holds `lock`.
  bool WaitForIdleFarm(std::unique_lock<std::mutex>& lock);
  void FinishFrame(const Job& job, int frame) const;

  FrameStore store_;
  FrameWriterOptions stored_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Job> queue_;
  std::condition_variable finishedOne_;  // a job left Finish (Drop waits for it)
  std::optional<uint64_t> current_;      // the job being finished
  bool dropCurrent_ = false;             // Drop asked for current_ to stop
  bool busy_ = false;
  std::chrono::steady_clock::time_point idleSince_ = std::chrono::steady_clock::now();
  const std::chrono::milliseconds idleGrace_;
  bool stopping_ = false;
  std::atomic<uint64_t> framesFinished_{0};
  std::thread thread_;
};

}  // namespace tcfarm
