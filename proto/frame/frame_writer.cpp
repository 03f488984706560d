#include "proto/frame/frame_writer.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <system_error>

namespace tcfarm {

FrameWriter::FrameWriter(std::filesystem::path directory, FrameWriterOptions options)
    : directory_(std::move(directory)), options_(std::move(options)) {
  if (options_.writeExr && !IsLosslessExrCompression(options_.exrCompression)) {
    throw FrameIoError("EXR compression '" + options_.exrCompression +
                       "' is not lossless; expected none, rle, zips, zip or piz");
  }
  options_.maxQueuedFrames = std::max<size_t>(1, options_.maxQueuedFrames);
  // The writer's own threads encode frames in parallel; OpenEXR's pool would only hand
  // each frame's blocks from thread to thread (a tenth of the coordinator's CPU went to
  // those switches while a job rendered). -1: OpenEXR reads and writes on the calling
  // thread, for the whole process (OIIO holds one setting).
  OIIO::attribute("exr_threads", -1);
  for (unsigned i = 0; i < std::max(1u, options_.threads); ++i) {
    threads_.emplace_back([this] { Run(); });
  }
}

FrameWriter::~FrameWriter() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  for (auto& thread : threads_) thread.join();
}

void FrameWriter::Write(int frame, Image image) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return queuedFrames_ < options_.maxQueuedFrames; });
  Item item;
  item.frame = frame;
  item.image = std::move(image);
  queue_.push_back(std::move(item));
  ++queuedFrames_;
  changed_.notify_all();
}

void FrameWriter::WriteMask(std::string name, int width, int height, std::vector<uint8_t> mask) {
  Item item;
  item.image.width = width;
  item.image.height = height;
  item.maskName = std::move(name);
  item.mask = std::move(mask);
  std::lock_guard<std::mutex> lock(mutex_);
  queue_.push_back(std::move(item));
  changed_.notify_all();
}

bool FrameWriter::HasRoom() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queuedFrames_ < options_.maxQueuedFrames;
}

bool FrameWriter::Idle() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.empty() && writing_ == 0;
}

void FrameWriter::Finish() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return queue_.empty() && writing_ == 0; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void FrameWriter::WriteFiles(const Item& item) const {
  if (!item.maskName.empty()) {
    WriteMaskPng(directory_ / item.maskName, item.image.width, item.image.height, item.mask);
    return;
  }
  WriteFrameFiles(item);
}

// Both files or neither: a frame whose PNG found no room loses its EXR too, so that a
// frame in the folder is always a whole frame.
void FrameWriter::WriteFrameFiles(const Item& item) const {
  const std::string stem = (directory_ / FrameFileStem(item.frame)).string();
  std::vector<std::filesystem::path> placed;
  try {
    if (options_.writeExr) {
      WriteExr(stem + ".exr", item.image, options_.exrCompression);
      placed.push_back(stem + ".exr");
    }
    if (options_.writePng) {
      WritePng(stem + ".png", item.image, options_.view);
      placed.push_back(stem + ".png");
    }
  } catch (...) {
    std::error_code ignored;
    for (const std::filesystem::path& path : placed) std::filesystem::remove(path, ignored);
    throw;
  }
}

std::vector<int> FrameWriter::TakeWritten() {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::exchange(written_, {});
}

std::optional<FrameWriter::Failure> FrameWriter::FirstFailure() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return firstFailure_;
}

// The free space goes with the reason: an encoder's message for a full disk is often
// only "write failed".
void FrameWriter::NoteFailure(const Item& item, const std::exception& error) {
  if (firstFailure_) return;
  Failure failure;
  if (item.maskName.empty()) failure.frame = item.frame;
  failure.file = item.maskName.empty() ? FrameFileStem(item.frame) : item.maskName;
  failure.why = error.what();
  std::error_code spaceError;
  const std::filesystem::space_info space = std::filesystem::space(directory_, spaceError);
  if (!spaceError) {
    failure.why += "; " + std::to_string(space.available) + " bytes free on the disk of " + directory_.string();
    if (space.available < (uint64_t{1} << 20)) failure.why += " (disk full)";
  }
  firstFailure_ = std::move(failure);
}

void FrameWriter::Run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping with nothing left
    Item item = std::move(queue_.front());
    queue_.pop_front();
    if (item.maskName.empty()) --queuedFrames_;
    ++writing_;
    changed_.notify_all();
    lock.unlock();
    std::exception_ptr error;
    try {
      WriteFiles(item);
    } catch (...) {
      error = std::current_exception();
    }
    if (options_.recycle && item.maskName.empty()) options_.recycle->Give(std::move(item.image.rgb));
    lock.lock();
    if (error) {
      try {
        std::rethrow_exception(error);
      } catch (const std::exception& e) {
        NoteFailure(item, e);
      } catch (...) {
      }
    } else if (item.maskName.empty()) {
      written_.push_back(item.frame);
    }
    if (error && !error_) error_ = error;
    --writing_;
    changed_.notify_all();
  }
}

}  // namespace tcfarm
