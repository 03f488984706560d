// Where a job's files lie in the store folder; the one place that knows the layout:
//
//   STORE/<job>/frame_NNNN.exr, frame_NNNN.png   the finished frames
//   STORE/<job>/mask_NNNN.png                    traced pixels white, copied black
//   STORE/<job>/change_NNNN.png                  pixels equal to frame NNNN-1's white
//   STORE/<job>/.pending/                        frames waiting for their turn on disk
//                                                (PendingFrames names the files inside)
//   STORE/store-id                               the store's identity (store_identity.h)
//
// NNNN is the scene's absolute frame number. The farm writes these files; the HTTP API
// serves them. Paths only: nothing here touches the disk.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace tcfarm {

enum class MaskKind { kTraced, kChange };
// "mask" and "change", the names in the files and in the API's routes.
std::string_view MaskKindName(MaskKind kind);
std::optional<MaskKind> MaskKindFromName(std::string_view name);

class FrameStore {
 public:
  explicit FrameStore(std::filesystem::path root) : root_(std::move(root)) {}

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path JobFolder(uint64_t job) const;
  // extension: "exr" or "png".
  std::filesystem::path FramePath(uint64_t job, int frame, std::string_view extension) const;
  std::filesystem::path MaskPath(uint64_t job, MaskKind kind, int frame) const;
  // The mask's file name inside the job's folder, as FrameWriter::WriteMask takes it.
  static std::string MaskFileName(MaskKind kind, int frame);
  std::filesystem::path SpillFolder(uint64_t job) const;

 private:
  std::filesystem::path root_;
};

}  // namespace tcfarm
