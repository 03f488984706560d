#include "coordinator/store/frame_finisher.h"

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

constexpr const char* kFinishedMarker = ".finished";
// Compression of the frames a job writes while it renders: none, the fastest lossless.
constexpr const char* kRenderingCompression = "none";
// Where a job's options keep its preview's view (JobPreviewView).
constexpr const char* kViewOption = "view";
constexpr const char* kExposureOption = "exposure";

}  // namespace

FrameWriterOptions WhileRendering(const FrameWriterOptions& stored) {
  FrameWriterOptions rendering = stored;
  if (!stored.writeExr) return rendering;
  rendering.exrCompression = kRenderingCompression;
  rendering.writePng = false;
  return rendering;
}

ViewTransform JobPreviewView(const JobSpec& spec) {
  ViewTransform view;
  const nlohmann::json& options = spec.options;
  if (!options.is_object()) return view;
  if (const auto name = options.find(kViewOption); name != options.end() && name->is_string()) {
    view.view = ParseView(name->get<std::string>()).value_or(View::kStandard);
  }
  if (const auto exposure = options.find(kExposureOption); exposure != options.end() && exposure->is_number()) {
    view.exposure = exposure->get<double>();
  }
  return view;
}

void SetJobPreviewView(JobSpec& spec, const ViewTransform& view) {
  if (!spec.options.is_object()) spec.options = nlohmann::json::object();
  spec.options.erase(kViewOption);
  spec.options.erase(kExposureOption);
  if (view.view != View::kStandard) spec.options[kViewOption] = std::string(ViewName(view.view));
  if (view.exposure != 0) spec.options[kExposureOption] = view.exposure;
}

std::optional<std::string> EncodePreview(const FrameStore& store, uint64_t job, int frame, const ViewTransform& view) {
  const std::filesystem::path exr = store.FramePath(job, frame, "exr");
  std::error_code missing;
  if (!std::filesystem::is_regular_file(exr, missing)) return std::nullopt;
  std::string png = EncodePng(ReadImage(exr), view);
  const std::filesystem::path path = store.FramePath(job, frame, "png");
  const std::filesystem::path partial = PartialPathFor(path);
  // Kept when the disk takes it; served from memory all the same when it does not.
  std::error_code ignored;
  if (std::ofstream out{partial, std::ios::binary}; out.write(png.data(), std::streamsize(png.size())) && out.flush()) {
    out.close();
    std::filesystem::rename(partial, path, ignored);
  }
  std::filesystem::remove(partial, ignored);
  return png;
}

FrameFinisher::FrameFinisher(FrameStore store, FrameWriterOptions stored, std::chrono::milliseconds idleGrace)
    : store_(std::move(store)), stored_(std::move(stored)), idleGrace_(idleGrace), thread_([this] { Run(); }) {}

FrameFinisher::~FrameFinisher() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void FrameFinisher::Add(uint64_t job, int first, int last, const ViewTransform& view) {
  if (!stored_.writeExr) return;  // written as the store keeps them already
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back({job, first, last, view});
  }
  wake_.notify_all();
}

void FrameFinisher::SetFarmBusy(bool busy) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (busy_ == busy) return;
    busy_ = busy;
    if (!busy) idleSince_ = std::chrono::steady_clock::now();
  }
  wake_.notify_all();
}

void FrameFinisher::Drop(uint64_t job) {
  std::unique_lock<std::mutex> lock(mutex_);
  queue_.erase(std::remove_if(queue_.begin(), queue_.end(), [job](const Job& queued) { return queued.id == job; }),
               queue_.end());
  if (current_ != job) return;
  dropCurrent_ = true;
  wake_.notify_all();  // it may be waiting for the farm to be idle
  finishedOne_.wait(lock, [&] { return current_ != job; });
}

bool FrameFinisher::Idle() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return queue_.empty() && !current_;
}

bool FrameFinisher::IsFinished(const FrameStore& store, uint64_t job) {
  std::error_code ignored;
  return std::filesystem::exists(store.JobFolder(job) / kFinishedMarker, ignored);
}

void FrameFinisher::Run() {
  for (;;) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      job = queue_.front();
      queue_.pop_front();
      current_ = job.id;
      dropCurrent_ = false;
    }
    Finish(job);
    // The frames it read and encoded are freed; the pages glibc keeps for this thread's
    // arena go back to the system, so the coordinator's RSS falls back once a job is done.
    malloc_trim(0);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      current_.reset();
    }
    finishedOne_.notify_all();
  }
}

void FrameFinisher::Finish(const Job& job) {
  for (int frame = job.first; frame <= job.last; ++frame) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      // Stopping: the next coordinator finishes the job. Dropped: its folder is about to go.
      if (!WaitForIdleFarm(lock)) return;
    }
    try {
      FinishFrame(job, frame);
      ++framesFinished_;
    } catch (const std::exception& e) {
      // A full disk, a frame gone: the frame stays as it was rendered, lossless.
      std::fprintf(stderr, "coordinator: job %llu frame %d stays as rendered: %s\n",
                   static_cast<unsigned long long>(job.id), frame, e.what());
    }
  }
  // Drop waits for this to return, so the marker never lands in a folder being removed.
  std::lock_guard<std::mutex> lock(mutex_);
  if (!dropCurrent_) std::ofstream(store_.JobFolder(job.id) / kFinishedMarker) << "finished\n";
}

bool FrameFinisher::WaitForIdleFarm(std::unique_lock<std::mutex>& lock) {
  for (;;) {
    if (stopping_ || dropCurrent_) return false;
    if (busy_) {
      wake_.wait(lock);
      continue;
    }
    const auto idleEnough = idleSince_ + idleGrace_;
    if (std::chrono::steady_clock::now() >= idleEnough) return true;
    wake_.wait_until(lock, idleEnough);
  }
}

void FrameFinisher::FinishFrame(const Job& finishing, int frame) const {
  const uint64_t job = finishing.id;
  const std::filesystem::path exr = store_.FramePath(job, frame, "exr");
  std::error_code missing;
  if (!std::filesystem::is_regular_file(exr, missing)) return;  // never written (a failed job)
  // "zip:1" is recorded as "zip": the name before the level says whether it is done.
  const std::string wanted = stored_.exrCompression.substr(0, stored_.exrCompression.find(':'));
  const bool compress = ExrCompressionOf(exr) != wanted;
  const bool preview = stored_.writePng && !std::filesystem::is_regular_file(store_.FramePath(job, frame, "png"), missing);
  if (!compress && !preview) return;  // finished before (a store older than the marker)
  const Image image = ReadImage(exr);
  if (compress) WriteExr(exr, image, stored_.exrCompression);
  if (preview) WritePng(store_.FramePath(job, frame, "png"), image, finishing.view);
}

}  // namespace tcfarm
