#include "farm/job_run.h"

#include <stdexcept>

#include "scene/scene.h"

namespace tcfarm {
namespace {

const std::filesystem::path& CreatedDirectory(const std::filesystem::path& path) {
  std::filesystem::create_directories(path);
  return path;
}

int FrameCountOf(const JobSpec& spec) { return spec.lastFrame - spec.firstFrame + 1; }

VerificationOptions VerificationFor(const JobSpec& spec, uint64_t jobId, Strategy strategy) {
  VerificationOptions options;
  options.seed = jobId;
  const nlohmann::json& verify = spec.options.is_object() && spec.options.contains("verify")
                                     ? spec.options["verify"]
                                     : nlohmann::json();
  if (verify.is_object()) {
    bool all = verify.value("frames", std::string()) == "all";
    int sample = verify.value("sample", 0);
    options.referenceFrames = FramesToVerify(FrameCountOf(spec), all, sample);
  }
  if (spec.options.is_object() && spec.options.contains("spot_check_share")) {
    options.spotCheckShare = spec.options["spot_check_share"].get<double>();
  }
  // exact traces no frame plainly in full (segment starts carry horizons, which cost
  // more than the frame), so nothing of its own prices brute force. One brute-force
  // frame does, and the last one is the most copied into: compared bit for bit, it also
  // checks the horizons on the job's own animation.
  if (strategy == Strategy::kExact && options.referenceFrames.empty()) {
    options.referenceFrames = {FrameCountOf(spec) - 1};
  }
  return options;
}

std::unique_ptr<Planner> MakeJobPlanner(const ResolvedStrategy& resolved, const PlannerOptions& options,
                                        AutoGuardedPlanner** surveying) {
  if (!resolved.surveyBinWidth) return MakePlanner(resolved.strategy, options);
  auto planner = std::make_unique<AutoGuardedPlanner>(options);
  *surveying = planner.get();
  return planner;
}

// Only auto asks, and only jobs stored before the store kept the answer lack it.
bool CameraOrLightsChange(const JobSpec& spec) {
  if (spec.cameraOrLightsChange || spec.strategy != Strategy::kAuto) {
    return spec.cameraOrLightsChange.value_or(true);
  }
  const Scene scene = ParseScene(spec.sceneJson);
  return scene.CameraMoves() || scene.AnyLightChanges();
}

}  // namespace

ResolvedStrategy ResolveJobStrategy(const JobSpec& spec, int workers) {
  return ResolveStrategy(spec.strategy, spec.binWidth, FrameCountOf(spec), CameraOrLightsChange(spec), workers);
}

PlannerOptions PlannerOptionsFor(const JobSpec& spec, const ResolvedStrategy& resolved,
                                 uint64_t jobMemoryBytes) {
  PlannerOptions options;
  options.width = spec.frameSize.width;
  options.height = spec.frameSize.height;
  options.frameCount = FrameCountOf(spec);
  options.binWidth = resolved.binWidth;
  options.tolerance = static_cast<float>(spec.tolerance);
  if (jobMemoryBytes > 0) {
    options.maxLiveBins = LiveBinsWithin(jobMemoryBytes, options.width, options.height, resolved.strategy,
                                         resolved.binWidth, options.maxLiveBins, options.frameCount);
    if (options.maxLiveBins == 0) {
      throw std::invalid_argument(MemoryShortfall(jobMemoryBytes, options.width, options.height,
                                                  resolved.strategy, resolved.binWidth, options.frameCount));
    }
  }
  return options;
}

JobRun::JobRun(const JobRecord& record, const FrameStore& store, const FrameWriterOptions& output, int workers,
               size_t pendingFrameBytes, uint64_t jobMemoryBytes)
    : id_(record.id),
      spec_(record.spec),
      resolved_(ResolveJobStrategy(record.spec, workers)),
      plannerOptions_(PlannerOptionsFor(record.spec, resolved_, jobMemoryBytes)),
      planner_(MakeJobPlanner(resolved_, plannerOptions_, &autoPlanner_)),
      verification_(spec_.frameSize.width, spec_.frameSize.height, FrameCountOf(spec_),
                    VerificationFor(spec_, record.id, resolved_.strategy)),
      writer_(CreatedDirectory(store.JobFolder(record.id)), output),
      coherence_(spec_.frameSize.width, spec_.frameSize.height, store.SpillFolder(record.id), pendingFrameBytes),
      cost_(PixelsPerFrame(), FrameCountOf(spec_)),
      started_(std::chrono::steady_clock::now()) {
  spec_.sceneJson.clear();  // the dispatcher holds it for the workers
}

std::vector<DispatchTask> JobRun::TakeTasks() {
  std::vector<DispatchTask> tasks;
  // While the writer is behind, the planner's tasks wait: tracing more would only pile up
  // frames in memory.
  const bool writerBehind = unwritten_.size() >= kMaxUnwrittenFrames;
  for (TraceTask& t : writerBehind ? std::vector<TraceTask>{} : planner_->TakeReadyTasks()) {
    tasks.push_back({id_, t.id, spec_.firstFrame + t.frame, std::move(t.pixels), t.window});
  }
  for (Verification::Request& r : verification_.TakeRequests()) {
    tasks.push_back({id_, r.id | kVerificationTask, spec_.firstFrame + r.frame,
                     std::move(r.pixels), 0});
  }
  return tasks;
}

bool JobRun::OnResult(uint64_t taskId, const wire::Result& result) {
  return (taskId & kVerificationTask) ? OnVerificationResult(taskId & ~kVerificationTask, result)
                                      : OnPlannerResult(taskId, result);
}

bool JobRun::OnVerificationResult(uint64_t taskId, const wire::Result& result) {
  const bool reference = verification_.IsReference(taskId);
  if (!verification_.OnResult(taskId, result.rgb.data(), result.rgb.size())) return false;
  cost_.OnVerificationResult(result, reference);
  return true;
}

bool JobRun::OnPlannerResult(uint64_t taskId, const wire::Result& result) {
  // Workers speak absolute frames; the planner counts from the job's first frame.
  std::vector<int32_t> horizons(result.horizons);
  for (int32_t& h : horizons) h -= spec_.firstFrame;
  if (!planner_->OnResult(taskId, result.rgb.data(), result.rgb.size(),
                          horizons.empty() ? nullptr : horizons.data(), horizons.size())) {
    return false;
  }
  cost_.OnPlannerResult(result.frame - spec_.firstFrame, result);
  return true;
}

int JobRun::CollectFinishedFrames(JobStore& store) {
  for (FinishedFrame& frame : planner_->TakeFinishedFrames()) unwritten_.push_back(std::move(frame));
  // Only as much as the writer takes at once and a short turn allows: the farm loop must
  // come back to its socket (results, heartbeats) while large frames are encoded.
  const auto turnEnds = std::chrono::steady_clock::now() + kFinishingTurn;
  int collected = 0;
  while (!unwritten_.empty() && writer_.HasRoom() && std::chrono::steady_clock::now() < turnEnds) {
    FinishFrame(store, std::move(unwritten_.front()));
    unwritten_.pop_front();
    ++collected;
  }
  return collected;
}

void JobRun::FinishFrame(JobStore& store, FinishedFrame frame) {
  const int absolute = spec_.firstFrame + frame.frame;
  store.RecordFrame(id_, absolute, frame.tracedCount, PixelsPerFrame() - frame.tracedCount);
  cost_.OnFrameFinished(frame.frame, frame.tracedCount);
  verification_.OnFrameFinished(frame.frame, frame.rgb, frame.traced);
  WriteMask(MaskKind::kTraced, absolute, std::move(frame.traced));
  for (JobCoherence::ChangeMask& mask : coherence_.Add(frame.frame, frame.rgb)) {
    WriteMask(MaskKind::kChange, spec_.firstFrame + mask.frame, std::move(mask.unchanged));
  }
  writer_.Write(absolute, Image{spec_.frameSize.width, spec_.frameSize.height, std::move(frame.rgb)});
  ++framesDone_;
}

void JobRun::WriteMask(MaskKind kind, int absoluteFrame, std::vector<uint8_t> mask) {
  writer_.WriteMask(FrameStore::MaskFileName(kind, absoluteFrame), spec_.frameSize.width, spec_.frameSize.height,
                    std::move(mask));
}

void JobRun::FinishWriting() { writer_.Finish(); }

int JobRun::BinWidth() const {
  return autoPlanner_ ? autoPlanner_->ChosenBinWidth() : resolved_.binWidth;
}

nlohmann::json JobRun::Stats(bool final) const {
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  nlohmann::json stats;
  stats["strategy"] = {{"name", std::string(StrategyName(resolved_.strategy))},
                       {"bin_width", BinWidth()},
                       {"reason", resolved_.reason}};
  if (autoPlanner_ && autoPlanner_->ChosenBinWidth() > 0) {
    nlohmann::json survey = {{"frames", autoPlanner_->SurveyedFrames()}, {"predicted_traced_share", {}}};
    for (const auto& [width, share] : autoPlanner_->Predictions()) {
      survey["predicted_traced_share"][std::to_string(width)] = share;
    }
    stats["strategy"]["survey"] = survey;
  }
  stats["frames_done"] = framesDone_;
  // Bins (segments) worked on at once: fewer than 4 when the coordinator's memory for the
  // job would not hold their frames.
  stats["live_bins"] = plannerOptions_.maxLiveBins;
  // Frames that finished ahead of their turn and waited on disk, not in memory.
  stats["frames_waited_on_disk"] = coherence_.FramesWaitedOnDisk();
  stats["pixels_traced"] = planner_->TracedPixels();
  stats["pixels_copied"] = planner_->CopiedPixels();
  stats["traced_pixel_ratio"] = static_cast<double>(planner_->TracedPixels()) /
                                static_cast<double>(PixelsPerFrame() * FrameCountOf(spec_));
  stats["wall_seconds"] = wall;
  const SequenceAnalyzer& coherence = coherence_.analysis();
  cost_.AddTo(stats, resolved_.strategy, BinWidth(), coherence.frameToFrame());
  stats["error"] = verification_.Report();
  const RunningStats& f2f = coherence.frameToFrame();
  const RunningStats& longTerm = coherence.longTerm();
  if (f2f.count > 0) {
    stats["coherence"] = {
        {"frame_to_frame", {{"mean", f2f.Mean()}, {"min", f2f.min}, {"max", f2f.max}}},
        {"long_term", {{"mean", longTerm.Mean()}, {"min", longTerm.min}, {"max", longTerm.max}}}};
  }
  if (final && coherence.FrameCount() > 0) stats["analysis"] = coherence.Finish().ToJson();
  return stats;
}

JobRun::PixelTally JobRun::TakeUnreportedPixels() {
  const PixelTally now{tracedPixels(), copiedPixels()};
  const PixelTally unreported{now.traced - reported_.traced, now.copied - reported_.copied};
  reported_ = now;
  return unreported;
}

}  // namespace tcfarm
