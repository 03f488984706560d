#include "coordinator/planner/bin_width_survey.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include "coordinator/planner/planner.h"

namespace tcfarm {
namespace {

bool SampleEqual(const float* a, const float* b, float tolerance) {
  if (tolerance == 0) return std::memcmp(a, b, 3 * sizeof(float)) == 0;
  return std::fabs(a[0] - b[0]) <= tolerance && std::fabs(a[1] - b[1]) <= tolerance &&
         std::fabs(a[2] - b[2]) <= tolerance;
}

void ValidateSurvey(const CoarseSurvey& survey) {
  if (survey.width == 0 || survey.height == 0 || survey.tile == 0 || survey.samples.empty()) {
    throw std::invalid_argument("coarse survey of " + std::to_string(survey.samples.size()) + " frames of " +
                                std::to_string(survey.width) + " x " + std::to_string(survey.height) +
                                " pixels, tile " + std::to_string(survey.tile) + "; expected all >= 1");
  }
  const size_t floats = size_t{survey.TilesAcross()} * survey.TilesDown() * 3;
  for (size_t f = 0; f < survey.samples.size(); ++f) {
    if (survey.samples[f].size() != floats) {
      throw std::invalid_argument("coarse survey frame " + std::to_string(f) + " holds " +
                                  std::to_string(survey.samples[f].size()) + " floats; expected " +
                                  std::to_string(floats) + " (3 per tile)");
    }
  }
}

// Per tile, how many times its sample changed up to each surveyed frame, so that
// "changes inside [l, r]" is one subtraction.
std::vector<uint32_t> ChangesUpTo(const CoarseSurvey& survey) {
  const size_t frames = survey.samples.size();
  const size_t tiles = size_t{survey.TilesAcross()} * survey.TilesDown();
  std::vector<uint32_t> changes(tiles * frames, 0);
  for (size_t tile = 0; tile < tiles; ++tile) {
    uint32_t* counts = changes.data() + tile * frames;
    for (size_t f = 1; f < frames; ++f) {
      counts[f] = counts[f - 1] + !SampleEqual(&survey.samples[f - 1][3 * tile], &survey.samples[f][3 * tile],
                                               survey.tolerance);
    }
  }
  return changes;
}

// Middle-frame traces the search makes for one tile over [left, right], as SearchPlanner
// splits intervals.
uint64_t TracesOfTile(const uint32_t* changes, int left, int right) {
  if (right - left < 2 || changes[right] == changes[left]) return 0;
  const int mid = left + (right - left) / 2;
  return 1 + TracesOfTile(changes, left, mid) + TracesOfTile(changes, mid, right);
}

double Predict(const CoarseSurvey& survey, const std::vector<uint32_t>& changes, int binWidth) {
  const int frames = static_cast<int>(survey.samples.size());
  const uint32_t across = survey.TilesAcross(), down = survey.TilesDown();
  const uint64_t pixelsPerFrame = uint64_t{survey.width} * survey.height;
  uint64_t traced = 0;
  const auto bins = planner_internal::TileBins(frames, binWidth);
  traced += pixelsPerFrame * (bins.size() + (frames > 1 ? 1 : 0));  // every distinct bin end
  for (const auto& [left, right] : bins) {
    if (right - left < 2) continue;
    traced += uint64_t{across} * down * static_cast<uint64_t>(right - left - 1);  // coarse samples
    for (uint32_t ty = 0; ty < down; ++ty) {
      const uint64_t rows = std::min(survey.tile, survey.height - ty * survey.tile);
      for (uint32_t tx = 0; tx < across; ++tx) {
        const uint64_t columns = std::min(survey.tile, survey.width - tx * survey.tile);
        const size_t tile = size_t{ty} * across + tx;
        traced += (rows * columns - 1) * TracesOfTile(changes.data() + tile * frames, left, right);
      }
    }
  }
  return static_cast<double>(traced) / (static_cast<double>(pixelsPerFrame) * frames);
}

}  // namespace

double PredictGuardedTracedShare(const CoarseSurvey& survey, int binWidth) {
  ValidateSurvey(survey);
  if (binWidth < 2) throw std::invalid_argument("bin width " + std::to_string(binWidth) + "; expected >= 2");
  return Predict(survey, ChangesUpTo(survey), binWidth);
}

BinWidthChoice ChooseGuardedBinWidth(const CoarseSurvey& survey, int widest) {
  ValidateSurvey(survey);
  const std::vector<uint32_t> changes = ChangesUpTo(survey);
  const int last = std::max(2, std::min(widest, static_cast<int>(survey.samples.size())));
  BinWidthChoice choice;
  double best = 0;
  for (int width = 2; width <= last; ++width) {
    const double share = Predict(survey, changes, width);
    choice.predicted.emplace_back(width, share);
    if (width == 2 || share < best) {
      best = share;
      choice.binWidth = width;
    }
  }
  return choice;
}

}  // namespace tcfarm
