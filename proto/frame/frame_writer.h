// Writes finished frames on a background thread, so that encoding and disk never stall
// tracing. The queue is bounded: a producer faster than the disk waits instead of
// holding an unbounded number of frames in memory.
//
// A frame is whole or absent: each file goes to a temporary name and is renamed into
// place, and when one of a frame's files cannot be written the others are removed. The
// caller learns which frames are in place (TakeWritten) and which write failed first
// (FirstFailure), so its records can say exactly what the folder holds.
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <string>
#include <utility>
#include <vector>

#include "proto/frame/frame_buffer_pool.h"
#include "proto/frame/frame_io.h"

namespace tcfarm {

struct FrameWriterOptions {
  bool writeExr = true;
  bool writePng = true;
  std::string exrCompression = "zip:1";
  // Encoding a frame (EXR zip + PNG) costs several times tracing it at small sizes, so
  // frames are encoded in parallel.
  unsigned threads = 2;
  // Frames queued before Write blocks: enough to ride out slow writes.
  size_t maxQueuedFrames = 4;
  ViewTransform view = {};  // how the PNG preview shows the linear values
  // Where a written frame's pixel buffer goes, for the next finished frame to be copied
  // into; none: it is freed.
  std::shared_ptr<FrameBufferPool> recycle = nullptr;
};

class FrameWriter {
 public:
  // Throws FrameIoError for a lossy EXR compression.
  FrameWriter(std::filesystem::path directory, FrameWriterOptions options = {});
  ~FrameWriter();  // finishes pending writes; errors are only reported by Finish()
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  // Queues frame `frame` as DIRECTORY/frame_NNNN.{exr,png}.
  void Write(int frame, Image image);
  // Queues a mask (width * height values, white where non-zero) as DIRECTORY/NAME, an
  // 8-bit greyscale PNG. Masks are a byte a pixel and come with frames, so they do not
  // count towards maxQueuedFrames.
  void WriteMask(std::string name, int width, int height, std::vector<uint8_t> mask);
  // Waits for every queued frame; rethrows the first write error.
  void Finish();
  // Whether Write would return at once (fewer than maxQueuedFrames frames queued).
  bool HasRoom() const;
  // Whether everything queued is written (Finish would return at once).
  bool Idle() const;
  // Frames whose files are all in place since the last call, in the order they finished.
  std::vector<int> TakeWritten();
  // The first write that failed: its frame (nullopt for a mask), its file and why.
  struct Failure {
    std::optional<int> frame;
    std::string file;
    std::string why;
  };
  std::optional<Failure> FirstFailure() const;

 private:
  void Run();

  // A frame, or a mask when maskName is set.
  struct Item {
    int frame = 0;
    Image image;
    std::string maskName;
    std::vector<uint8_t> mask;
  };
  void WriteFiles(const Item& item) const;
  void WriteFrameFiles(const Item& item) const;
  // Records a failed item; the caller holds mutex_.
  void NoteFailure(const Item& item, const std::exception& error);

  std::filesystem::path directory_;
  FrameWriterOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Item> queue_;
  size_t queuedFrames_ = 0;  // frames in queue_, masks not counted
  unsigned writing_ = 0;
  bool stopping_ = false;
  std::exception_ptr error_;
  std::optional<Failure> firstFailure_;
  std::vector<int> written_;  // frames in place, not yet taken
  std::vector<std::thread> threads_;
};

}  // namespace tcfarm
