#include "coordinator/planner/search_planner.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "coordinator/planner/guarded_planner.h"

namespace tcfarm {
namespace {

constexpr const char* kPlannerName = "search planner";

void Check(bool condition, const std::string& what) { planner_internal::Check(condition, kPlannerName, what); }

template <typename A, typename B>
void CheckEqual(const A& actual, const B& expected, const char* what) {
  planner_internal::CheckEqual(actual, expected, kPlannerName, what);
}

void ValidateOptions(const PlannerOptions& options) {
  planner_internal::ValidateCommonOptions(options);
  planner_internal::RequireOption(options.binWidth >= 2, "binWidth", options.binWidth,
                                  ">= 2 (2 traces every pixel)");
}

struct BitwiseEqual {
  bool operator()(const float* a, const float* b) const { return std::memcmp(a, b, 3 * sizeof(float)) == 0; }
};

struct EqualWithin {
  float tolerance;
  bool operator()(const float* a, const float* b) const {
    return std::fabs(a[0] - b[0]) <= tolerance && std::fabs(a[1] - b[1]) <= tolerance &&
           std::fabs(a[2] - b[2]) <= tolerance;
  }
};

}  // namespace

SearchPlanner::SearchPlanner(const PlannerOptions& options) : SearchPlanner(options, nullptr) {}

SearchPlanner::SearchPlanner(const PlannerOptions& options, std::unique_ptr<CoarseGuard> guard,
                             std::vector<std::vector<float>> coarseSamples)
    : options_(options), guard_(std::move(guard)), coarseSamples_(std::move(coarseSamples)) {
  ValidateOptions(options);
  pixelCount_ = static_cast<uint32_t>(options.width) * static_cast<uint32_t>(options.height);
  // The coarse samples are traced at every frame, so the search never needs them.
  searchPixels_ = PixelSet::Full(pixelCount_);
  if (guard_) searchPixels_ = searchPixels_.Difference(guard_->Samples());
  for (const auto& [left, right] : planner_internal::TileBins(options.frameCount, options.binWidth)) {
    if (planner_internal::AllKept(options, left, right)) continue;  // in the store already
    Bin bin;
    bin.left = left;
    bin.right = right;
    bins_.push_back(bin);
    // Bin ends are traced in full, samples included: their given samples are never used.
    for (int end : {left, right}) {
      if (static_cast<size_t>(end) < coarseSamples_.size()) coarseSamples_[end] = {};
    }
  }
  released_.assign(static_cast<size_t>(options.frameCount), false);
  StartBins();
}

SearchPlanner::~SearchPlanner() = default;

std::vector<TraceTask> SearchPlanner::TakeReadyTasks() { return TakeAll(readyTasks_); }

std::vector<FinishedFrame> SearchPlanner::TakeFinishedFrames() { return TakeAll(finished_); }

bool SearchPlanner::Done() const {
  return nextBin_ == bins_.size() && liveBins_ == 0 && frames_.empty() && finished_.empty();
}

bool SearchPlanner::OnResult(uint64_t taskId, const float* rgb, size_t floatCount, const int32_t* /*horizons*/,
                             size_t /*horizonCount*/) {
  auto found = pendingTasks_.find(taskId);
  if (found == pendingTasks_.end()) {
    if (taskId != 0 && taskId < nextTaskId_) return false;  // completed before: a re-delivery
    throw std::invalid_argument("result for unknown task id " + std::to_string(taskId) + "; ids issued are 1 .. " +
                                std::to_string(nextTaskId_ - 1));
  }
  const PendingTask& task = found->second;
  planner_internal::ValidateRgb(taskId, task.frame, task.pixels.size(), rgb, floatCount);
  WriteTraced(FrameAt(task.frame), task.frame, task.pixels, rgb);

  const uint64_t requestId = task.request;
  pendingTasks_.erase(found);
  auto request = requests_.find(requestId);
  Check(request != requests_.end(), "task " + std::to_string(taskId) + " belongs to no open trace request");
  if (--request->second.chunksLeft == 0) {
    std::vector<Continuation> continuations = std::move(request->second.continuations);
    requests_.erase(request);
    for (const Continuation& continuation : continuations) RunContinuation(continuation);
  }
  ReleaseFinishedFrames();
  return true;
}

void SearchPlanner::StartBins() {
  while (liveBins_ < options_.maxLiveBins && nextBin_ < bins_.size()) StartBin(nextBin_++);
}

void SearchPlanner::StartBin(size_t binIndex) {
  Bin& bin = bins_[binIndex];
  ++liveBins_;
  // A bin reads both its end frames until it finishes. The right end is also the next
  // bin's left end: its reader is added now, on the next bin's behalf, so the frame
  // cannot be released in the gap between this bin finishing and the next starting.
  // (A resumed job plans only some bins, so neighbours in bins_ need not share an end.)
  const bool sharesLeft = binIndex > 0 && bins_[binIndex - 1].right == bin.left;
  const bool sharesRight = binIndex + 1 < bins_.size() && bins_[binIndex + 1].left == bin.right;
  if (!sharesLeft) AddReader(bin.left);
  AddReader(bin.right);
  if (sharesRight) AddReader(bin.right);

  std::vector<int> ends = {bin.left};
  if (bin.right != bin.left) ends.push_back(bin.right);  // a one-frame job's bin is [0, 0]
  for (int end : ends) {
    Frame& frame = FrameAt(end);
    if (frame.knownCount == pixelCount_) continue;  // traced for the bin before
    Continuation continuation;
    continuation.bin = binIndex;
    continuation.isPreparation = true;
    ++bin.preparing;
    if (frame.fullTraceRequest != 0) {
      AddContinuation(frame.fullTraceRequest, std::move(continuation));  // the bin before traces it now
    } else {
      frame.fullTraceRequest = RequestTrace(end, PixelSet::Full(pixelCount_), std::move(continuation));
    }
  }
  // The coarse pass: the end frames' full traces hold their samples already. Each inner
  // frame is read (when the bin is indexed) until the search starts.
  if (guard_) {
    for (int frame = bin.left + 1; frame < bin.right; ++frame) PrepareFrame(binIndex, frame, guard_->Samples());
  }
  // Every new bin has a right end frame that no earlier bin traced, so it always waits
  // for at least one trace and never finishes inside StartBin.
  Check(bin.preparing > 0, "bin " + std::to_string(binIndex) + " starts with both end frames traced");
}

void SearchPlanner::PrepareFrame(size_t binIndex, int frame, const PixelSet& pixels) {
  AddReader(frame);
  const size_t index = static_cast<size_t>(frame);
  if (index < coarseSamples_.size() && !coarseSamples_[index].empty()) {
    Check(coarseSamples_[index].size() == 3 * size_t{pixels.size()},
          "frame " + std::to_string(frame) + " has " + std::to_string(coarseSamples_[index].size()) +
              " floats of coarse samples for " + std::to_string(pixels.size()) + " samples");
    WriteTraced(FrameAt(frame), frame, pixels, coarseSamples_[index].data());
    coarseSamples_[index] = {};
    return;
  }
  Continuation continuation;
  continuation.bin = binIndex;
  continuation.isPreparation = true;
  ++bins_[binIndex].preparing;
  RequestTrace(frame, pixels, std::move(continuation));
}

// Every frame of the bin is traced at its ends, and at its coarse samples with a guard.
void SearchPlanner::SearchPreparedBin(size_t binIndex) {
  const Bin& bin = bins_[binIndex];
  if (!guard_) {
    Search(binIndex, searchPixels_, bin.left, bin.right, 1);
    return;
  }
  std::vector<const float*> frameRgb;
  for (int frame = bin.left; frame <= bin.right; ++frame) {
    const Frame& state = frames_.at(frame);
    Check(!state.state.empty(), "frame " + std::to_string(frame) + " has no value when bin " +
                                    std::to_string(binIndex) + " is searched");
    guard_->Samples().ForEach([&](uint32_t sample) {
      if (state.state[sample] != kTraced) {
        Check(false, "coarse sample " + std::to_string(sample) + " of frame " + std::to_string(frame) +
                         " is not traced when bin " + std::to_string(binIndex) + " is searched");
      }
    });
    frameRgb.push_back(state.rgb.data());
  }
  guard_->IndexBin(binIndex, bin.left, frameRgb);
  Search(binIndex, searchPixels_, bin.left, bin.right, 1);
  for (int frame = bin.left + 1; frame < bin.right; ++frame) RemoveReader(frame);
}

void SearchPlanner::FinishBin(size_t binIndex) {
  const Bin& bin = bins_[binIndex];
  // Every frame of the bin has every pixel by now: either released already (it was
  // complete) or complete and waiting for its readers.
  for (int frame = bin.left; frame <= bin.right; ++frame) {
    if (released_[static_cast<size_t>(frame)]) continue;
    CheckEqual(frames_.at(frame).knownCount, uint64_t{pixelCount_}, "known pixels of a frame of a finished bin");
  }
  RemoveReader(bin.left);
  RemoveReader(bin.right);
  if (guard_) guard_->ForgetBin(binIndex);
  --liveBins_;
  // Release before starting the next bin so the live frames never exceed the bound.
  ReleaseFinishedFrames();
  StartBins();
}

void SearchPlanner::RunContinuation(const Continuation& continuation) {
  Bin& bin = bins_[continuation.bin];
  --bin.waiting;
  if (continuation.isPreparation) {
    if (--bin.preparing == 0) SearchPreparedBin(continuation.bin);
  } else {
    Search(continuation.bin, continuation.pixels, continuation.left, continuation.mid, continuation.depth + 1);
    Search(continuation.bin, continuation.pixels, continuation.mid, continuation.right, continuation.depth + 1);
    RemoveReader(continuation.left);
    RemoveReader(continuation.mid);
    RemoveReader(continuation.right);
  }
  if (bin.waiting == 0) FinishBin(continuation.bin);
}

// The paper's Search(S, l, r), up to the point where it must wait for a trace.
void SearchPlanner::Search(size_t bin, const PixelSet& pixels, int left, int right, int depth) {
  if (right - left <= 1 || pixels.empty()) return;
  const Frame& leftFrame = frames_.at(left);
  const Frame& rightFrame = frames_.at(right);
  PixelSetBuilder same, changed;
  if (options_.tolerance == 0) {
    Classify(pixels, leftFrame, rightFrame, BitwiseEqual{}, same, changed);
  } else {
    Classify(pixels, leftFrame, rightFrame, EqualWithin{options_.tolerance}, same, changed);
  }
  PixelSet unchanged = same.Build();
  PixelSet toSearch = changed.Build();
  if (guard_ && !unchanged.empty()) {
    // Equal ends prove nothing where a tile's coarse samples change in between.
    const PixelSet forced = unchanged.Intersection(guard_->PixelsOfChangedTiles(bin, left, right));
    unchanged = unchanged.Difference(forced);
    toSearch = toSearch.Union(forced);
  }
  if (!unchanged.empty()) {
    for (int frame = left + 1; frame < right; ++frame) CopyPixels(leftFrame, FrameAt(frame), frame, unchanged);
  }
  if (toSearch.empty()) return;

  Continuation continuation;
  continuation.bin = bin;
  continuation.left = left;
  continuation.mid = left + (right - left) / 2;  // (l+r)/2 without overflow
  continuation.right = right;
  continuation.depth = depth;
  continuation.pixels = std::move(toSearch);
  AddReader(continuation.left);
  AddReader(continuation.mid);
  AddReader(continuation.right);
  const PixelSet toTrace = continuation.pixels;
  RequestTrace(continuation.mid, toTrace, std::move(continuation));
}

template <typename Equal>
void SearchPlanner::Classify(const PixelSet& pixels, const Frame& left, const Frame& right, Equal equal,
                             PixelSetBuilder& same, PixelSetBuilder& changed) const {
  const float* leftRgb = left.rgb.data();
  const float* rightRgb = right.rgb.data();
  for (const Span& span : pixels.spans()) {
    for (uint32_t index = span.begin; index != span.end; ++index) {
      const size_t offset = size_t{index} * 3;
      (equal(leftRgb + offset, rightRgb + offset) ? same : changed).Add(index);
    }
  }
}

uint64_t SearchPlanner::RequestTrace(int frame, const PixelSet& pixels, Continuation continuation) {
  FrameAt(frame);  // the frame must exist to receive the results
  const uint64_t requestId = nextRequestId_++;
  std::vector<PixelSet> chunks = planner_internal::SplitForWorkers(pixels, options_);
  Check(!chunks.empty(), "empty trace request at frame " + std::to_string(frame));
  const int chain = static_cast<int>(continuation.bin), step = continuation.isPreparation ? 0 : continuation.depth;
  requests_[requestId].chunksLeft = chunks.size();
  AddContinuation(requestId, std::move(continuation));
  for (PixelSet& chunk : chunks) {
    const uint64_t taskId = nextTaskId_++;
    pendingTasks_[taskId] = PendingTask{requestId, frame, chunk};
    readyTasks_.push_back(TraceTask{taskId, frame, std::move(chunk), 0, chain, step});
  }
  return requestId;
}

void SearchPlanner::AddContinuation(uint64_t request, Continuation continuation) {
  ++bins_[continuation.bin].waiting;
  requests_.at(request).continuations.push_back(std::move(continuation));
}

void SearchPlanner::WriteTraced(Frame& frame, int frameIndex, const PixelSet& pixels, const float* rgb) {
  AllocatePixels(frame);
  for (const Span& span : pixels.spans()) {
    MarkKnown(frame, frameIndex, span, kTraced);
    const size_t floats = size_t{span.size()} * 3;
    std::memcpy(frame.rgb.data() + size_t{span.begin} * 3, rgb, floats * sizeof(float));
    rgb += floats;
  }
  frame.tracedCount += pixels.size();
  tracedPixels_ += pixels.size();
  if (frame.knownCount == pixelCount_) frame.fullTraceRequest = 0;
}

void SearchPlanner::CopyPixels(const Frame& source, Frame& destination, int destinationIndex,
                               const PixelSet& pixels) {
  AllocatePixels(destination);
  for (const Span& span : pixels.spans()) {
    MarkKnown(destination, destinationIndex, span, kCopied);
    const size_t offset = size_t{span.begin} * 3;
    std::memcpy(destination.rgb.data() + offset, source.rgb.data() + offset, size_t{span.size()} * 3 * sizeof(float));
  }
  copiedPixels_ += pixels.size();
}

// Each pixel of each frame gets its value exactly once, traced or copied.
void SearchPlanner::MarkKnown(Frame& frame, int frameIndex, Span span, PixelState how) {
  uint8_t* state = frame.state.data();
  for (uint32_t index = span.begin; index != span.end; ++index) {
    if (state[index] != kUnknown) {
      std::ostringstream what;
      what << "pixel " << index << " of frame " << frameIndex << " is given a value twice (state "
           << int{state[index]} << ", then " << int{how} << ")";
      Check(false, what.str());
    }
    state[index] = how;
  }
  frame.knownCount += span.size();
}

SearchPlanner::Frame& SearchPlanner::FrameAt(int frame) {
  auto found = frames_.find(frame);
  if (found != frames_.end()) return found->second;
  Check(!released_[static_cast<size_t>(frame)], "frame " + std::to_string(frame) + " is needed after its release");
  return frames_[frame];
}

// A frame's pixels take memory from its first value on, not from when a bin first names
// it: a job waiting for workers holds no frames.
void SearchPlanner::AllocatePixels(Frame& frame) const {
  if (!frame.state.empty()) return;
  frame.rgb.assign(size_t{pixelCount_} * 3, 0.0f);
  frame.state.assign(pixelCount_, kUnknown);
}

void SearchPlanner::AddReader(int frame) { ++FrameAt(frame).readers; }

void SearchPlanner::RemoveReader(int frame) {
  Frame& state = frames_.at(frame);
  Check(state.readers > 0, "frame " + std::to_string(frame) + " loses a reader it does not have");
  --state.readers;
}

void SearchPlanner::ReleaseFinishedFrames() {
  for (auto it = frames_.begin(); it != frames_.end();) {
    Frame& frame = it->second;
    if (frame.knownCount != pixelCount_ || frame.readers > 0) {
      ++it;
      continue;
    }
    FinishedFrame finished;
    finished.frame = it->first;
    finished.rgb = std::move(frame.rgb);
    finished.traced = std::move(frame.state);
    for (uint8_t& state : finished.traced) state = state == kTraced ? 1 : 0;
    finished.tracedCount = frame.tracedCount;
    finished_.push_back(std::move(finished));
    released_[static_cast<size_t>(it->first)] = true;
    it = frames_.erase(it);
  }
}

}  // namespace tcfarm
