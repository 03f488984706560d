// What a job costs the coordinator in memory, estimated before it runs: the farm admits
// jobs against one budget for all of them (Farm::ClaimJobs), the HTTP API refuses at
// submit a job that could not fit even alone, and a running job works on as many bins
// (segments) at once as its share allows.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "coordinator/planner/strategy.h"

namespace tcfarm {

// What a job's memory depends on.
struct JobMemoryShape {
  int width = 0;
  int height = 0;
  int frameCount = 0;
  Strategy strategy = Strategy::kSearch;  // resolved: never kAuto
  int binWidth = 0;                       // with surveyBinWidth: the widest considered
  bool surveyBinWidth = false;            // auto's guarded: the survey's coarse samples too
  // The farm's memory for frames that finish ahead of their turn (PendingFrames).
  uint64_t pendingFrameBytes = 0;
};

// The shape of a job as it will run at most, from its request alone (no scene, no
// workers): auto is taken as guarded with the widest bin its survey may pick unless the
// submission says camera and lights are static (then exact, which holds one working frame
// per segment whatever the segments' length). Never less than the job will need.
JobMemoryShape RequestedJobShape(Strategy requested, int binWidth, int frameCount,
                                 std::optional<bool> cameraOrLightsChange, int width, int height,
                                 uint64_t pendingFrameBytes);

// Frames of width x height float RGB (12 bytes a pixel) a job holds at most: the planner's
// working frames with `liveBins` bins (segments) at once (a search or guarded bin holds its
// own frames, an exact segment one working frame), plus kFarmFramesPerJob the farm keeps
// (frames waiting for the writer and queued in it, the coherence analysis), and never more
// than the job's own frames plus those the farm copies. Measured peaks (RSS) stay below
// it: 5 frames for a one-frame job, 47 for a 60-frame search at n = 10.
constexpr int kFarmFramesPerJob = 14;
int FramesHeldPerJob(Strategy strategy, int binWidth, int liveBins, int frameCount);
// Bytes of one width x height frame as the coordinator holds it (float RGB).
uint64_t FrameBytes(int width, int height);
// What a job keeps for each of its frames whatever their size (kept, written and released
// flags, recorded traced counts, per-frame coherence figures), generously.
constexpr uint64_t kBookkeepingBytesPerFrame = 64;

// The job's memory at most with `liveBins` bins (segments) at once: its frames held, the
// pending frames' memory, auto's survey samples and the per-frame bookkeeping.
uint64_t JobMemoryBytes(const JobMemoryShape& shape, int liveBins);
// The most bins (segments), 1 .. maxLiveBins, whose memory fits in `budgetBytes`; 0 when
// not even one bin's does.
int LiveBinsWithin(uint64_t budgetBytes, const JobMemoryShape& shape, int maxLiveBins);

// Why a job cannot fit in `budgetBytes` (the farm's memory for all running jobs) even
// alone and one bin at a time: what it needs and what the farm has; "" when it fits.
std::string MemoryShortfall(uint64_t budgetBytes, const JobMemoryShape& shape);
// "33.0 KiB", "12.0 MiB", "3.00 GiB": how the messages give sizes.
std::string MemoryText(uint64_t bytes);

}  // namespace tcfarm
