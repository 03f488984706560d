// Choosing guarded's bin width from the sequence itself.
//
// Equation 3 predicts search's cost from the mean change rate d alone, and it only ever
// falls as the bin widens: it cannot choose a width. What a wider bin costs guarded is
// where the changes are in time: a tile whose coarse sample changes anywhere inside a bin
// is searched down to every interval where it changes. A survey of the guard's coarse
// raster (one sample per tile, about 1.6 % of the pixels) over the first frames holds
// exactly that, so guarded search can be played out on it for every width: each tile
// stands for its pixels, traced at an interval's middle frame whenever its sample changes
// inside the interval, as GuardedPlanner would force it. The width that traces least wins.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace tcfarm {

struct CoarseSurvey {
  uint32_t width = 0, height = 0;  // the image, pixels
  uint32_t tile = 8;               // the guard's tile side (PlannerOptions::coarseTile)
  float tolerance = 0;             // as PlannerOptions::tolerance
  // Per surveyed frame (the job's first frames, in order): the RGB of each tile's sample,
  // tiles in row-major order (CoarseGuard's sample order).
  std::vector<std::vector<float>> samples;

  uint32_t TilesAcross() const { return (width + tile - 1) / tile; }
  uint32_t TilesDown() const { return (height + tile - 1) / tile; }
};

// The share of the surveyed frames' pixels that guarded search with this bin width
// would trace there: bin ends in full, the coarse samples of inner frames, and each
// tile's other pixels at every middle frame where its sample changes inside the interval.
// Throws std::invalid_argument for a survey whose sample counts do not match its tiles.
double PredictGuardedTracedShare(const CoarseSurvey& survey, int binWidth);

struct BinWidthChoice {
  int binWidth = 2;
  std::vector<std::pair<int, double>> predicted;  // (width, traced share) for 2 .. widest
};
// The width in [2, min(widest, surveyed frames)] that traces least; on a tie the
// narrower, whose copies span fewer frames.
BinWidthChoice ChooseGuardedBinWidth(const CoarseSurvey& survey, int widest);

}  // namespace tcfarm
