#include "coordinator/http/frame_routes.h"

#include <httplib.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <utility>

#include "coordinator/http/query_params.h"
#include "coordinator/store/frame_finisher.h"
#include "proto/frame/frame_io.h"

namespace tcfarm::http {
namespace {

using nlohmann::json;

constexpr size_t kFileChunkBytes = 64u << 10;
constexpr size_t kMaxFrameDigits = 9;  // scene frames stay below 10^7 + 10^5

struct FrameFile {
  int frame = 0;
  std::string extension;   // "png" or "exr"
  const char* contentType;
};

// "42.png" -> frame 42, png.
FrameFile ParseFrameFile(const std::string& text) {
  const std::string expected = "expected <frame number>.png or <frame number>.exr";
  const size_t dot = text.rfind('.');
  const std::string number = text.substr(0, dot);
  const std::string extension = dot == std::string::npos ? "" : text.substr(dot + 1);
  if (!AllDigits(number) || number.size() > kMaxFrameDigits) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "frame file " + ShowValue(text) + " has no frame number; " + expected);
  }
  if (extension == "png") return FrameFile{std::stoi(number), extension, "image/png"};
  if (extension == "exr") return FrameFile{std::stoi(number), extension, "image/x-exr"};
  throw ApiError(400, error_code::kInvalidParameter,
                 "frame file " + ShowValue(text) + " has an unknown extension; " + expected);
}

// Streams the file so a 16K float EXR never has to sit in memory whole. The stream stays
// open for the response's lifetime: a frame renamed over it meanwhile is not mixed in.
bool ServeFile(httplib::Response& response, const std::filesystem::path& path, const char* contentType) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) return false;
  const uintmax_t size = std::filesystem::file_size(path, error);
  auto file = std::make_shared<std::ifstream>(path, std::ios::binary);
  if (error || !*file) return false;
  response.set_content_provider(
      static_cast<size_t>(size), contentType,
      [file](size_t offset, size_t length, httplib::DataSink& sink) {
        std::vector<char> buffer(std::min(length, kFileChunkBytes));
        file->seekg(static_cast<std::streamoff>(offset));
        file->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        const std::streamsize got = file->gcount();
        return got > 0 && sink.write(buffer.data(), static_cast<size_t>(got));
      });
  return true;
}

}  // namespace

FrameRanges::Range FrameRanges::Of(uint64_t id) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto cached = ranges_.find(id);
    if (cached != ranges_.end()) return cached->second;
  }
  const JobRecord record = LoadJob(store_, id);
  const Range range{record.spec.firstFrame, record.spec.lastFrame, JobPreviewView(record.spec)};
  std::lock_guard<std::mutex> lock(mutex_);
  ranges_.emplace(id, range);
  return range;
}

void FrameRanges::Remember(uint64_t id, Range range) {
  std::lock_guard<std::mutex> lock(mutex_);
  ranges_[id] = range;
}

void FrameRanges::Forget(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  ranges_.erase(id);
}

FrameRoutes::FrameRoutes(JobStore& store, FarmControl& farm, FrameRanges& ranges,
                         const std::filesystem::path& storeRoot)
    : store_(store), farm_(farm), ranges_(ranges), frameStore_(storeRoot) {}

std::vector<Route> FrameRoutes::Routes() {
  return {
      {"GET", "/api/v1/jobs/([^/]+)/frames", Access::kRead, Bind(this, &FrameRoutes::GetFrameStates)},
      {"GET", "/api/v1/jobs/([^/]+)/frames/([^/]+)", Access::kRead, Bind(this, &FrameRoutes::GetFrame)},
      {"GET", "/api/v1/jobs/([^/]+)/frames/([^/]+)/(mask|change)\\.png", Access::kRead,
       Bind(this, &FrameRoutes::GetFrameMask)},
  };
}

// queued, tracing (the farm is working on it), written (in the store, recorded), failed
// (a failed job's frame that was not written). A canceled job's unwritten frames are queued:
// a retry would render them.
void FrameRoutes::GetFrameStates(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const FrameRanges::Range range = ranges_.Of(id);
  const JobState state = RequireJob(store_, id);
  const std::vector<RecordedFrame> written = store_.RecordedFrames(id);
  std::vector<int> tracing;
  if (state == JobState::kRunning) {
    FarmSnapshot snapshot = farm_.Snapshot();
    if (auto live = snapshot.tracingFrames.find(id); live != snapshot.tracingFrames.end()) tracing = std::move(live->second);
  }
  json frames = json::array();
  std::map<std::string, int> counts{{"queued", 0}, {"tracing", 0}, {"written", 0}, {"failed", 0}};
  auto nextWritten = written.begin();
  auto nextTracing = tracing.begin();
  for (int frame = range.firstFrame; frame <= range.lastFrame; ++frame) {
    while (nextWritten != written.end() && nextWritten->frame < frame) ++nextWritten;
    while (nextTracing != tracing.end() && *nextTracing < frame) ++nextTracing;
    json entry{{"frame", frame}, {"traced", nullptr}, {"copied", nullptr}};
    std::string frameState = "queued";
    if (nextWritten != written.end() && nextWritten->frame == frame) {
      frameState = "written";
      entry["traced"] = nextWritten->traced;
      entry["copied"] = nextWritten->copied;
    } else if (nextTracing != tracing.end() && *nextTracing == frame) {
      frameState = "tracing";
    } else if (state == JobState::kFailed) {
      frameState = "failed";
    }
    entry["state"] = frameState;
    ++counts[frameState];
    frames.push_back(std::move(entry));
  }
  WriteJson(response, json{{"job", id}, {"state", ToString(state)}, {"frames", std::move(frames)}, {"counts", counts}});
}

void FrameRoutes::CheckFrameInJob(uint64_t id, int frame) {
  const FrameRanges::Range range = ranges_.Of(id);
  if (frame < range.firstFrame || frame > range.lastFrame) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "frame " + std::to_string(frame) + " is outside job " + std::to_string(id) +
                       "'s frames [" + std::to_string(range.firstFrame) + ", " +
                       std::to_string(range.lastFrame) + "]");
  }
}

void FrameRoutes::GetFrame(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const FrameFile file = ParseFrameFile(request.matches[2]);
  CheckFrameInJob(id, file.frame);
  const std::filesystem::path path = frameStore_.FramePath(id, file.frame, file.extension);
  // A frame's preview is made once its job is done and the farm idle (FrameFinisher);
  // asked for before, it is made now from the frame's EXR.
  std::error_code missing;
  if (file.extension == "png" && !std::filesystem::is_regular_file(path, missing)) {
    std::optional<std::string> preview;
    try {
      preview = EncodePreview(frameStore_, id, file.frame, ranges_.Of(id).previewView);
    } catch (const FrameIoError& e) {
      throw ApiError(500, error_code::kInternal,
                     "the preview of frame " + std::to_string(file.frame) + " of job " + std::to_string(id) +
                         " could not be made: " + e.what());
    }
    if (preview) {
      response.set_content(std::move(*preview), file.contentType);
      return;
    }
  }
  if (!ServeFile(response, path, file.contentType)) {
    RequireJob(store_, id);  // deleted meanwhile (by the retention: the frame range was cached)
    throw ApiError(404, error_code::kFrameNotReady,
                   "frame " + std::to_string(file.frame) + " of job " + std::to_string(id) +
                       " is not written yet");
  }
}

// frames/<n>/mask.png: the pixels traced at frame n (white) and copied (black);
// frames/<n>/change.png: the pixels equal to frame n - 1's (white) and changed (black).
void FrameRoutes::GetFrameMask(const httplib::Request& request, const std::string&, httplib::Response& response) {
  const uint64_t id = ParseJobId(request.matches[1]);
  const std::string number = request.matches[2];
  const std::string kind = request.matches[3];
  if (!AllDigits(number) || number.size() > kMaxFrameDigits) {
    throw ApiError(400, error_code::kInvalidParameter,
                   "frame " + ShowValue(number) + " is not a frame number; expected <frame number>/" + kind +
                       ".png");
  }
  const int frame = std::stoi(number);
  CheckFrameInJob(id, frame);
  // The route's pattern admits only the two names.
  const std::filesystem::path path = frameStore_.MaskPath(id, MaskKindFromName(kind).value(), frame);
  if (!ServeFile(response, path, "image/png")) {
    RequireJob(store_, id);
    throw ApiError(404, error_code::kFrameNotReady,
                   std::string(kind == "mask" ? "the traced-pixel" : "the change") + " mask of frame " +
                       std::to_string(frame) + " of job " +
                       std::to_string(id) + " is not written yet");
  }
}

}  // namespace tcfarm::http
