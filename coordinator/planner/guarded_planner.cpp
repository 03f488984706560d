#include "coordinator/planner/guarded_planner.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

namespace tcfarm {
namespace {

constexpr const char* kPlannerName = "guarded planner";

uint32_t CeilDiv(uint32_t a, uint32_t b) { return a / b + (a % b != 0); }

// The guard needs the geometry before SearchPlanner's constructor validates it.
std::unique_ptr<CoarseGuard> MakeGuard(const PlannerOptions& options) {
  planner_internal::ValidateCommonOptions(options);
  planner_internal::RequireOption(options.coarseTile >= 1, "coarseTile", options.coarseTile,
                                  ">= 1 (1 samples every pixel)");
  return std::make_unique<CoarseGuard>(static_cast<uint32_t>(options.width), static_cast<uint32_t>(options.height),
                                       static_cast<uint32_t>(options.coarseTile), options.tolerance);
}

}  // namespace

CoarseGuard::CoarseGuard(uint32_t width, uint32_t height, uint32_t tile, float tolerance)
    : width_(width), height_(height), tile_(tile), tolerance_(tolerance) {
  if (width == 0 || height == 0 || tile == 0) {
    throw std::invalid_argument("coarse raster of " + std::to_string(width) + " x " + std::to_string(height) +
                                " pixels in tiles of " + std::to_string(tile) + "; expected all >= 1");
  }
  tilesAcross_ = CeilDiv(width, tile);
  tilesDown_ = CeilDiv(height, tile);
  // The pixel nearest the tile's centre that exists: a partial tile at the right or
  // bottom edge samples its last column or row when the centre falls outside the image.
  auto centre = [tile](uint32_t tileIndex, uint32_t extent) {
    const uint32_t first = tileIndex * tile;
    return first + std::min(tile / 2, extent - 1 - first);
  };
  PixelSetBuilder samples;
  sampleOfTile_.reserve(TileCount());
  for (uint32_t ty = 0; ty < tilesDown_; ++ty) {
    for (uint32_t tx = 0; tx < tilesAcross_; ++tx) {
      const uint32_t sample = centre(ty, height) * width + centre(tx, width);
      sampleOfTile_.push_back(sample);
      samples.Add(sample);  // ascending: row-major tiles have row-major centres
    }
  }
  samples_ = samples.Build();
}

uint32_t CoarseGuard::TileOf(uint32_t pixel) const {
  return (pixel / width_ / tile_) * tilesAcross_ + (pixel % width_) / tile_;
}

bool CoarseGuard::SampleEqual(const float* a, const float* b) const {
  if (tolerance_ == 0) return std::memcmp(a, b, 3 * sizeof(float)) == 0;
  return std::fabs(a[0] - b[0]) <= tolerance_ && std::fabs(a[1] - b[1]) <= tolerance_ &&
         std::fabs(a[2] - b[2]) <= tolerance_;
}

void CoarseGuard::IndexBin(size_t bin, int left, const std::vector<const float*>& frameRgb) {
  planner_internal::Check(!frameRgb.empty(), kPlannerName, "bin " + std::to_string(bin) + " indexed with no frames");
  planner_internal::Check(bins_.count(bin) == 0, kPlannerName, "bin " + std::to_string(bin) + " indexed twice");
  BinIndex& index = bins_[bin];
  index.left = left;
  index.frames = static_cast<int>(frameRgb.size());
  index.changesUpTo.assign(size_t{TileCount()} * frameRgb.size(), 0);
  for (uint32_t tile = 0; tile < TileCount(); ++tile) {
    const size_t offset = size_t{sampleOfTile_[tile]} * 3;
    uint32_t* changes = index.changesUpTo.data() + size_t{tile} * frameRgb.size();
    for (size_t i = 1; i < frameRgb.size(); ++i) {
      changes[i] = changes[i - 1] + !SampleEqual(frameRgb[i - 1] + offset, frameRgb[i] + offset);
    }
  }
}

void CoarseGuard::ForgetBin(size_t bin) { bins_.erase(bin); }

PixelSet CoarseGuard::PixelsOfChangedTiles(size_t bin, int left, int right) const {
  auto found = bins_.find(bin);
  planner_internal::Check(found != bins_.end(), kPlannerName, "bin " + std::to_string(bin) + " is not indexed");
  const BinIndex& index = found->second;
  planner_internal::Check(left >= index.left && left <= right && right < index.left + index.frames, kPlannerName,
                          "interval [" + std::to_string(left) + ", " + std::to_string(right) +
                              "] outside bin " + std::to_string(bin));
  const size_t first = static_cast<size_t>(left - index.left);
  const size_t last = static_cast<size_t>(right - index.left);
  PixelSetBuilder pixels;
  for (uint32_t ty = 0; ty < tilesDown_; ++ty) {
    // Runs of changed tiles in this tile row, as column ranges, then one span per pixel row.
    std::vector<std::pair<uint32_t, uint32_t>> columns;
    for (uint32_t tx = 0; tx < tilesAcross_; ++tx) {
      const uint32_t* changes = index.changesUpTo.data() + size_t{ty * tilesAcross_ + tx} * index.frames;
      if (changes[last] == changes[first]) continue;
      const uint32_t begin = tx * tile_, end = std::min(begin + tile_, width_);
      if (!columns.empty() && columns.back().second == begin) {
        columns.back().second = end;
      } else {
        columns.emplace_back(begin, end);
      }
    }
    const uint32_t rowEnd = std::min((ty + 1) * tile_, height_);
    for (uint32_t y = ty * tile_; y < rowEnd && !columns.empty(); ++y) {
      for (const auto& [begin, end] : columns) pixels.AddSpan(y * width_ + begin, y * width_ + end);
    }
  }
  return pixels.Build();
}

GuardedPlanner::GuardedPlanner(const PlannerOptions& options) : SearchPlanner(options, MakeGuard(options)) {}

GuardedPlanner::GuardedPlanner(const PlannerOptions& options, std::vector<std::vector<float>> coarseSamples)
    : SearchPlanner(options, MakeGuard(options), std::move(coarseSamples)) {}

}  // namespace tcfarm
