#include "frame/frame_writer.h"

namespace tcfarm {

FrameWriter::FrameWriter(std::filesystem::path directory, bool writeExr, bool writePng,
                         size_t maxQueuedFrames)
    : directory_(std::move(directory)),
      writeExr_(writeExr),
      writePng_(writePng),
      maxQueued_(std::max<size_t>(1, maxQueuedFrames)),
      thread_([this] { Run(); }) {}

FrameWriter::~FrameWriter() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void FrameWriter::Write(int frame, Image image) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return queue_.size() < maxQueued_; });
  queue_.emplace_back(frame, std::move(image));
  changed_.notify_all();
}

void FrameWriter::Finish() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return queue_.empty() && !writing_; });
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void FrameWriter::Run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    changed_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping with nothing left
    auto [frame, image] = std::move(queue_.front());
    queue_.pop_front();
    writing_ = true;
    changed_.notify_all();
    lock.unlock();
    try {
      std::filesystem::path stem = directory_ / FrameFileStem(frame);
      if (writeExr_) WriteExr(stem.string() + ".exr", image);
      if (writePng_) WritePng(stem.string() + ".png", image);
    } catch (...) {
      std::lock_guard<std::mutex> errorLock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
    lock.lock();
    writing_ = false;
    changed_.notify_all();
  }
}

}  // namespace tcfarm
