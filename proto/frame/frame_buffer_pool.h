// Frame-sized pixel buffers handed back once a frame is written, for the next finished
// frame to be copied into. A buffer of many MB taken fresh from the system costs a page
// fault for every 4 KiB on its first write, more than the copy into it: a coordinator that
// finishes a 1280x720 frame every few milliseconds spent a tenth of its CPU there.
// Thread-safe: frames are finished on the farm's loop and written on the writer's threads.
#pragma once

#include <cstddef>
#include <mutex>
#include <utility>
#include <vector>

namespace tcfarm {

class FrameBufferPool {
 public:
  // Keeps at most `capacity` buffers; those given beyond it are freed.
  explicit FrameBufferPool(size_t capacity) : capacity_(capacity) {}

  // A buffer that holds `floats` floats without growing (its old values left in it), or an
  // empty one when none is kept: the caller assigns every value either way.
  std::vector<float> Take(size_t floats) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto buffer = buffers_.begin(); buffer != buffers_.end(); ++buffer) {
      if (buffer->capacity() < floats) continue;
      std::vector<float> taken = std::move(*buffer);
      buffers_.erase(buffer);
      return taken;
    }
    return {};
  }

  // Keeps the buffer for a later Take while there is room.
  void Give(std::vector<float> buffer) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (buffers_.size() < capacity_ && buffer.capacity() > 0) buffers_.push_back(std::move(buffer));
  }

  size_t Held() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return buffers_.size();
  }

 private:
  mutable std::mutex mutex_;
  size_t capacity_;
  std::vector<std::vector<float>> buffers_;
};

}  // namespace tcfarm
