// A check that disagreed with a job promising exactness, and how it is settled.
//
// Two workers returned different bits for the same pixels: the one whose values are in
// the job (through a trace or a copy of one) and the checker. Neither can be believed
// over the other, so a third party that every job trusts, the coordinator's referee
// (farm/referee.h), traces the disputed pixels itself; its values are the truth.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace tcfarm {

struct Dispute {
  int frame = 0;            // the job's numbering
  std::string checker;      // the worker whose check disagreed
  std::vector<uint32_t> pixels;  // a sample of the pixels that disagree
  std::vector<float> jobValues;      // 3 per pixel, in pixels' order
  std::vector<float> checkerValues;  // 3 per pixel
};

// The most pixels a dispute carries: a few suffice to tell who is wrong, and the
// referee traces every one.
constexpr size_t kMaxDisputedPixels = 64;

// A worker found to return values that are not the truth, and the evidence, in words.
struct Verdict {
  std::string worker;  // its principal
  std::string why;
};

struct Ruling {
  bool checkerWrong = false;        // some checked value is not the truth
  std::vector<uint32_t> jobWrong;   // pixels whose value in the job is not the truth
};

// Compares both sides with the truth (3 floats per disputed pixel), bit for bit.
// Throws std::invalid_argument when truth has the wrong size.
Ruling Settle(const Dispute& dispute, const std::vector<float>& truth);

}  // namespace tcfarm
