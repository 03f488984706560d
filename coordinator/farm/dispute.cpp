#include "coordinator/farm/dispute.h"

#include <stdexcept>

#include "proto/frame/compare.h"

namespace tcfarm {
Ruling Settle(const Dispute& dispute, const std::vector<float>& truth) {
  const size_t floats = 3 * dispute.pixels.size();
  if (truth.size() != floats || dispute.jobValues.size() != floats || dispute.checkerValues.size() != floats) {
    throw std::invalid_argument("a dispute over " + std::to_string(dispute.pixels.size()) + " pixels got " +
                                std::to_string(truth.size()) + " values of the truth");
  }
  Ruling ruling;
  for (size_t i = 0; i < dispute.pixels.size(); ++i) {
    const float* real = &truth[3 * i];
    if (!SameBits(&dispute.checkerValues[3 * i], real)) ruling.checkerWrong = true;
    if (!SameBits(&dispute.jobValues[3 * i], real)) ruling.jobWrong.push_back(dispute.pixels[i]);
  }
  return ruling;
}

}  // namespace tcfarm
