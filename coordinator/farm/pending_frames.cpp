#include "coordinator/farm/pending_frames.h"

#include <cstdio>
#include <memory>
#include <string>
#include <system_error>
#include <utility>

namespace tcfarm {
namespace {

size_t BytesOf(const Image& image) { return image.rgb.size() * sizeof(float); }

struct FileCloser {
  void operator()(std::FILE* file) const { std::fclose(file); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

}  // namespace

PendingFrames::PendingFrames(std::filesystem::path spillDirectory, size_t memoryBudgetBytes)
    : directory_(std::move(spillDirectory)), budget_(memoryBudgetBytes) {}

PendingFrames::~PendingFrames() {
  std::error_code ignored;
  if (!spilled_.empty() || std::filesystem::exists(directory_, ignored)) {
    std::filesystem::remove_all(directory_, ignored);
  }
}

std::filesystem::path PendingFrames::SpillPath(int frame) const {
  return directory_ / (std::to_string(frame) + ".rgb32f");
}

void PendingFrames::Put(int frame, Image image) {
  if (heldBytes_ + BytesOf(image) <= budget_) {
    heldBytes_ += BytesOf(image);
    held_[frame] = std::move(image);
    return;
  }
  std::error_code error;
  std::filesystem::create_directories(directory_, error);
  const std::filesystem::path path = SpillPath(frame);
  File file(std::fopen(path.c_str(), "wb"));
  if (!file || std::fwrite(image.rgb.data(), sizeof(float), image.rgb.size(), file.get()) != image.rgb.size() ||
      std::fflush(file.get()) != 0) {
    std::filesystem::remove(path, error);
    throw FrameIoError("cannot spill frame " + std::to_string(frame) + " to " + path.string() +
                       ": disk full or not writable");
  }
  spilled_[frame] = {image.width, image.height};
  ++totalSpilled_;
}

std::optional<Image> PendingFrames::Take(int frame) {
  if (auto held = held_.find(frame); held != held_.end()) {
    Image image = std::move(held->second);
    held_.erase(held);
    heldBytes_ -= BytesOf(image);
    return image;
  }
  auto spilled = spilled_.find(frame);
  if (spilled == spilled_.end()) return std::nullopt;
  Image image{spilled->second.width, spilled->second.height, {}};
  image.rgb.resize(image.PixelCount() * 3);
  const std::filesystem::path path = SpillPath(frame);
  File file(std::fopen(path.c_str(), "rb"));
  if (!file || std::fread(image.rgb.data(), sizeof(float), image.rgb.size(), file.get()) != image.rgb.size()) {
    throw FrameIoError("cannot read back frame " + std::to_string(frame) + " from " + path.string());
  }
  file.reset();
  spilled_.erase(spilled);
  std::error_code ignored;
  std::filesystem::remove(path, ignored);
  return image;
}

}  // namespace tcfarm
