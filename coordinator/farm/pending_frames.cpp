#include "coordinator/farm/pending_frames.h"

#include <cstdio>
#include <memory>
#include <string>
#include <system_error>
#include <utility>

namespace tcfarm {
namespace {

size_t BytesOf(const PendingFrames::Frame& waiting) {
  if (const Image* image = std::get_if<Image>(&waiting)) return image->rgb.size() * sizeof(float);
  const FrameChanges& changes = std::get<FrameChanges>(waiting);
  return changes.pixels.size() * sizeof(uint32_t) + changes.rgb.size() * sizeof(float);
}

template <typename T>
bool WriteAll(std::FILE* file, const std::vector<T>& values) {
  return std::fwrite(values.data(), sizeof(T), values.size(), file) == values.size();
}

template <typename T>
bool ReadAll(std::FILE* file, std::vector<T>& values, size_t count) {
  values.resize(count);
  return std::fread(values.data(), sizeof(T), count, file) == count;
}

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

void PendingFrames::Put(int frame, Frame waiting) {
  const size_t bytes = BytesOf(waiting);
  if (heldBytes_ + bytes <= budget_) {
    heldBytes_ += bytes;
    held_[frame] = std::move(waiting);
    return;
  }
  Spill(frame, waiting);
}

void PendingFrames::Spill(int frame, const Frame& waiting) {
  std::error_code error;
  std::filesystem::create_directories(directory_, error);
  const std::filesystem::path path = SpillPath(frame);
  File file(std::fopen(path.c_str(), "wb"));
  Spilled spilled;
  bool written = false;
  if (const Image* image = std::get_if<Image>(&waiting)) {
    spilled = {false, image->width, image->height, 0};
    written = file && WriteAll(file.get(), image->rgb);
  } else {
    const FrameChanges& changes = std::get<FrameChanges>(waiting);
    spilled = {true, 0, 0, changes.pixels.size()};
    written = file && WriteAll(file.get(), changes.pixels) && WriteAll(file.get(), changes.rgb);
  }
  if (!written || std::fflush(file.get()) != 0) {
    std::filesystem::remove(path, error);
    throw FrameIoError("cannot spill frame " + std::to_string(frame) + " to " + path.string() +
                       ": disk full or not writable");
  }
  spilled_[frame] = spilled;
  ++totalSpilled_;
}

std::optional<PendingFrames::Frame> PendingFrames::Take(int frame) {
  if (auto held = held_.find(frame); held != held_.end()) {
    Frame waiting = std::move(held->second);
    held_.erase(held);
    heldBytes_ -= BytesOf(waiting);
    return waiting;
  }
  auto spilled = spilled_.find(frame);
  if (spilled == spilled_.end()) return std::nullopt;
  const Spilled& what = spilled->second;
  const std::filesystem::path path = SpillPath(frame);
  File file(std::fopen(path.c_str(), "rb"));
  Frame waiting;
  bool read = false;
  if (what.changes) {
    FrameChanges changes;
    read = file && ReadAll(file.get(), changes.pixels, what.pixels) &&
           ReadAll(file.get(), changes.rgb, what.pixels * 3);
    waiting = std::move(changes);
  } else {
    Image image{what.width, what.height, {}};
    read = file && ReadAll(file.get(), image.rgb, image.PixelCount() * 3);
    waiting = std::move(image);
  }
  if (!read) throw FrameIoError("cannot read back frame " + std::to_string(frame) + " from " + path.string());
  file.reset();
  spilled_.erase(spilled);
  std::error_code ignored;
  std::filesystem::remove(path, ignored);
  return waiting;
}

}  // namespace tcfarm
