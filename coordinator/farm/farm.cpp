#include "coordinator/farm/farm.h"

#include <algorithm>
#include <cstdio>
#include <iterator>
#include <stdexcept>

namespace tcfarm {
namespace {

// How often the loop looks for new jobs and republishes its snapshot: often enough that
// a submitted job starts at once, rarely enough that SQLite is not polled in a tight loop.
constexpr Milliseconds kClaimInterval{100};
constexpr Milliseconds kSnapshotInterval{200};
// Poll timeout of the loop when idle; bounds the latency of cancellation and stop.
constexpr Milliseconds kIdlePoll{50};
// A worker on probation has done at most this many tasks since it joined: the referee
// samples more of its values (RefereeSample::kProbationFactor), unseen. One that
// reconnects starts over.
constexpr uint64_t kProbationTasks = 16;

double SecondsBetween(SteadyTime earlier, SteadyTime later) {
  return std::chrono::duration<double>(later - earlier).count();
}

std::string Figure(double value, const char* format) {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

// "the coordinator's referee (N pixels) and other workers (M pixels)", as far as each checked.
std::string CheckersInWords(const nlohmann::json& checkedBy) {
  const uint64_t referee = checkedBy.value("referee_pixels", uint64_t{0});
  const uint64_t workers = checkedBy.value("worker_pixels", uint64_t{0});
  std::string words;
  if (referee > 0) words = "the coordinator's referee (" + std::to_string(referee) + " pixels)";
  if (workers > 0) {
    words += std::string(words.empty() ? "" : " and ") + "workers other than those checked (" +
             std::to_string(workers) + " pixels)";
  }
  return words.empty() ? "nobody yet" : words;
}

// The verification event of a finished job: its reference comparison when frames were
// verified, its spot checks when any copied pixel was checked; nullopt when neither.
std::optional<EventDraft> VerificationEvent(const nlohmann::json& error) {
  if (!error.is_object()) return std::nullopt;
  const nlohmann::json spot = error.value("spot_checks", nlohmann::json::object());
  const bool spotChecked = spot.value("pixels_checked", 0.0) > 0;
  if (!error.contains("reference") && !spotChecked) return std::nullopt;
  EventDraft event{"verification", "", nlohmann::json::object()};
  std::string message;
  if (error.contains("reference")) {
    const nlohmann::json& reference = error["reference"];
    event.fields["reference"] = reference;
    const nlohmann::json psnr = reference.value("psnr_db", nlohmann::json());
    message = "verified " + std::to_string(reference.value("frames_compared", 0)) + " of " +
              std::to_string(reference.value("frames_requested", 0)) + " frames against brute force: " +
              std::to_string(reference.value("pixels_differing", 0)) + " pixels differ (" +
              Figure(reference.value("percent_differing", 0.0), "%.4g") + " %), max error " +
              Figure(reference.value("max_abs_error", 0.0), "%.4g") + ", PSNR " +
              (psnr.is_number() ? Figure(psnr.get<double>(), "%.1f") + " dB" : std::string("infinite"));
  }
  if (spotChecked) {
    event.fields["spot_checks"] = spot;
    message += std::string(message.empty() ? "" : "; ") + "spot checks: " +
               std::to_string(spot.value("mismatches", 0)) + " of " + std::to_string(spot.value("pixels_checked", 0)) +
               " copied pixels traced again differ";
  }
  // Every verified figure names who checked: never a worker whose values it checks.
  const nlohmann::json checkedBy = error.value("checked_by", nlohmann::json::object());
  event.fields["checked_by"] = checkedBy;
  message += "; checked by " + CheckersInWords(checkedBy);
  event.message = message;
  return event;
}

}  // namespace

Farm::Farm(JobStore& store, FarmOptions options, const Clock& clock)
    : store_(store),
      options_(std::move(options)),
      clock_(clock),
      frameStore_(options_.storeRoot),
      assets_(options_.storeRoot / "assets"),
      dispatcher_(options_.endpoint, clock, options_.heartbeat, &assets_, options_.curve),
      ownReferee_(options_.referee ? nullptr : std::make_unique<TracingReferee>(options_.storeRoot / "assets",
                                                                                   options_.importBudget)),
      referee_(options_.referee ? options_.referee : ownReferee_.get()),
      bans_(options_.storeRoot / "worker_bans.json"),
      finisher_(frameStore_, options_.output),
      admission_(MemoryBudget{options_.farmMemoryBytes, options_.pendingFrameBytes, options_.longestMemoryWait},
                 clock) {
  for (const WorkerBan& ban : bans_.List()) dispatcher_.Ban(ban.principal);
  LoadScenePrices();
}

void Farm::LoadScenePrices() {
  try {
    for (const JobStore::ScenePrices& row : store_.LoadScenePrices(PriceBook::kDefaultCapacity)) {
      prices_.Record(row.sceneHash, row.deforming, SegmentPrices{row.startPrice, row.framePrice});
    }
  } catch (const std::exception& e) {
    // Prices are a hint: the model starts from its priors.
    std::fprintf(stderr, "coordinator: the measured segment prices could not be read: %s\n", e.what());
  }
}

void Farm::KeepScenePrices(const JobRun& run) {
  const JobSpec& spec = run.spec();
  const std::optional<SegmentPrices> measured = run.MeasuredSegmentPrices();
  if (!measured) return;
  const SegmentPrices kept = prices_.Record(spec.sceneHash, spec.deformingMeshes, *measured);
  try {
    store_.SaveScenePrices({spec.sceneHash, spec.deformingMeshes, kept.startPrice, kept.framePrice},
                           PriceBook::kDefaultCapacity);
  } catch (const std::exception& e) {
    NoteRefusedWrite(e);  // kept in memory all the same; only a restart forgets them
  }
}


Farm::~Farm() = default;

void Farm::Run(const std::atomic<bool>& stop, const std::function<void()>& afterStep) {
  while (!stop) {
    Step(kIdlePoll);
    if (afterStep) afterStep();
  }
  requests_.Stop();
  dispatcher_.SayGoodbye();
}

void Farm::Step(Milliseconds pollTimeout) {
  SteadyTime now = clock_.Now();
  ApplyRequests();
  if (now - lastClaim_ >= kClaimInterval) {
    lastClaim_ = now;
    SettleClosingJobs();
    ClaimJobs();
  }
  // Results wake the receive at once; the planner's follow-up tasks go out in the same
  // step, so no worker waits for the timeout.
  PumpTasks();
  dispatcher_.Flush();
  dispatcher_.Receive(pollTimeout, *this);
  PumpTasks();
  RouteStrandedChecks();
  dispatcher_.Flush();
  CollectFrames();
  DistrustWrongWorkers();
  RecordEvents();
  finisher_.SetFarmBusy(!runs_.empty());
  UpdateMetrics();
  if (clock_.Now() - lastSnapshot_ >= kSnapshotInterval) PublishSnapshot();
}

// Jobs a previous process left running are requeued before anything is claimed: after
// the first claim, "running" would also mean this process's own jobs.
void Farm::ClaimJobs() {
  try {
    if (!interruptedRequeued_) {
      for (uint64_t id : store_.RequeueInterrupted()) {
        std::fprintf(stderr, "coordinator: job %llu was interrupted; requeued to resume\n",
                     static_cast<unsigned long long>(id));
      }
      interruptedRequeued_ = true;
      RequeueUnfinishedFrames();
    }
    admission_.BeginLook();
    while (static_cast<int>(runs_.size()) < options_.maxRunningJobs) {
      uint64_t granted = 0;
      bool passable = true;
      std::optional<JobRecord> record = store_.ClaimNext([&](const JobRecord& job) {
        return passable && admission_.Admits(job, MemoryGranted(), &granted, &passable);
      });
      if (!record) break;
      StartJob(*record, granted);
    }
    admission_.EndLook();
  } catch (const JobStoreFullError& e) {
    NoteRefusedWrite(e);  // claimed nothing; the next interval tries again
  }
}

uint64_t Farm::MemoryGranted() const {
  uint64_t granted = 0;
  for (const auto& [id, run] : runs_) granted += run->memoryGranted();
  return granted;
}

void Farm::RequeueUnfinishedFrames() {
  for (JobState state : {JobState::kCompleted, JobState::kFailed, JobState::kCanceled}) {
    for (const JobRecord& record : store_.List(state, /*limit=*/0)) {
      if (!FrameFinisher::IsFinished(frameStore_, record.id)) {
        finisher_.Add(record.id, record.spec.firstFrame, record.spec.lastFrame, JobPreviewView(record.spec));
      }
    }
  }
}

void Farm::StartJob(const JobRecord& record, uint64_t granted) {
  // Canceled, retried and claimed again before the cancel reached the loop: the old run
  // goes first, and the job resumes from what it wrote.
  if (runs_.count(record.id)) StopRun(record.id);
  try {
    JobRunSettings settings;
    settings.output = WhileRendering(options_.output);
    settings.output.view = JobPreviewView(record.spec);  // for a store that keeps only previews
    settings.workers = LiveWorkers();
    settings.pendingFrameBytes = options_.pendingFrameBytes;
    settings.jobMemoryBytes = granted;
    settings.referee = referee_;
    settings.segmentPrices = prices_.Quote(record.spec.sceneHash, record.spec.deformingMeshes);
    auto run = std::make_unique<JobRun>(record, frameStore_, settings);
    const FrameSize size = run->frameSize();
    dispatcher_.AddJob(record.id, record.spec.priority, static_cast<uint32_t>(size.width),
                       static_cast<uint32_t>(size.height), record.spec.sceneHash,
                       record.spec.sceneJson);
    runs_[record.id] = std::move(run);
  } catch (const std::exception& e) {
    // A bad job fails alone; the farm goes on.
    ClosingJob closing;
    closing.failed = true;
    closing.why = e.what();
    Close(record.id, std::move(closing));
  }
}

void Farm::RequestCancel(uint64_t jobId) { requests_.Cancel(jobId); }

void Farm::RequestPriority(uint64_t jobId, int priority) { requests_.SetPriority(jobId, priority); }

bool Farm::ReleaseJob(uint64_t jobId) {
  if (!requests_.Release(jobId)) return false;
  // Off the loop: the finisher may be a frame's encoding away from letting go.
  finisher_.Drop(jobId);
  return true;
}

void Farm::ApplyRequests() {
  FarmRequests::Batch asked = requests_.Take();
  std::set<uint64_t>& cancels = asked.cancels;
  for (const std::string& principal : asked.liftedBans) {
    if (dispatcher_.Unban(principal)) {
      std::fprintf(stderr, "coordinator: the ban of %s is lifted; it is heard again on its next connection\n",
                   principal.c_str());
    }
  }
  for (const auto& [id, ticket] : asked.releases) cancels.insert(id);
  std::set<uint64_t> unread;  // asked again by the next step
  for (uint64_t id : cancels) {
    if (!runs_.count(id)) continue;
    std::optional<JobState> state;
    try {
      state = store_.StateOf(id);
    } catch (const JobStoreError&) {
      unread.insert(id);
      continue;
    }
    // A cancel (or release) that comes after the job was retried and claimed again is stale.
    if (state == JobState::kRunning) continue;
    StopRun(id);
    metrics_.jobsFinishedCanceled.Increment();
  }
  for (const auto& [id, priority] : asked.priorities) {
    if (runs_.count(id)) dispatcher_.SetPriority(id, priority);
  }
  requests_.Settle(asked.releases, unread);
}

void Farm::StopRun(uint64_t jobId) {
  auto run = runs_.find(jobId);
  if (run == runs_.end()) return;
  dispatcher_.RemoveJob(jobId);
  try {
    run->second->FinishWriting();  // frames already finished stay downloadable
  } catch (const std::exception&) {
  }
  finisher_.Add(jobId, run->second->firstFrame(), run->second->lastFrame(), run->second->previewView());
  runs_.erase(run);
}

void Farm::RecordEvents() {
  try {
    for (const WorkerLoss& loss : dispatcher_.TakeWorkerLosses()) {
      for (const auto& [jobId, tasks] : loss.requeuedTasks) {
        store_.AppendEvent(jobId, {"worker_lost",
                                   "worker " + loss.worker + " " + loss.why + "; " + std::to_string(tasks) +
                                       " of its tasks of this job were requeued",
                                   {{"worker", loss.worker}, {"why", loss.why}, {"requeued_tasks", tasks}}});
      }
    }
    if (clock_.Now() - lastFrameEvents_ >= kClaimInterval) {
      lastFrameEvents_ = clock_.Now();
      store_.FlushFrameEvents();
    }
  } catch (const JobStoreError& e) {
    NoteRefusedWrite(e);  // events are news, not records: the job goes on without them
  }
}

void Farm::PumpTasks() {
  for (auto& [id, run] : runs_) {
    for (DispatchTask& task : run->TakeTasks(LiveWorkers())) dispatcher_.Enqueue(std::move(task));
  }
}

void Farm::OnResult(const DispatchTask& task, wire::Result&& result, double latencySeconds,
                    const WorkerState& worker) {
  metrics_.taskLatency.Observe(latencySeconds);
  const uint64_t jobId = task.jobId;
  auto run = runs_.find(jobId);
  if (run == runs_.end()) return;
  const bool onProbation = worker.tasksDone <= kProbationTasks;
  try {
    if (!run->second->OnResult(task, result, worker.principal, onProbation)) return;
  } catch (const std::invalid_argument& e) {
    // The dispatcher checked sizes; a planner complaint here means values it refuses
    // (non-finite). The pixels are lost, so the job cannot finish correctly.
    FailJob(jobId, std::string("a worker returned an unusable result: ") + e.what());
    return;
  }
  metrics_.taskResults.Increment();
  metrics_.raysPrimary.Increment(static_cast<double>(result.primaryRays));
  metrics_.raysShadow.Increment(static_cast<double>(result.shadowRays));
  metrics_.raysReflection.Increment(static_cast<double>(result.reflectionRays));
  metrics_.raysRefraction.Increment(static_cast<double>(result.refractionRays));
}

void Farm::OnTaskFailed(uint64_t jobId, uint64_t /*plannerTaskId*/, const std::string& why) {
  FailJob(jobId, "a worker could not trace this job: " + why);
}

void Farm::CollectFrames() {
  std::vector<uint64_t> done;
  for (auto& [id, run] : runs_) {
    int frames = 0;
    try {
      frames = run->CollectFinishedFrames(store_);
    } catch (const std::exception& e) {
      FailJob(id, e.what());
      return;  // runs_ changed
    }
    if (!run->RecordsBlocked().empty()) NoteRefusedWrite(std::runtime_error(run->RecordsBlocked()));
    metrics_.framesWritten.Increment(frames);
    // Planners count pixels as results arrive, between collections.
    const JobRun::PixelTally pixels = run->TakeUnreportedPixels();
    metrics_.pixelsTraced.Increment(static_cast<double>(pixels.traced));
    metrics_.pixelsCopied.Increment(static_cast<double>(pixels.copied));
    if (run->Done()) done.push_back(id);
  }
  for (uint64_t id : done) FinishJob(id);
}

void Farm::DistrustWrongWorkers() {
  std::vector<ExactnessAudit::Verdict> verdicts;
  for (auto& [id, run] : runs_) {
    for (ExactnessAudit::Verdict& verdict : run->TakeVerdicts()) verdicts.push_back(std::move(verdict));
  }
  for (const ExactnessAudit::Verdict& verdict : verdicts) {
    const WorkerState* worker = dispatcher_.FindPrincipal(verdict.worker);
    const std::string name = worker ? worker->name : "a worker no longer connected";
    std::fprintf(stderr,
                 "coordinator: distrusted worker %s (%s): %s; it is banned and the frames its values reached are "
                 "traced again\n",
                 name.c_str(), verdict.worker.c_str(), verdict.why.c_str());
    if (dispatcher_.Distrust(verdict.worker, verdict.why)) {
      try {
        bans_.Add({verdict.worker, name, verdict.why, JobStore::SystemNowMs()});
      } catch (const std::exception& e) {
        // The ban holds in this process all the same; only a restart would forget it.
        std::fprintf(stderr, "coordinator: the ban of %s could not be kept in the store: %s\n",
                     verdict.worker.c_str(), e.what());
      }
    }
    for (auto& [id, run] : runs_) run->OnWorkerDistrusted(verdict.worker, name);
  }
}

void Farm::RouteStrandedChecks() {
  for (DispatchTask& task : dispatcher_.TakeStranded()) {
    auto run = runs_.find(task.jobId);
    if (run == runs_.end()) continue;
    const uint64_t jobId = task.jobId;
    try {
      run->second->TraceByReferee(std::move(task), store_);
    } catch (const std::exception& e) {
      FailJob(jobId, e.what());
    }
  }
}

bool Farm::LiftBan(const std::string& principal) {
  if (!bans_.Remove(principal)) return false;
  requests_.LiftBan(principal);
  return true;
}

void Farm::FinishJob(uint64_t jobId) {
  auto run = runs_.find(jobId);
  try {
    run->second->FinishWriting();
  } catch (const std::exception& e) {
    FailJob(jobId, e.what());
    return;
  }
  // Later auto jobs of this scene, or of its kind, are predicted with what this one measured.
  KeepScenePrices(*run->second);
  ClosingJob closing;
  closing.stats = run->second->Stats(/*final=*/true);
  CountError(closing.stats["error"]);
  if (std::optional<EventDraft> verified = VerificationEvent(closing.stats["error"])) {
    closing.events.push_back(std::move(*verified));
  }
  finishedTraced_ += run->second->tracedPixels();
  finishedPixels_ += run->second->tracedPixels() + run->second->copiedPixels();
  dispatcher_.RemoveJob(jobId);
  closing.run = std::move(run->second);
  runs_.erase(run);
  Close(jobId, std::move(closing));
}

void Farm::Close(uint64_t jobId, ClosingJob closing) {
  if (closing.run) {
    finisher_.Add(jobId, closing.run->firstFrame(), closing.run->lastFrame(), closing.run->previewView());
  }
  ClosingJob& stored = closing_[jobId] = std::move(closing);
  if (Settle(jobId, stored)) closing_.erase(jobId);
}

void Farm::SettleClosingJobs() {
  for (auto it = closing_.begin(); it != closing_.end();) {
    it = Settle(it->first, it->second) ? closing_.erase(it) : std::next(it);
  }
}

bool Farm::Settle(uint64_t jobId, ClosingJob& closing) {
  try {
    if (closing.run && !closing.run->RecordWrittenFrames(store_)) {
      NoteRefusedWrite(std::runtime_error(closing.run->RecordsBlocked()));
      return false;
    }
    if (!closing.failed) {
      if (store_.Complete(jobId, closing.stats, closing.events)) metrics_.jobsFinishedCompleted.Increment();
      return true;
    }
    // Said once every frame that made it to disk is recorded, so the record is the folder.
    std::string why = closing.why;
    if (closing.run) {
      if (std::optional<std::string> writeFailure = closing.run->WriteFailure()) why = *writeFailure;
      store_.SetStats(jobId, closing.run->Stats());
    }
    if (store_.Fail(jobId, why)) metrics_.jobsFinishedFailed.Increment();
    std::fprintf(stderr, "coordinator: job %llu failed: %s\n", static_cast<unsigned long long>(jobId), why.c_str());
    return true;
  } catch (const std::exception& e) {
    NoteRefusedWrite(e);
    return false;
  }
}

// Every refusal is counted; the log says so at most once per interval, not once a step.
void Farm::NoteRefusedWrite(const std::exception& error) {
  constexpr Milliseconds kRefusalLogInterval{10000};
  metrics_.jobStoreWritesRefused.Increment();
  const SteadyTime now = clock_.Now();
  if (lastRefusalLogged_ != SteadyTime{} && now - lastRefusalLogged_ < kRefusalLogInterval) return;
  lastRefusalLogged_ = now;
  std::fprintf(stderr, "coordinator: the job database refused a write; records are kept and retried: %s\n",
               error.what());
}

// The job's measured error, added to the farm-wide counters.
void Farm::CountError(const nlohmann::json& error) {
  const nlohmann::json& spot = error["spot_checks"];
  metrics_.spotCheckPixels.Increment(spot.value("pixels_checked", 0.0));
  metrics_.spotCheckMismatches.Increment(spot.value("mismatches", 0.0));
  if (error.contains("reference")) {
    const nlohmann::json& reference = error["reference"];
    metrics_.verifiedFrames.Increment(reference.value("frames_compared", 0.0));
    metrics_.verifiedPixelsDiffering.Increment(reference.value("pixels_differing", 0.0));
  }
  if (error.contains("suspect")) {
    metrics_.suspectJobs.Increment();
    metrics_.suspectPixels.Increment(error["suspect"].value("pixels_disagreeing", 0.0));
  }
  if (error.contains("audit")) {
    metrics_.framesRewritten.Increment(error["audit"].value("frames_rewritten", 0.0));
    metrics_.pixelsRewritten.Increment(error["audit"].value("pixels_rewritten", 0.0));
  }
}

void Farm::FailJob(uint64_t jobId, const std::string& why) {
  auto run = runs_.find(jobId);
  if (run == runs_.end()) return;
  dispatcher_.RemoveJob(jobId);
  try {
    run->second->FinishWriting();  // what is queued is written (or not), then recorded
  } catch (const std::exception&) {
  }
  ClosingJob closing;
  closing.run = std::move(run->second);
  closing.failed = true;
  closing.why = why;
  runs_.erase(run);
  Close(jobId, std::move(closing));
}

void Farm::UpdateMetrics() {
  const DispatcherCounters& c = dispatcher_.counters();
  metrics_.tasksDispatched.Increment(static_cast<double>(c.tasksSent - lastCounters_.tasksSent));
  metrics_.tasksRequeued.Increment(static_cast<double>(c.requeued - lastCounters_.requeued));
  metrics_.messagesMalformed.Increment(static_cast<double>(c.malformed - lastCounters_.malformed));
  metrics_.foreignReplies.Increment(static_cast<double>(c.foreignReplies - lastCounters_.foreignReplies));
  metrics_.workersDropped.Increment(static_cast<double>(c.workersDropped - lastCounters_.workersDropped));
  metrics_.workersDistrusted.Increment(
      static_cast<double>(c.workersDistrusted - lastCounters_.workersDistrusted));
  metrics_.tasksToReferee.Increment(static_cast<double>(c.tasksStranded - lastCounters_.tasksStranded));
  metrics_.taskErrorsRetried.Increment(static_cast<double>(c.taskErrorsRetried - lastCounters_.taskErrorsRetried));
  metrics_.workersRefusedKey.Increment(static_cast<double>(c.refusedKeys - lastCounters_.refusedKeys));
  metrics_.workersRefusedHandshake.Increment(
      static_cast<double>(c.failedHandshakes - lastCounters_.failedHandshakes));
  lastCounters_ = c;
  metrics_.queueDepth.Set(static_cast<double>(dispatcher_.PendingTasks()));
  metrics_.tasksInFlight.Set(static_cast<double>(dispatcher_.InFlightTasks()));
  metrics_.liveWorkers.Set(static_cast<double>(dispatcher_.registry().workers().size()));
  metrics_.runningJobs.Set(static_cast<double>(runs_.size()));
  if (finishedPixels_ > 0) {
    metrics_.tracedPixelRatio.Set(static_cast<double>(finishedTraced_) / finishedPixels_);
  }
}

void Farm::PublishSnapshot() {
  SteadyTime now = clock_.Now();
  lastSnapshot_ = now;
  FarmSnapshot snapshot;
  for (const auto& [identity, w] : dispatcher_.registry().workers()) {
    snapshot.workers.push_back({w.name, w.principal, w.capacity, w.threads,
                                static_cast<uint32_t>(w.inFlight.size()), w.tasksDone,
                                w.pixelsDone, w.traceSeconds, SecondsBetween(w.lastHeard, now),
                                SecondsBetween(w.connectedAt, now)});
  }
  for (const auto& [id, run] : runs_) {
    snapshot.runningStats[id] = run->Stats();
    snapshot.tracingFrames[id] = run->TracingFrames();
  }
  snapshot.queuedTasks = dispatcher_.PendingTasks();
  snapshot.inFlightTasks = dispatcher_.InFlightTasks();
  try {
    metrics_.queuedJobs.Set(static_cast<double>(store_.CountInState(JobState::kQueued)));
  } catch (const JobStoreError&) {
    // A read the disk refused: the gauge keeps its last value.
  }
  requests_.Publish(std::move(snapshot));
}

FarmSnapshot Farm::Snapshot() const { return requests_.Snapshot(); }

}  // namespace tcfarm
