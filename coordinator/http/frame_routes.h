// The HTTP API's frames: a job's frame states, and its frames and masks as files.
//   GET /api/v1/jobs/{id}/frames                          each frame's state
//   GET /api/v1/jobs/{id}/frames/{n}.png | {n}.exr        the frame (PNG made on demand)
//   GET /api/v1/jobs/{id}/frames/{n}/mask.png|change.png  traced pixels / unchanged pixels
#pragma once

#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "coordinator/farm/farm_control.h"
#include "coordinator/http/api_route.h"
#include "coordinator/jobs/job_store.h"
#include "coordinator/store/frame_store.h"
#include "proto/frame/view_transform.h"

namespace tcfarm::http {

// A job's frames, which never change once it is submitted: cached per job, so that serving
// a frame does not load the job's scene and per-frame counts each time. The jobs' routes
// fill it at submit and empty it at delete. Thread-safe.
class FrameRanges {
 public:
  struct Range {
    int firstFrame = 0;
    int lastFrame = 0;
    ViewTransform previewView;  // how a preview made on request shows the frames
  };

  explicit FrameRanges(JobStore& store) : store_(store) {}

  Range Of(uint64_t id);  // loads the job the first time; throws ApiError 404 job_not_found
  void Remember(uint64_t id, Range range);
  void Forget(uint64_t id);

 private:
  JobStore& store_;
  std::mutex mutex_;
  std::unordered_map<uint64_t, Range> ranges_;
};

class FrameRoutes {
 public:
  // storeRoot: where the frame store holds each job's files (storeRoot/<job id>/).
  FrameRoutes(JobStore& store, FarmControl& farm, FrameRanges& ranges, const std::filesystem::path& storeRoot);

  std::vector<Route> Routes();

 private:
  void GetFrameStates(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetFrame(const httplib::Request& request, const std::string& body, httplib::Response& response);
  void GetFrameMask(const httplib::Request& request, const std::string& body, httplib::Response& response);
  // Throws 400 invalid_parameter when frame is outside job id's frames.
  void CheckFrameInJob(uint64_t id, int frame);

  JobStore& store_;
  FarmControl& farm_;
  FrameRanges& ranges_;
  FrameStore frameStore_;
};

}  // namespace tcfarm::http
