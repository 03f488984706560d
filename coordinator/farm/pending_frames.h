// Finished frames that wait for their turn: a job's coherence and change masks read its
// frames in order, and planners release them out of order (the paper's search finishes
// bins side by side). Held in memory up to a budget, spilled beyond it to raw files, so
// a job's memory does not grow with how far ahead its frames finish: 60 frames of
// 16384x16384 would otherwise wait as 190 GB. A frame waits whole, or by its changes
// from the frame before (FrameChanges), which is all the coherence reads of it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <variant>

#include "proto/frame/frame_io.h"
#include "proto/frame/sequence_analysis.h"

namespace tcfarm {

class PendingFrames {
 public:
  using Frame = std::variant<Image, FrameChanges>;

  // spillDirectory is created on the first spill and removed by the destructor.
  PendingFrames(std::filesystem::path spillDirectory, size_t memoryBudgetBytes);
  ~PendingFrames();
  PendingFrames(const PendingFrames&) = delete;
  PendingFrames& operator=(const PendingFrames&) = delete;

  // Throws FrameIoError when a spill cannot be written (the frame is not kept).
  void Put(int frame, Frame waiting);
  // The frame, bit for bit as put, and forgets it; nullopt when it is not there. Throws
  // FrameIoError when a spilled frame cannot be read back.
  std::optional<Frame> Take(int frame);

  size_t HeldBytes() const { return heldBytes_; }   // in memory
  size_t SpilledFrames() const { return spilled_.size(); }  // on disk now
  uint64_t TotalSpilled() const { return totalSpilled_; }      // ever

 private:
  // What a spill file holds: the frame whole (floats), or its pixels then their floats.
  struct Spilled {
    bool changes = false;
    int width = 0, height = 0;  // a whole frame's
    size_t pixels = 0;          // changes: how many
  };
  std::filesystem::path SpillPath(int frame) const;
  void Spill(int frame, const Frame& waiting);

  std::filesystem::path directory_;
  size_t budget_;
  size_t heldBytes_ = 0;
  std::map<int, Frame> held_;
  std::map<int, Spilled> spilled_;
  uint64_t totalSpilled_ = 0;
};

}  // namespace tcfarm
