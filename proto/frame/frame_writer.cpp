#include "frame/frame_writer.h"

#include <algorithm>

namespace tcfarm {

FrameWriter::FrameWriter(std::filesystem::path directory, FrameWriterOptions options)
    : directory_(std::move(directory)), options_(std::move(options)) {
  if (options_.writeExr && !IsLosslessExrCompression(options_.exrCompression)) {
    throw FrameIoError("EXR compression '" + options_.exrCompression +
                       "' is not lossless; expected none, rle, zips, zip or piz");
  }
  options_.maxQueuedFrames = std::max<size_t>(1, options_.maxQueuedFrames);
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
  std::filesystem::path stem = directory_ / FrameFileStem(item.frame);
  if (options_.writeExr) WriteExr(stem.string() + ".exr", item.image, options_.exrCompression);
  if (options_.writePng) WritePng(stem.string() + ".png", item.image);
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
    lock.lock();
    if (error && !error_) error_ = error;
    --writing_;
    changed_.notify_all();
  }
}

}  // namespace tcfarm
