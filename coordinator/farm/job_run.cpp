#include "coordinator/farm/job_run.h"

#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <set>
#include <stdexcept>
#include <system_error>

#include "proto/frame/compare.h"
#include "proto/scene/scene.h"

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
  options.promisesExact = PromisesExact(strategy);
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

// What a killed coordinator left half done in the job's folder: a frame file being
// renamed into place, frames waiting on disk for their turn.
void RemoveLeftovers(const FrameStore& store, uint64_t job) {
  std::error_code ignored;
  std::filesystem::remove_all(store.SpillFolder(job), ignored);
  for (std::filesystem::directory_iterator it(store.JobFolder(job), ignored), end; !ignored && it != end;
       it.increment(ignored)) {
    if (it->path().extension() == ".partial") {
      std::filesystem::remove(it->path(), ignored);
    }
  }
}

// A job that was never started plans now; one that was keeps the plan it started with.
ResolvedStrategy ResolveForRun(const JobRecord& record, int workers, const SegmentPrices& prices) {
  if (std::optional<ResolvedStrategy> planned = PlanFromJson(record.plan)) return *planned;
  return ResolveJobStrategy(record.spec, workers, prices);
}

}  // namespace

nlohmann::json PlanJson(const ResolvedStrategy& resolved) {
  nlohmann::json plan = {{"strategy", std::string(StrategyName(resolved.strategy))},
                         {"bin_width", resolved.binWidth},
                         {"reason", resolved.reason},
                         {"survey", resolved.surveyBinWidth}};
  if (resolved.segments) plan["segments"] = resolved.segments->ToJson();
  if (resolved.predictedRelativeCost) plan["predicted_relative_cost"] = *resolved.predictedRelativeCost;
  if (!resolved.candidates.empty()) {
    plan["candidates"] = nlohmann::json::array();
    for (const StrategyCandidate& candidate : resolved.candidates) plan["candidates"].push_back(candidate.ToJson());
  }
  return plan;
}

std::optional<ResolvedStrategy> PlanFromJson(const nlohmann::json& plan) {
  if (!plan.is_object() || !plan.contains("strategy")) return std::nullopt;
  const std::string name = plan.value("strategy", std::string());
  const std::optional<Strategy> strategy = StrategyFromString(name);
  if (!strategy || *strategy == Strategy::kAuto || !plan.contains("bin_width")) {
    throw std::invalid_argument("the job's stored plan " + plan.dump() +
                                " names no strategy and bin width this coordinator can run");
  }
  ResolvedStrategy resolved{*strategy, plan.value("bin_width", 0), plan.value("reason", std::string()),
                            plan.value("survey", false), {}};
  if (plan.contains("segments")) resolved.segments = SegmentPlan::FromJson(plan["segments"]);
  if (const auto predicted = plan.find("predicted_relative_cost"); predicted != plan.end() && predicted->is_number()) {
    resolved.predictedRelativeCost = predicted->get<double>();
  }
  if (const auto candidates = plan.find("candidates"); candidates != plan.end() && candidates->is_array()) {
    for (const nlohmann::json& candidate : *candidates) resolved.candidates.push_back(StrategyCandidate::FromJson(candidate));
  }
  return resolved;
}

KeptFrames FindKeptFrames(const JobRecord& record, const FrameStore& store, const FrameWriterOptions& output) {
  KeptFrames found;
  found.kept.assign(static_cast<size_t>(record.FrameCount()), false);
  const uint64_t pixels = record.spec.frameSize.Pixels();
  std::error_code ignored;
  for (size_t i = 0; i < record.tracedPerFrame.size() && i < found.kept.size(); ++i) {
    if (record.tracedPerFrame[i] < 0) continue;
    const int frame = record.spec.firstFrame + static_cast<int>(i);
    // The coherence analysis reads kept frames back, bit for bit, from their EXR.
    const bool present = output.writeExr && std::filesystem::is_regular_file(store.FramePath(record.id, frame, "exr"), ignored) &&
                         (!output.writePng || std::filesystem::is_regular_file(store.FramePath(record.id, frame, "png"), ignored));
    if (!present) {
      found.missing.push_back(frame);
      continue;
    }
    found.kept[i] = true;
    ++found.count;
    found.traced += static_cast<uint64_t>(record.tracedPerFrame[i]);
    found.copied += pixels - static_cast<uint64_t>(record.tracedPerFrame[i]);
  }
  return found;
}

ResolvedStrategy ResolveJobStrategy(const JobSpec& spec, int workers, const SegmentPrices& prices) {
  return ResolveStrategy(spec.strategy, spec.binWidth, FrameCountOf(spec), CameraOrLightsChange(spec), workers,
                         spec.frameSize.Pixels(), prices);
}

namespace {
// The job's memory as it runs with this strategy (JobMemoryBytes).
JobMemoryShape JobShapeFor(const JobSpec& spec, const ResolvedStrategy& resolved, uint64_t pendingFrameBytes) {
  return {spec.frameSize.width, spec.frameSize.height, FrameCountOf(spec), resolved.strategy, resolved.binWidth,
          resolved.surveyBinWidth, pendingFrameBytes};
}
}  // namespace

PlannerOptions PlannerOptionsFor(const JobSpec& spec, const ResolvedStrategy& resolved, uint64_t jobMemoryBytes,
                                 uint64_t pendingFrameBytes) {
  PlannerOptions options;
  options.width = spec.frameSize.width;
  options.height = spec.frameSize.height;
  options.frameCount = FrameCountOf(spec);
  options.binWidth = resolved.binWidth;
  options.tolerance = static_cast<float>(spec.tolerance);
  if (jobMemoryBytes > 0) {
    const JobMemoryShape shape = JobShapeFor(spec, resolved, pendingFrameBytes);
    options.maxLiveBins = LiveBinsWithin(jobMemoryBytes, shape, options.maxLiveBins);
    if (options.maxLiveBins == 0) throw std::invalid_argument(MemoryShortfall(jobMemoryBytes, shape));
  }
  return options;
}

namespace {
PlannerOptions WithKeptFrames(PlannerOptions options, const KeptFrames& kept) {
  if (kept.count > 0) options.keptFrames = kept.kept;
  return options;
}

PlannerOptions WithFrameBuffers(PlannerOptions options, std::shared_ptr<FrameBufferPool> buffers) {
  options.frameBuffers = std::move(buffers);
  return options;
}

// Only exact's planner copies its finished frames out of working buffers it keeps; the
// others hand over the frames they built, so buffers given back would only wait.
bool RecyclesFrameBuffers(Strategy strategy) { return strategy == Strategy::kExact; }

FrameWriterOptions RecyclingInto(FrameWriterOptions options, std::shared_ptr<FrameBufferPool> buffers) {
  options.recycle = std::move(buffers);
  return options;
}
}  // namespace

JobRun::ReturnsFreedMemory::~ReturnsFreedMemory() { malloc_trim(0); }

JobRun::JobRun(const JobRecord& record, const FrameStore& store, const JobRunSettings& settings)
    : id_(record.id),
      memoryGranted_(settings.jobMemoryBytes),
      spec_(record.spec),
      frameStore_(store),
      kept_(FindKeptFrames(record, store, settings.output)),
      resolved_(ResolveForRun(record, settings.workers, settings.segmentPrices)),
      frameBuffers_(RecyclesFrameBuffers(resolved_.strategy) ? std::make_shared<FrameBufferPool>(kRecycledFrameBuffers)
                                                             : nullptr),
      plannerOptions_(WithFrameBuffers(
          WithKeptFrames(PlannerOptionsFor(record.spec, resolved_, settings.jobMemoryBytes, settings.pendingFrameBytes),
                         kept_),
          frameBuffers_)),
      planner_(MakeJobPlanner(resolved_, plannerOptions_, &autoPlanner_)),
      verification_(spec_.frameSize.width, spec_.frameSize.height, FrameCountOf(spec_),
                    VerificationFor(spec_, record.id, resolved_.strategy)),
      audit_(record.id, spec_.firstFrame, FrameCountOf(spec_), settings.referee),
      sample_(record.id, spec_.firstFrame, FrameCountOf(spec_), settings.referee),
      referee_(settings.referee),
      written_(kept_.kept),
      writer_(CreatedDirectory(store.JobFolder(record.id)), RecyclingInto(settings.output, frameBuffers_)),
      coherence_(store.SpillFolder(record.id), settings.pendingFrameBytes),
      cost_(PixelsPerFrame(), FrameCountOf(spec_), resolved_.strategy == Strategy::kExact ? resolved_.binWidth : 0),
      started_(std::chrono::steady_clock::now()),
      records_(record.id, PixelsPerFrame(), kept_.missing, kept_.count) {
  spec_.sceneJson.clear();  // the dispatcher holds it for the workers
  RemoveLeftovers(store, id_);
  if (!PlanFromJson(record.plan)) records_.SavePlan(PlanJson(resolved_));
  chosenWidthPlanned_ = !resolved_.surveyBinWidth;
}

std::vector<DispatchTask> JobRun::TakeTasks(int workers) {
  std::vector<DispatchTask> tasks;
  planner_->SetWorkers(workers);
  // While the writer or the referee is behind, the planner's tasks wait: tracing more would
  // only pile up frames, or sampled values, in memory.
  const bool behind = unwritten_.size() >= kMaxUnwrittenFrames || sample_.Behind();
  for (TraceTask& t : behind ? std::vector<TraceTask>{} : planner_->TakeReadyTasks()) {
    taskChains_[t.id] = {t.chain, t.step};
    ++tasksOut_[spec_.firstFrame + t.frame];
    tasks.push_back({id_, t.id, spec_.firstFrame + t.frame, std::move(t.pixels), t.window, {}, false});
  }
  // Spot checks are the referee's: a worker never sees one, so none can be told apart from
  // work (farm/referee_sample.h). A reference frame, traced in full on request, goes to a
  // worker other than the ones whose values it checks, so that a worker that returns wrong
  // values never checks itself; where no such worker is connected, the referee traces it
  // (the dispatcher hands it back: TakeStranded).
  for (Verification::Request& r : verification_.TakeRequests()) {
    DispatchTask check{id_, r.id | kVerificationTask, spec_.firstFrame + r.frame, std::move(r.pixels), 0, {},
                       /*refereeMayTrace=*/true};
    if (!verification_.IsReference(r.id)) {
      forReferee_.push_back(std::move(check));
      continue;
    }
    check.avoid = audit_.WorkersReaching(r.frame);
    check.avoid.insert(audit_.Distrusted().begin(), audit_.Distrusted().end());
    tasks.push_back(std::move(check));
  }
  for (int frame : audit_.TakeFramesToRepair([this](int f) { return written_[static_cast<size_t>(f)]; })) {
    tasks.push_back({id_, kRepairTask | static_cast<uint64_t>(frame), spec_.firstFrame + frame,
                     PixelSet::Full(static_cast<uint32_t>(PixelsPerFrame())), 0, audit_.Distrusted(),
                     /*refereeMayTrace=*/true});
  }
  return tasks;
}

void JobRun::TraceByReferee(DispatchTask task, const JobStore& store) {
  if (!referee_) throw std::runtime_error("no worker may trace a check of frame " + std::to_string(task.frame) +
                                          " and this farm has no referee to trace it");
  const uint64_t id = nextRefereeCheck_++;
  std::vector<uint32_t> pixels;
  pixels.reserve(task.pixels.size());
  task.pixels.ForEach([&](uint32_t pixel) { pixels.push_back(pixel); });
  referee_->Ask({id_, id, spec_.sceneHash, SceneJson(store), task.frame, std::move(pixels),
                 Referee::Purpose::kCheck});
  refereeChecks_[id] = std::move(task);
}

void JobRun::HearRefereeChecks() {
  if (!referee_ || refereeChecks_.empty()) return;
  for (Referee::Answer& answer : referee_->TakeAnswers(id_, Referee::Purpose::kCheck)) {
    auto asked = refereeChecks_.find(answer.id);
    if (asked == refereeChecks_.end()) continue;
    const DispatchTask task = std::move(asked->second);
    refereeChecks_.erase(asked);
    if (!answer.error.empty()) {
      const uint64_t check = task.plannerTaskId & ~kVerificationTask;
      const bool spotCheck = (task.plannerTaskId & kVerificationTask) && !verification_.IsReference(check);
      const std::string why = "the coordinator's referee could not trace a check of frame " +
                              std::to_string(task.frame) + ": " + answer.error;
      // A spot check only measures: without it the job reports fewer pixels checked. A
      // reference or a repair the job cannot do without.
      if (!spotCheck) throw std::runtime_error(why);
      verification_.Abandon(check, why);
      continue;
    }
    wire::Result result;
    result.jobId = id_;
    result.frame = task.frame;
    result.rgb = std::move(answer.rgb);
    result.traceSeconds = answer.seconds;
    result.traceCpuSeconds = answer.cpuSeconds;
    OnResult(task, result, Referee::kName);
  }
}

const std::string& JobRun::SceneJson(const JobStore& store) {
  if (sceneJson_.empty()) {
    std::optional<JobRecord> record = store.Get(id_);
    if (record) sceneJson_ = std::move(record->spec.sceneJson);
  }
  return sceneJson_;
}

int JobRun::CopyReach(int window) const {
  switch (resolved_.strategy) {
    case Strategy::kBrute:
      return 0;
    case Strategy::kExact:
      return window;  // copies only as far as the horizons the task returned
    default:
      return std::max(window, plannerOptions_.binWidth);  // copies across a bin
  }
}

bool JobRun::OnResult(const DispatchTask& task, const wire::Result& result, const std::string& worker,
                      bool onProbation) {
  if (!Accept(task, result, worker)) return false;
  // Every value a worker sent, whatever it was for, may be drawn for the referee.
  if (result.rgb.size() == 3 * task.pixels.size()) {
    const bool horizons = task.window > 0 && result.horizons.size() == task.pixels.size();
    sample_.OnValues(task.frame - spec_.firstFrame, worker, task.pixels, result.rgb.data(),
                     horizons ? result.horizons.data() : nullptr, onProbation);
  }
  return true;
}

bool JobRun::Accept(const DispatchTask& task, const wire::Result& result, const std::string& worker) {
  if (task.plannerTaskId & kVerificationTask) {
    return OnVerificationResult(task.plannerTaskId & ~kVerificationTask, result, worker);
  }
  if (task.plannerTaskId & kRepairTask) return OnRepairResult(task, result, worker);
  return OnPlannerResult(task, result, worker);
}

bool JobRun::OnVerificationResult(uint64_t taskId, const wire::Result& result, const std::string& worker) {
  const bool reference = verification_.IsReference(taskId);
  if (!verification_.OnResult(taskId, result.rgb.data(), result.rgb.size(), worker)) return false;
  cost_.OnVerificationResult(result, reference);
  return true;
}

bool JobRun::OnRepairResult(const DispatchTask& task, const wire::Result& result, const std::string& worker) {
  const int frame = static_cast<int>(task.plannerTaskId & ~kRepairTask);
  const int absolute = spec_.firstFrame + frame;
  const uint64_t changed = PixelsDifferingFromWritten(absolute, result.rgb);
  if (changed > 0) {
    std::fprintf(stderr, "coordinator: job %llu: frame %d traced again: %llu pixels differed; rewritten\n",
                 static_cast<unsigned long long>(id_), absolute, static_cast<unsigned long long>(changed));
    writer_.Write(absolute, Image{spec_.frameSize.width, spec_.frameSize.height, result.rgb});
    verification_.Reverify(frame, result.rgb);  // its reference, if asked, compares with what it shows now
  }
  audit_.OnRepaired(frame, worker, changed);
  cost_.OnRepairResult(result);
  return true;
}

uint64_t JobRun::PixelsDifferingFromWritten(int absoluteFrame, const std::vector<float>& rgb) const {
  Image written;
  try {
    written = ReadImage(frameStore_.FramePath(id_, absoluteFrame, "exr"));
  } catch (const std::exception& e) {
    // No lossless copy to compare with (a farm that writes PNG only, a file gone): the
    // frame is rewritten whole.
    std::fprintf(stderr, "coordinator: job %llu: frame %d to repair cannot be read back (%s); rewritten whole\n",
                 static_cast<unsigned long long>(id_), absoluteFrame, e.what());
    return rgb.size() / 3;
  }
  if (written.rgb.size() != rgb.size()) return rgb.size() / 3;
  return CompareImages(written, Image{written.width, written.height, rgb}).differingPixels;
}

std::vector<ExactnessAudit::Verdict> JobRun::TakeVerdicts() {
  std::vector<ExactnessAudit::Verdict> verdicts;
  verdicts.swap(verdicts_);
  return verdicts;
}

void JobRun::OnWorkerDistrusted(const std::string& worker, const std::string& name) {
  audit_.OnWorkerDistrusted(worker, name);
  sample_.OnWorkerDistrusted(worker);
  for (int frame : verification_.ForgetReferencesBy(worker)) toReverify_.insert(frame);
}

void JobRun::ReverifyWrittenFrames() {
  for (auto it = toReverify_.begin(); it != toReverify_.end();) {
    const int frame = *it;
    if (!written_[static_cast<size_t>(frame)]) {
      ++it;
      continue;
    }
    const int absolute = spec_.firstFrame + frame;
    try {
      verification_.Reverify(frame, ReadImage(frameStore_.FramePath(id_, absolute, "exr")).rgb);
    } catch (const std::exception& e) {
      // No lossless copy to compare with (a farm that writes PNG only): the frame stays
      // uncompared, and the report says fewer frames were compared than asked.
      std::fprintf(stderr, "coordinator: job %llu: frame %d cannot be read back to verify again (%s)\n",
                   static_cast<unsigned long long>(id_), absolute, e.what());
    }
    it = toReverify_.erase(it);
  }
}

void JobRun::Audit(const JobStore& store) {
  ReverifyWrittenFrames();
  for (DispatchTask& check : forReferee_) TraceByReferee(std::move(check), store);
  forReferee_.clear();
  HearRefereeChecks();
  sample_.Ask(spec_.sceneHash, [&]() -> const std::string& { return SceneJson(store); });
  for (Verdict& verdict : sample_.HearReferee()) verdicts_.push_back(std::move(verdict));
  for (const auto& [frame, pixels] : sample_.TakeWrongPixels()) verification_.OnWrongValues(frame, pixels);
  for (int frame : sample_.TakeKeptFramesWrong()) audit_.OweRepair(frame);
  audit_.Open(verification_.TakeDisputes(),
              [&] { return ExactnessAudit::SceneRef{spec_.sceneHash, SceneJson(store)}; });
  for (ExactnessAudit::Verdict& verdict : audit_.HearReferee()) verdicts_.push_back(std::move(verdict));
  for (const std::string& suspect : audit_.TakeSuspects()) sample_.Suspect(suspect);
}

bool JobRun::OnPlannerResult(const DispatchTask& task, const wire::Result& result, const std::string& worker) {
  const uint64_t taskId = task.plannerTaskId;
  // Workers speak absolute frames; the planner counts from the job's first frame.
  std::vector<int32_t> horizons(result.horizons);
  for (int32_t& h : horizons) h -= spec_.firstFrame;
  if (!planner_->OnResult(taskId, result.rgb.data(), result.rgb.size(),
                          horizons.empty() ? nullptr : horizons.data(), horizons.size())) {
    return false;
  }
  if (auto out = tasksOut_.find(task.frame); out != tasksOut_.end() && --out->second == 0) tasksOut_.erase(out);
  const auto chain = taskChains_.find(taskId);
  if (chain != taskChains_.end()) {
    cost_.OnPlannerResult(result.frame - spec_.firstFrame, result, chain->second.first, chain->second.second);
    taskChains_.erase(chain);
  } else {
    cost_.OnPlannerResult(result.frame - spec_.firstFrame, result);
  }
  audit_.OnTraced(result.frame - spec_.firstFrame, worker, CopyReach(task.window));
  return true;
}

int JobRun::CollectFinishedFrames(JobStore& store) {
  for (FinishedFrame& frame : planner_->TakeFinishedFrames()) {
    if (kept_.count > 0 && kept_.kept[static_cast<size_t>(frame.frame)]) {
      // In the store already, from before the restart: the same bits, not written again.
      retracedPixels_ += frame.tracedCount;
      ++retracedFrames_;
      if (frameBuffers_) frameBuffers_->Give(std::move(frame.rgb));
      continue;
    }
    unwritten_.push_back(std::move(frame));
  }
  // Only as much as the writer takes at once and a short turn allows: the farm loop must
  // come back to its socket (results, heartbeats) while large frames are encoded.
  const auto turnEnds = std::chrono::steady_clock::now() + kFinishingTurn;
  FeedKeptFrames(turnEnds);
  int collected = 0;
  while (!unwritten_.empty() && writer_.HasRoom() && std::chrono::steady_clock::now() < turnEnds) {
    FinishFrame(std::move(unwritten_.front()));
    unwritten_.pop_front();
    ++collected;
    FeedKeptFrames(turnEnds);
  }
  RecordWrittenFrames(store);
  if (std::optional<std::string> failure = WriteFailure()) throw FrameIoError(*failure);
  Audit(store);
  return collected;
}

bool JobRun::RecordWrittenFrames(JobStore& store) {
  for (int frame : writer_.TakeWritten()) {
    written_[static_cast<size_t>(frame - spec_.firstFrame)] = true;
    records_.Written(frame);
  }
  // The written frames of a failed write are counted too: they are in the folder.
  if (writer_.FirstFailure() && writer_.Idle()) records_.DropWriting();
  // Auto's survey chose the bin width: the plan says so before the next frame's record.
  if (autoPlanner_ && !chosenWidthPlanned_ && autoPlanner_->ChosenBinWidth() > 0) {
    records_.SavePlan(PlanJson(SurveyedPlan()));
    chosenWidthPlanned_ = true;
  }
  return records_.Flush(store);
}

std::optional<std::string> JobRun::WriteFailure() const {
  const std::optional<FrameWriter::Failure> failure = writer_.FirstFailure();
  if (!failure) return std::nullopt;
  const std::string what = failure->frame ? "frame " + std::to_string(*failure->frame) + " (" + failure->file + ")"
                                          : "the mask " + failure->file;
  return what + " could not be written: " + failure->why + "; " + std::to_string(records_.recorded()) + " of " +
         std::to_string(FrameCountOf(spec_)) +
         " frames are written and recorded (traced_per_frame names them; they stay downloadable)";
}

void JobRun::FeedKeptFrames(std::chrono::steady_clock::time_point turnEnds) {
  const int frames = FrameCountOf(spec_);
  while (kept_.count > 0 && coherence_.NextFrame() < frames &&
         kept_.kept[static_cast<size_t>(coherence_.NextFrame())] && std::chrono::steady_clock::now() < turnEnds) {
    const int frame = coherence_.NextFrame();
    const int absolute = spec_.firstFrame + frame;
    Image image = ReadImage(frameStore_.FramePath(id_, absolute, "exr"));
    if (image.width != spec_.frameSize.width || image.height != spec_.frameSize.height) {
      throw FrameIoError("frame " + std::to_string(absolute) + " kept from before the restart is " +
                         std::to_string(image.width) + "x" + std::to_string(image.height) + ", expected " +
                         std::to_string(spec_.frameSize.width) + "x" + std::to_string(spec_.frameSize.height));
    }
    // Its reference, when one is asked for, is traced and compared like any frame's. It
    // gets no spot checks: which of its pixels are copies went with the run that made it.
    verification_.OnKeptFrame(frame, image.rgb);
    // What the run before drew of its values went with that run: drawn again here.
    if (PromisesExact(resolved_.strategy)) sample_.OnKeptValues(frame, image.rgb);
    for (JobCoherence::ChangeMask& mask : coherence_.Add(frame, image)) {
      WriteMask(MaskKind::kChange, spec_.firstFrame + mask.frame, std::move(mask.unchanged));
    }
  }
}

void JobRun::FinishFrame(FinishedFrame frame) {
  const int absolute = spec_.firstFrame + frame.frame;
  records_.Writing(absolute, frame.tracedCount);
  cost_.OnFrameFinished(frame.frame, frame.tracedCount);
  Image image{spec_.frameSize.width, spec_.frameSize.height, std::move(frame.rgb)};
  verification_.OnFrameFinished(frame.frame, image.rgb, frame.traced);
  // Every planner gives a pixel it does not trace the previous frame's bits: only the
  // traced pixels can have changed.
  std::vector<JobCoherence::ChangeMask> changeMasks = coherence_.Add(frame.frame, image, &frame.traced);
  WriteMask(MaskKind::kTraced, absolute, std::move(frame.traced));
  for (JobCoherence::ChangeMask& mask : changeMasks) {
    WriteMask(MaskKind::kChange, spec_.firstFrame + mask.frame, std::move(mask.unchanged));
  }
  writer_.Write(absolute, std::move(image));
  ++framesDone_;
}

void JobRun::WriteMask(MaskKind kind, int absoluteFrame, std::vector<uint8_t> mask) {
  writer_.WriteMask(FrameStore::MaskFileName(kind, absoluteFrame), spec_.frameSize.width, spec_.frameSize.height,
                    std::move(mask));
}

void JobRun::FinishWriting() { writer_.Finish(); }

ResolvedStrategy JobRun::SurveyedPlan() const {
  ResolvedStrategy chosen = resolved_;
  const BinWidthChoice& survey = autoPlanner_->SurveyChoice();
  chosen.binWidth = autoPlanner_->ChosenBinWidth();
  chosen.surveyBinWidth = false;
  chosen.predictedRelativeCost = SurveyPrediction(survey, chosen.binWidth);
  const std::optional<double> best = SurveyPrediction(survey, survey.binWidth);
  for (StrategyCandidate& candidate : chosen.candidates) {
    if (candidate.strategy == Strategy::kGuarded) candidate.predictedRelativeCost = best;
  }
  char why[200];
  if (chosen.binWidth != survey.binWidth) {
    std::snprintf(why, sizeof why,
                  "; the survey predicts guarded's best width (%d) to cost %.3f of brute force's CPU (at least "
                  "%.2f): bins of 2, every pixel traced",
                  survey.binWidth, best.value_or(1.0), kAutoBruteFromCost);
  } else {
    std::snprintf(why, sizeof why, "; bin width %d chosen by the survey (predicted relative CPU cost %.3f)",
                  chosen.binWidth, chosen.predictedRelativeCost.value_or(1.0));
  }
  chosen.reason += why;
  return chosen;
}

int JobRun::BinWidth() const {
  return autoPlanner_ ? autoPlanner_->ChosenBinWidth() : resolved_.binWidth;
}

std::vector<int> JobRun::TracingFrames() const {
  std::set<int> frames;
  for (const auto& [frame, count] : tasksOut_) frames.insert(frame);
  for (const FinishedFrame& frame : unwritten_) frames.insert(spec_.firstFrame + frame.frame);
  for (int frame : records_.WritingFrames()) frames.insert(frame);
  return {frames.begin(), frames.end()};
}

nlohmann::json JobRun::StrategyStats() const {
  const bool surveyed = autoPlanner_ && autoPlanner_->ChosenBinWidth() > 0;
  const ResolvedStrategy plan = surveyed ? SurveyedPlan() : resolved_;
  nlohmann::json strategy = PlanJson(plan);
  strategy.erase("survey");
  strategy.erase("strategy");
  strategy["name"] = std::string(StrategyName(plan.strategy));
  strategy["bin_width"] = BinWidth();
  if (surveyed) {
    nlohmann::json survey = {{"frames", autoPlanner_->SurveyedFrames()}, {"predicted_traced_share", {}}};
    for (const auto& [width, share] : autoPlanner_->Predictions()) {
      survey["predicted_traced_share"][std::to_string(width)] = share;
    }
    strategy["survey"] = survey;
  }
  return strategy;
}

nlohmann::json JobRun::Stats(bool final) const {
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  nlohmann::json stats;
  stats["strategy"] = StrategyStats();
  stats["frames_done"] = kept_.count + framesDone_;
  // A resumed job: frames it found in the store, and the pixels traced again because they
  // lay in bins (segments) that were in progress when the coordinator stopped.
  stats["resumed_frames"] = kept_.count;
  stats["retraced_frames"] = retracedFrames_;
  stats["retraced_pixels"] = retracedPixels_;
  // Bins (segments) worked on at once: fewer than 4 when the coordinator's memory for the
  // job would not hold their frames.
  stats["live_bins"] = plannerOptions_.maxLiveBins;
  // Frames that finished ahead of their turn and waited on disk, not in memory.
  stats["frames_waited_on_disk"] = coherence_.FramesWaitedOnDisk();
  // The job's frames' own pixels: kept ones as recorded, not those traced again.
  const uint64_t traced = kept_.traced + planner_->TracedPixels() - std::min(retracedPixels_, planner_->TracedPixels());
  stats["pixels_traced"] = traced;
  const uint64_t recopied = uint64_t(retracedFrames_) * PixelsPerFrame() - retracedPixels_;
  stats["pixels_copied"] = kept_.copied + planner_->CopiedPixels() - std::min(recopied, planner_->CopiedPixels());
  stats["traced_pixel_ratio"] =
      static_cast<double>(traced) / static_cast<double>(PixelsPerFrame() * FrameCountOf(spec_));
  stats["wall_seconds"] = wall;
  const SequenceAnalyzer& coherence = coherence_.analysis();
  cost_.AddTo(stats, coherence.frameToFrame());
  stats["error"] = verification_.Report();
  if (nlohmann::json audit = audit_.Report(); !audit.is_null()) stats["error"]["audit"] = audit;
  stats["error"]["referee_sample"] = sample_.Report();
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
