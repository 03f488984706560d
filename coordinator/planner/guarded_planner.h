// The `guarded` planner: the paper's own remedy for the flaw of `search` (section 4,
// docs/architecture.md, section 3.3).
//
// Before a bin is searched, every frame of it is traced on a coarse raster: one sample
// per coarseTile x coarseTile tile, at the existing pixel nearest the tile's centre (tiles
// at the right and bottom edges may be partial). The search then runs as in `search`,
// except that Search(S, l, r) treats a pixel as changed when its ends differ or when its
// tile's sample differs between any two consecutive frames of [l, r]: a small object
// moving between equal bin ends is caught as long as it crosses a tile's sample.
//
// The coarse samples are ordinary pixels traced at their frames: they are the pixels'
// final values (marked traced, counted in TracedPixels) and are never traced or copied
// again at those frames, so they cost no ray twice. At a bin's end frames the full trace
// already includes them; interior frames get a trace of the samples alone. The search
// itself then covers only the other pixels.
//
// GuardedPlanner is SearchPlanner with a CoarseGuard plugged in; the bin machinery
// (tasks, continuations, frame release) is shared.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "proto/pixel_set/pixel_set.h"
#include "coordinator/planner/planner.h"
#include "coordinator/planner/search_planner.h"

namespace tcfarm {

// The coarse raster of one job and, per live bin, which tiles change where.
class CoarseGuard {
 public:
  // tolerance as in PlannerOptions: a sample changes when it is not equal to the one before.
  CoarseGuard(uint32_t width, uint32_t height, uint32_t tile, float tolerance);

  const PixelSet& Samples() const { return samples_; }  // one pixel per tile, ascending
  uint32_t TileCount() const { return tilesAcross_ * tilesDown_; }
  uint32_t SampleOf(uint32_t tile) const { return sampleOfTile_[tile]; }
  uint32_t TileOf(uint32_t pixel) const;

  // Records which tiles change between consecutive frames of a bin; frameRgb[i] is the
  // RGB of frame left + i, whose samples must be known. Called once per bin, before its search.
  void IndexBin(size_t bin, int left, const std::vector<const float*>& frameRgb);
  void ForgetBin(size_t bin);
  size_t IndexedBins() const { return bins_.size(); }

  // Every pixel of every tile whose sample differs between two consecutive frames in
  // [left, right] (frames of the indexed bin).
  PixelSet PixelsOfChangedTiles(size_t bin, int left, int right) const;

 private:
  struct BinIndex {
    int left = 0;
    int frames = 0;
    // [tile * frames + i]: changes of the tile's sample between consecutive frames in
    // [left, left + i], so any interval's count is one subtraction.
    std::vector<uint32_t> changesUpTo;
  };

  bool SampleEqual(const float* a, const float* b) const;

  uint32_t width_ = 0;
  uint32_t height_ = 0;
  uint32_t tile_ = 0;
  float tolerance_ = 0;
  uint32_t tilesAcross_ = 0;
  uint32_t tilesDown_ = 0;
  PixelSet samples_;
  std::vector<uint32_t> sampleOfTile_;
  std::unordered_map<size_t, BinIndex> bins_;
};

class GuardedPlanner : public SearchPlanner {
 public:
  // Throws std::invalid_argument naming the bad option (coarseTile must be >= 1; 1
  // samples every pixel, which makes guarded brute force).
  explicit GuardedPlanner(const PlannerOptions& options);
  // The same, with the coarse samples of the first frames traced already
  // (coarseSamples[f]: frame f's, in Samples() order; see SearchPlanner).
  GuardedPlanner(const PlannerOptions& options, std::vector<std::vector<float>> coarseSamples);
};

}  // namespace tcfarm
