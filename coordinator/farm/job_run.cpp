#include "farm/job_run.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "frame/frame_io.h"
#include "frame/sequence_analysis.h"

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

JobRun::JobRun(const JobRecord& record, const std::filesystem::path& storeRoot,
               const FrameWriterOptions& output, int workers, size_t pendingFrameBytes,
               uint64_t jobMemoryBytes)
    : id_(record.id),
      spec_(record.spec),
      resolved_(ResolveJobStrategy(record.spec, workers)),
      plannerOptions_(PlannerOptionsFor(record.spec, resolved_, jobMemoryBytes)),
      planner_(MakeJobPlanner(resolved_, plannerOptions_, &autoPlanner_)),
      verification_(record.spec.frameSize.width, record.spec.frameSize.height, FrameCountOf(record.spec),
                    VerificationFor(record.spec, record.id, resolved_.strategy)),
      writer_(CreatedDirectory(storeRoot / std::to_string(record.id)), output),
      started_(std::chrono::steady_clock::now()),
      waitingForCoherence_(storeRoot / std::to_string(record.id) / ".pending", pendingFrameBytes) {
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
  const TaskTime time{result.traceSeconds, result.traceCpuSeconds.value_or(0)};
  if (taskId & kVerificationTask) {
    const bool reference = verification_.IsReference(taskId & ~kVerificationTask);
    if (!verification_.OnResult(taskId & ~kVerificationTask, result.rgb.data(), result.rgb.size())) {
      return false;
    }
    verifyTime_ += time;
    if (reference) {
      referenceTime_ += time;
      referencePixels_ += result.rgb.size() / 3;
    }
  } else {
    // Workers speak absolute frames; the planner counts from the job's first frame.
    std::vector<int32_t> horizons(result.horizons);
    for (int32_t& h : horizons) h -= spec_.firstFrame;
    if (!planner_->OnResult(taskId, result.rgb.data(), result.rgb.size(),
                            horizons.empty() ? nullptr : horizons.data(), horizons.size())) {
      return false;
    }
    frameTraceTime_[result.frame - spec_.firstFrame] += time;
    if (!result.horizons.empty()) framesWithHorizons_.insert(result.frame - spec_.firstFrame);
  }
  traceTime_ += time;
  cpuReported_ = cpuReported_ && result.traceCpuSeconds.has_value();
  rays_[0] += result.primaryRays;
  rays_[1] += result.shadowRays;
  rays_[2] += result.reflectionRays;
  rays_[3] += result.refractionRays;
  ++results_;
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
  const uint64_t pixels = static_cast<uint64_t>(spec_.frameSize.width) * spec_.frameSize.height;
  const int absolute = spec_.firstFrame + frame.frame;
  store.RecordFrame(id_, absolute, frame.tracedCount, pixels - frame.tracedCount);
  // Traced in full and plainly (no horizons): what brute force pays for a frame.
  if (frame.tracedCount == pixels && framesWithHorizons_.count(frame.frame) == 0) {
    fullFrameTime_ += frameTraceTime_[frame.frame];
    ++fullFrames_;
  }
  frameTraceTime_.erase(frame.frame);
  framesWithHorizons_.erase(frame.frame);
  verification_.OnFrameFinished(frame.frame, frame.rgb, frame.traced);
  WriteMask("mask", absolute, std::move(frame.traced));
  TrackCoherence(frame.frame, frame.rgb);
  writer_.Write(absolute, Image{spec_.frameSize.width, spec_.frameSize.height, std::move(frame.rgb)});
  ++framesDone_;
}

void JobRun::TrackCoherence(int frame, const std::vector<float>& rgb) {
  Image image{spec_.frameSize.width, spec_.frameSize.height, rgb};
  if (frame != nextCoherenceFrame_) {
    waitingForCoherence_.Put(frame, std::move(image));
    return;
  }
  AddToCoherence(std::move(image));
  while (std::optional<Image> next = waitingForCoherence_.Take(nextCoherenceFrame_)) {
    AddToCoherence(std::move(*next));
  }
}

// The next frame in order: into the coherence analysis, and its change mask against the
// frame before.
void JobRun::AddToCoherence(Image frame) {
  coherence_.Add(frame);
  // The paper's Figure 5: white where the pixel is bitwise the previous frame's, black
  // where it changed; the first frame has nothing to change from, so is all white.
  const std::vector<float>& current = frame.rgb;
  std::vector<uint8_t> unchanged(frame.PixelCount(), 1);
  if (previousRgb_.size() == current.size()) {
    for (size_t pixel = 0; pixel < unchanged.size(); ++pixel) {
      unchanged[pixel] = std::memcmp(&current[pixel * 3], &previousRgb_[pixel * 3], 3 * sizeof(float)) == 0;
    }
  }
  WriteMask("change", spec_.firstFrame + nextCoherenceFrame_, std::move(unchanged));
  previousRgb_ = std::move(frame.rgb);
  ++nextCoherenceFrame_;
}

void JobRun::WriteMask(const char* kind, int absoluteFrame, std::vector<uint8_t> mask) {
  writer_.WriteMask(MaskFileStem(kind, absoluteFrame) + ".png", spec_.frameSize.width,
                    spec_.frameSize.height, std::move(mask));
}

void JobRun::FinishWriting() { writer_.Finish(); }

int JobRun::BinWidth() const {
  return autoPlanner_ ? autoPlanner_->ChosenBinWidth() : resolved_.binWidth;
}

// Predicted (equation 3, or its exact analogue) beside measured relative cost. Measured
// is the job's tracing time over brute force's, estimated from its reference frames when
// it has any (brute force itself), else from the frames it traced plainly in full (bin
// ends), which cost what brute force pays per frame.
nlohmann::json JobRun::CostFigures() const {
  nlohmann::json cost;
  const int frames = FrameCountOf(spec_);
  if (coherence_.frameToFrame().count > 0) {
    double d = 1 - coherence_.frameToFrame().Mean();
    double predicted = 1;
    if (resolved_.strategy == Strategy::kExact) {
      double segments = std::ceil(double(frames) / BinWidth());
      predicted = (segments + (frames - segments) * d) / frames;
    } else if (resolved_.strategy != Strategy::kBrute && BinWidth() >= 2) {
      predicted = Equation3RelativeCost(frames, BinWidth(), d);
    }
    cost["d"] = d;
    cost["predicted_relative_cost"] = predicted;
  }
  // Brute force's tracing time, from reference frames (brute force itself) where the job
  // has them, else from its own frames traced plainly in full.
  TaskTime brute;
  if (referencePixels_ > 0) {
    const double scale = double(spec_.frameSize.width) * spec_.frameSize.height * frames / double(referencePixels_);
    brute = {referenceTime_.wall * scale, referenceTime_.cpu * scale};
    cost["brute_estimate_from"] = "reference frames";
  } else if (fullFrames_ > 0) {
    brute = {fullFrameTime_.wall / fullFrames_ * frames, fullFrameTime_.cpu / fullFrames_ * frames};
    cost["brute_estimate_from"] = "frames traced in full";
  }
  const TaskTime job = traceTime_ - verifyTime_;
  if (brute.wall > 0) {
    cost["brute_trace_seconds_estimate"] = brute.wall;
    cost["measured_relative_cost_wall"] = job.wall / brute.wall;
    cost["measured_relative_cost"] = job.wall / brute.wall;
    cost["measured_relative_cost_basis"] = "trace seconds";
  }
  // CPU time where every worker reported it: it does not count waiting for shared cores.
  if (cpuReported_ && brute.cpu > 0) {
    cost["brute_trace_cpu_seconds_estimate"] = brute.cpu;
    cost["measured_relative_cost"] = job.cpu / brute.cpu;
    cost["measured_relative_cost_basis"] = "trace cpu seconds";
  }
  return cost;
}

nlohmann::json JobRun::Stats(bool final) const {
  const uint64_t pixelsPerFrame = static_cast<uint64_t>(spec_.frameSize.width) * spec_.frameSize.height;
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
  stats["frames_waited_on_disk"] = waitingForCoherence_.TotalSpilled();
  stats["pixels_traced"] = planner_->TracedPixels();
  stats["pixels_copied"] = planner_->CopiedPixels();
  stats["traced_pixel_ratio"] = static_cast<double>(planner_->TracedPixels()) /
                                static_cast<double>(pixelsPerFrame * FrameCountOf(spec_));
  stats["wall_seconds"] = wall;
  stats["trace_seconds"] = traceTime_.wall - verifyTime_.wall;
  stats["verify_trace_seconds"] = verifyTime_.wall;
  if (cpuReported_ && results_ > 0) {
    stats["trace_cpu_seconds"] = traceTime_.cpu - verifyTime_.cpu;
    stats["verify_trace_cpu_seconds"] = verifyTime_.cpu;
  }
  stats["tasks"] = results_;
  stats["rays"] = {{"primary", rays_[0]}, {"shadow", rays_[1]}, {"reflection", rays_[2]},
                   {"refraction", rays_[3]}};
  stats["cost"] = CostFigures();
  stats["error"] = verification_.Report();
  const RunningStats& f2f = coherence_.frameToFrame();
  const RunningStats& longTerm = coherence_.longTerm();
  if (f2f.count > 0) {
    stats["coherence"] = {
        {"frame_to_frame", {{"mean", f2f.Mean()}, {"min", f2f.min}, {"max", f2f.max}}},
        {"long_term", {{"mean", longTerm.Mean()}, {"min", longTerm.min}, {"max", longTerm.max}}}};
  }
  if (final && coherence_.FrameCount() > 0) stats["analysis"] = coherence_.Finish().ToJson();
  return stats;
}

JobRun::PixelTally JobRun::TakeUnreportedPixels() {
  const PixelTally now{tracedPixels(), copiedPixels()};
  const PixelTally unreported{now.traced - reported_.traced, now.copied - reported_.copied};
  reported_ = now;
  return unreported;
}

}  // namespace tcfarm
