// Writes finished frames on a background thread, so that encoding and disk never stall
// tracing. The queue is bounded: a producer faster than the disk waits instead of
// holding an unbounded number of frames in memory.
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <filesystem>
#include <mutex>
#include <thread>
#include <utility>

#include "frame/frame_io.h"

namespace tcfarm {

class FrameWriter {
 public:
  // Frames queued before Write blocks: enough to ride out a slow write of one frame.
  static constexpr size_t kDefaultQueueFrames = 4;

  FrameWriter(std::filesystem::path directory, bool writeExr, bool writePng,
              size_t maxQueuedFrames = kDefaultQueueFrames);
  ~FrameWriter();  // finishes pending writes; errors are only reported by Finish()
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  // Queues frame `frame` as DIRECTORY/frame_NNNN.{exr,png}.
  void Write(int frame, Image image);
  // Waits for every queued frame; rethrows the first write error.
  void Finish();

 private:
  void Run();

  std::filesystem::path directory_;
  bool writeExr_, writePng_;
  size_t maxQueued_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<std::pair<int, Image>> queue_;
  bool writing_ = false;
  bool stopping_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace tcfarm
