#include "coordinator/store/frame_store.h"

#include "proto/frame/frame_io.h"

namespace tcfarm {

std::string_view MaskKindName(MaskKind kind) { return kind == MaskKind::kTraced ? "mask" : "change"; }

std::optional<MaskKind> MaskKindFromName(std::string_view name) {
  for (MaskKind kind : {MaskKind::kTraced, MaskKind::kChange}) {
    if (MaskKindName(kind) == name) return kind;
  }
  return std::nullopt;
}

std::filesystem::path FrameStore::JobFolder(uint64_t job) const { return root_ / std::to_string(job); }

// FrameWriter names the frames it writes with FrameFileStem too, so the paths agree.
std::filesystem::path FrameStore::FramePath(uint64_t job, int frame, std::string_view extension) const {
  return JobFolder(job) / (FrameFileStem(frame) + "." + std::string(extension));
}

std::filesystem::path FrameStore::MaskPath(uint64_t job, MaskKind kind, int frame) const {
  return JobFolder(job) / MaskFileName(kind, frame);
}

std::string FrameStore::MaskFileName(MaskKind kind, int frame) {
  return MaskFileStem(std::string(MaskKindName(kind)), frame) + ".png";
}

std::filesystem::path FrameStore::SpillFolder(uint64_t job) const { return JobFolder(job) / ".pending"; }

}  // namespace tcfarm
