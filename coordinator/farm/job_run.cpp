#include "farm/job_run.h"

#include <stdexcept>

namespace tcfarm {

PlannerOptions PlannerOptionsFor(const JobSpec& spec, const Scene& scene) {
  PlannerOptions options;
  options.width = scene.render.width;
  options.height = scene.render.height;
  options.frameCount = spec.lastFrame - spec.firstFrame + 1;
  options.binWidth = spec.strategy == "brute" ? 2 : spec.binWidth;
  options.tolerance = static_cast<float>(spec.tolerance);
  return options;
}

namespace {

std::unique_ptr<Scene> ParseStoredScene(const JobSpec& spec) {
  return std::make_unique<Scene>(ParseScene(spec.sceneJson));
}

const std::filesystem::path& CreatedDirectory(const std::filesystem::path& path) {
  std::filesystem::create_directories(path);
  return path;
}

}  // namespace

JobRun::JobRun(const JobRecord& record, const std::filesystem::path& storeRoot,
               const FrameWriterOptions& output)
    : id_(record.id),
      spec_(record.spec),
      scene_(ParseStoredScene(record.spec)),
      directory_(storeRoot / std::to_string(record.id)),
      planner_(PlannerOptionsFor(record.spec, *scene_)),
      writer_(CreatedDirectory(directory_), output),
      started_(std::chrono::steady_clock::now()) {
  spec_.sceneJson.clear();  // parsed; no need to hold the text twice
}

std::vector<DispatchTask> JobRun::TakeTasks() {
  std::vector<DispatchTask> tasks;
  for (TraceTask& t : planner_.TakeReadyTasks()) {
    tasks.push_back({id_, t.id, spec_.firstFrame + t.frame, std::move(t.pixels), 0});
  }
  return tasks;
}

bool JobRun::OnResult(uint64_t plannerTaskId, const wire::Result& result) {
  if (!planner_.OnResult(plannerTaskId, result.rgb.data(), result.rgb.size())) return false;
  traceSeconds_ += result.traceSeconds;
  rays_[0] += result.primaryRays;
  rays_[1] += result.shadowRays;
  rays_[2] += result.reflectionRays;
  rays_[3] += result.refractionRays;
  ++results_;
  return true;
}

int JobRun::CollectFinishedFrames(JobStore& store) {
  std::vector<FinishedFrame> finished = planner_.TakeFinishedFrames();
  for (FinishedFrame& frame : finished) {
    int absolute = spec_.firstFrame + frame.frame;
    uint64_t pixels = frame.traced.size();
    store.RecordFrame(id_, absolute, frame.tracedCount, pixels - frame.tracedCount);
    TrackCoherence(frame.frame, frame.rgb);
    writer_.Write(absolute, Image{scene_->render.width, scene_->render.height, std::move(frame.rgb)});
    ++framesDone_;
  }
  return static_cast<int>(finished.size());
}

void JobRun::TrackCoherence(int frame, const std::vector<float>& rgb) {
  waitingForCoherence_.emplace(frame, Image{scene_->render.width, scene_->render.height, rgb});
  for (auto next = waitingForCoherence_.find(nextCoherenceFrame_);
       next != waitingForCoherence_.end(); next = waitingForCoherence_.find(nextCoherenceFrame_)) {
    coherence_.Add(next->second);
    waitingForCoherence_.erase(next);
    ++nextCoherenceFrame_;
  }
}

void JobRun::FinishWriting() { writer_.Finish(); }

nlohmann::json JobRun::Stats() const {
  const uint64_t pixelsPerFrame = static_cast<uint64_t>(scene_->render.width) * scene_->render.height;
  const uint64_t frames = static_cast<uint64_t>(spec_.lastFrame - spec_.firstFrame + 1);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  nlohmann::json stats;
  stats["frames_done"] = framesDone_;
  stats["pixels_traced"] = planner_.TracedPixels();
  stats["pixels_copied"] = planner_.CopiedPixels();
  stats["traced_pixel_ratio"] =
      static_cast<double>(planner_.TracedPixels()) / static_cast<double>(pixelsPerFrame * frames);
  stats["wall_seconds"] = wall;
  stats["trace_seconds"] = traceSeconds_;
  stats["tasks"] = results_;
  stats["rays"] = {{"primary", rays_[0]}, {"shadow", rays_[1]}, {"reflection", rays_[2]},
                   {"refraction", rays_[3]}};
  const RunningStats& f2f = coherence_.frameToFrame();
  const RunningStats& longTerm = coherence_.longTerm();
  if (f2f.count > 0) {
    stats["coherence"] = {
        {"frame_to_frame", {{"mean", f2f.Mean()}, {"min", f2f.min}, {"max", f2f.max}}},
        {"long_term", {{"mean", longTerm.Mean()}, {"min", longTerm.min}, {"max", longTerm.max}}}};
  }
  return stats;
}

}  // namespace tcfarm
