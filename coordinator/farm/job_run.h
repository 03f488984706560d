// One job being rendered: its planner, its frame writer, and the figures it reports.
// Owned by the farm loop; not thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "dispatch/dispatcher.h"
#include "frame/coherence.h"
#include "frame/frame_writer.h"
#include "jobs/job_store.h"
#include "planner/search_planner.h"
#include "scene/scene.h"

namespace tcfarm {

// Planner settings of a job: `brute` is the search with bins of 2 (every frame traced).
PlannerOptions PlannerOptionsFor(const JobSpec& spec, const Scene& scene);

class JobRun {
 public:
  // Throws SceneError when the stored scene no longer parses, std::invalid_argument for
  // planner options out of range.
  JobRun(const JobRecord& record, const std::filesystem::path& storeRoot,
         const FrameWriterOptions& output = {});

  uint64_t id() const { return id_; }
  const Scene& scene() const { return *scene_; }
  const std::filesystem::path& directory() const { return directory_; }

  std::vector<DispatchTask> TakeTasks();
  // Feeds a result to the planner. Returns false when the planner had it already.
  bool OnResult(uint64_t plannerTaskId, const wire::Result& result);
  // Hands finished frames to the writer and records them; returns how many.
  int CollectFinishedFrames(JobStore& store);
  bool Done() const { return planner_.Done(); }
  // Waits for the frame writer; throws FrameIoError if a frame could not be written.
  void FinishWriting();

  // Progress and results so far, for the job record ("stats").
  nlohmann::json Stats() const;
  uint64_t tracedPixels() const { return planner_.TracedPixels(); }
  uint64_t copiedPixels() const { return planner_.CopiedPixels(); }

 private:
  void TrackCoherence(int frame, const std::vector<float>& rgb);

  uint64_t id_;
  JobSpec spec_;
  std::unique_ptr<Scene> scene_;
  std::filesystem::path directory_;
  SearchPlanner planner_;
  FrameWriter writer_;
  std::chrono::steady_clock::time_point started_;
  double traceSeconds_ = 0;  // summed over tasks: the tracing time the job cost the farm
  uint64_t rays_[4] = {};    // primary, shadow, reflection, refraction
  uint64_t results_ = 0;
  int framesDone_ = 0;
  // Coherence needs frames in order; they finish nearly in order, so few wait here.
  CoherenceTracker coherence_;
  int nextCoherenceFrame_ = 0;
  std::map<int, Image> waitingForCoherence_;
};

}  // namespace tcfarm
