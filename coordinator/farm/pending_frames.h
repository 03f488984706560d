// Finished frames that wait for their turn: a job's coherence and change masks read its
// frames in order, and planners release them out of order (the paper's search finishes
// bins side by side). Held in memory up to a budget, spilled beyond it to raw float
// files, so a job's memory does not grow with how far ahead its frames finish: 60 frames
// of 16384x16384 would otherwise wait as 190 GB.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>

#include "proto/frame/frame_io.h"

namespace tcfarm {

class PendingFrames {
 public:
  // spillDirectory is created on the first spill and removed by the destructor.
  PendingFrames(std::filesystem::path spillDirectory, size_t memoryBudgetBytes);
  ~PendingFrames();
  PendingFrames(const PendingFrames&) = delete;
  PendingFrames& operator=(const PendingFrames&) = delete;

  // Throws FrameIoError when a spill cannot be written (the frame is not kept).
  void Put(int frame, Image image);
  // The frame, bit for bit as put, and forgets it; nullopt when it is not there. Throws
  // FrameIoError when a spilled frame cannot be read back.
  std::optional<Image> Take(int frame);

  size_t HeldBytes() const { return heldBytes_; }   // in memory
  size_t SpilledFrames() const { return spilled_.size(); }  // on disk now
  uint64_t TotalSpilled() const { return totalSpilled_; }      // ever

 private:
  struct Spilled {
    int width, height;
  };
  std::filesystem::path SpillPath(int frame) const;

  std::filesystem::path directory_;
  size_t budget_;
  size_t heldBytes_ = 0;
  std::map<int, Image> held_;
  std::map<int, Spilled> spilled_;
  uint64_t totalSpilled_ = 0;
};

}  // namespace tcfarm
