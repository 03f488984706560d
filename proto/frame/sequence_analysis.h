// Coherence analysis of any frame sequence (paper, sections 2 and 4): pixel events and their
// durations (Figures 3 and 4), frame-to-frame and long-term coherence (Figures 5 and 6),
// the pixels that ever change (Figure 7), and equation 3's predicted relative cost of the
// `search` algorithm for each bin width (Figure 8), with d measured from the sequence.
#pragma once

#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/frame/coherence.h"
#include "proto/frame/frame_io.h"

namespace tcfarm {

// Equation 3 for one bin width: relativeCost = (a + b) / N, performanceRatio = N / (a + b).
struct BinWidthPrediction {
  int binWidth = 0;
  double relativeCost = 0;
  double performanceRatio = 0;
};

struct SequenceAnalysis {
  int frames = 0, width = 0, height = 0;
  RunningStats frameToFrame, longTerm;
  std::vector<double> frameToFrameByFrame;  // [f] = coherence(f, f + 1)
  std::vector<double> longTermByFrame;      // [f - 1] = coherence(first, f), f >= 1 (Figure 6)
  // A pixel event is a maximal run of frames over which a pixel keeps its value, bitwise.
  std::vector<uint64_t> eventsByDuration;     // [duration in frames] = count; [0] is 0 (Figure 3)
  std::vector<double> volumeShareByDuration;  // duration * count / (frames * pixels) (Figure 4)
  uint64_t eventCount = 0;
  double meanEventDuration = 0, eventDurationStdDev = 0;  // over events (population sd)
  double d = 0;  // 1 - mean frame-to-frame coherence; 0 for a single frame (nothing changed)
  std::vector<BinWidthPrediction> predictions;  // bin widths 2 .. min(frames, 64) (Figure 8)
  std::vector<uint8_t> changeMask;  // width * height, 1 where the pixel ever changes (Figure 7)

  double ChangedPixelShare() const;
  // snake_case fields. The change mask is left out (one entry per pixel); its share is in.
  nlohmann::json ToJson() const;
};

// A frame told by the pixels that may differ from the frame before it; every other pixel
// is, bit for bit, the previous frame's. The farm's planners give a pixel they do not
// trace at a frame the value it had at the frame before, so a frame's traced pixels are
// all that can change, and the analysis need not look at the rest.
struct FrameChanges {
  std::vector<uint32_t> pixels;  // ascending pixel indices
  std::vector<float> rgb;        // 3 per pixel, in pixels' order
  // The pixels of `frame` where mayChange (one byte per pixel) is non-zero.
  static FrameChanges Gather(const Image& frame, const std::vector<uint8_t>& mayChange);
};

// Feed frames in order, then Finish. Memory is O(pixels): the first and the previous frame
// and per pixel the frame its current event began at, never O(frames * pixels), so
// sequences of any length fit.
class SequenceAnalyzer {
 public:
  // Throws std::invalid_argument for an empty or malformed image, or one whose size differs
  // from the first frame's.
  // unchanged, when given, is set to the frame's change mask: 1 where the pixel is bitwise
  // the previous frame's (every pixel of the first frame), 0 elsewhere.
  void Add(const Image& frame, std::vector<uint8_t>* unchanged = nullptr);
  // The next frame by its changes: every figure and mask comes out as Add of the whole
  // frame would give them, at a cost that grows with the pixels listed, not the frame.
  // Throws std::invalid_argument before the first frame (it is taken whole), and for
  // pixels out of range or not ascending, or other than 3 values per pixel; nothing
  // changes then.
  void AddChanges(const FrameChanges& changes, std::vector<uint8_t>* unchanged = nullptr);
  // The same for a whole frame whose pixels may differ from the previous frame's only
  // where mayChange (one byte per pixel) is non-zero; the first frame is taken whole.
  // Throws std::invalid_argument as Add does, and for a mask of another size.
  void AddTraced(const Image& frame, const std::vector<uint8_t>& mayChange, std::vector<uint8_t>* unchanged = nullptr);
  int FrameCount() const { return frames_; }
  // Running coherence figures, cheap to read while frames arrive.
  const RunningStats& frameToFrame() const { return frameToFrame_; }
  const RunningStats& longTerm() const { return longTerm_; }
  // Throws std::logic_error before the first frame. May be called again after more Adds.
  SequenceAnalysis Finish() const;

 private:
  void CheckShape(const Image& frame) const;
  void Start(const Image& frame);
  void CheckChanges(const FrameChanges& changes) const;
  // A new frame begins: its change mask starts all unchanged.
  void BeginFrame(std::vector<uint8_t>* unchanged);
  // Pixel `pixel` of the new frame has `value`; returns whether that ends its event (the
  // bits differ from the previous frame's), which also clears its mark in `mask`.
  bool AdvancePixel(size_t pixel, const float* value, uint8_t* mask);
  // The new frame's figures, from how many of its pixels changed.
  void EndFrame(size_t changedPixels);
  std::vector<uint64_t> EventsIncludingOpenRuns() const;

  int frames_ = 0, width_ = 0, height_ = 0;
  Image first_, previous_;
  // Per pixel: the frame its current event began at (0 for a pixel that never changed).
  // Pixels that do not change cost nothing: their runs grow with the frame count.
  std::vector<uint32_t> eventStart_;
  // Per pixel: whether it is bitwise the first frame's, and how many are. A pixel that
  // keeps its value keeps this too, so it changes only where an event ends.
  std::vector<uint8_t> sameAsFirst_;
  size_t sameAsFirstCount_ = 0;
  std::vector<uint64_t> closedEventsByDuration_;
  RunningStats frameToFrame_, longTerm_;
  std::vector<double> frameToFrameByFrame_, longTermByFrame_;
};

// Largest bin width for which SequenceAnalysis carries a prediction.
constexpr int kMaxPredictedBinWidth = 64;

// Equation 3: the relative cost (a + b) / N of tracing N frames with bin width n, when a
// share d of the pixels differ between frames. Bins share their end frames, so the N - 1
// steps between frames make q = floor((N-1)/(n-1)) whole bins of n - 1 steps and leave
// r = rem((N-1)/(n-1)) steps over:
//   a = 1 + q (1 + (n-2) d)     the first frame, then per bin its far end in full and d
//                               of the pixels in each of its n - 2 inner frames;
//   b = 0 when r = 0, else (r-1) d + 1   the remainder, searched as one smaller bin.
// Throws std::invalid_argument for binWidth < 2 or frames < 1.
double Equation3RelativeCost(int frames, int binWidth, double d);

// The bin width in 2..maxBinWidth of least equation-3 relative cost; the smaller on ties.
// Equation 3 depends on n only through the number of bins B = ceil((N-1)/(n-1)):
// (a + b) / N = (1 + B + (N-1-B) d) / N, which never rises with n (a bin end costs 1, an
// inner frame d <= 1). So the answer is the smallest n that reaches the fewest bins under
// the cap, and the cap is where the paper's warning about phenomena missed by too wide a bin
// must come in. Throws std::invalid_argument for maxBinWidth < 2 or frames < 1.
int BestBinWidth(int frames, double d, int maxBinWidth);

}  // namespace tcfarm
