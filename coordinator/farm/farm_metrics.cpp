#include "coordinator/farm/farm_metrics.h"

#include "proto/metrics/metric_builders.h"

namespace tcfarm {
namespace {

prometheus::Family<prometheus::Counter>& RayFamily(prometheus::Registry& registry) {
  return NewCounterFamily(registry, "tcfarm_rays_total",
                          "Rays cast by the workers for this coordinator, by ray type");
}

prometheus::Family<prometheus::Counter>& RefusedFamily(prometheus::Registry& registry) {
  return NewCounterFamily(registry, "tcfarm_workers_refused_total",
                          "Connections to the workers' socket refused by CURVE authentication, by reason");
}

prometheus::Family<prometheus::Counter>& JobsFamily(prometheus::Registry& registry) {
  return NewCounterFamily(registry, "tcfarm_jobs_finished_total",
                          "Jobs that reached a final state, by state");
}

// Task latency buckets from 1 ms to ~16 s: a task is sized for tens of milliseconds.
prometheus::Histogram::BucketBoundaries LatencyBuckets() {
  prometheus::Histogram::BucketBoundaries buckets;
  for (double b = 0.001; b < 20; b *= 2) buckets.push_back(b);
  return buckets;
}

}  // namespace

FarmMetrics::FarmMetrics()
    : registry(std::make_shared<prometheus::Registry>()),
      pixelsTraced(NewCounter(*registry, "tcfarm_pixels_traced_total",
                              "Pixels computed by ray tracing")),
      pixelsCopied(NewCounter(*registry, "tcfarm_pixels_copied_total",
                              "Pixels copied from another frame instead of traced")),
      tasksDispatched(NewCounter(*registry, "tcfarm_tasks_dispatched_total",
                                 "Tasks sent to workers, requeued ones included")),
      taskResults(NewCounter(*registry, "tcfarm_task_results_total",
                             "Task results accepted from workers")),
      tasksRequeued(NewCounter(*registry, "tcfarm_tasks_requeued_total",
                               "Tasks taken back (dead, silent or dropped workers, a worker's error) and requeued")),
      messagesMalformed(NewCounter(*registry, "tcfarm_messages_malformed_total",
                                   "Inbound messages dropped as malformed")),
      foreignReplies(NewCounter(*registry, "tcfarm_task_replies_foreign_total",
                                "RESULT or ERROR messages for a task in flight with another worker, dropped")),
      workersDropped(NewCounter(*registry, "tcfarm_workers_dropped_total",
                                "Workers forgotten and told DISCONNECT for a malformed result of their own task")),
      taskErrorsRetried(NewCounter(*registry, "tcfarm_task_errors_retried_total",
                                   "Tasks a worker could not trace, sent to a different worker")),
      workersRefusedKey(RefusedFamily(*registry).Add({{"reason", "key_not_allowed"}})),
      workersRefusedHandshake(RefusedFamily(*registry).Add({{"reason", "handshake_failed"}})),
      framesWritten(NewCounter(*registry, "tcfarm_frames_written_total",
                               "Finished frames handed to the frame store")),
      raysPrimary(RayFamily(*registry).Add({{"type", "primary"}})),
      raysShadow(RayFamily(*registry).Add({{"type", "shadow"}})),
      raysReflection(RayFamily(*registry).Add({{"type", "reflection"}})),
      raysRefraction(RayFamily(*registry).Add({{"type", "refraction"}})),
      jobsFinishedCompleted(JobsFamily(*registry).Add({{"state", "completed"}})),
      jobsFinishedFailed(JobsFamily(*registry).Add({{"state", "failed"}})),
      jobsFinishedCanceled(JobsFamily(*registry).Add({{"state", "canceled"}})),
      spotCheckPixels(NewCounter(*registry, "tcfarm_spot_check_pixels_total",
                                 "Copied pixels traced again to estimate error (finished jobs)")),
      spotCheckMismatches(NewCounter(*registry, "tcfarm_spot_check_mismatches_total",
                                     "Spot-checked copied pixels that differed from a trace")),
      verifiedFrames(NewCounter(*registry, "tcfarm_verified_frames_total",
                                "Frames compared with a brute-force reference (finished jobs)")),
      verifiedPixelsDiffering(NewCounter(*registry, "tcfarm_verified_pixels_differing_total",
                                         "Pixels of verified frames that differ from the reference")),
      suspectJobs(NewCounter(*registry, "tcfarm_suspect_jobs_total",
                             "Finished jobs whose strategy promises 0 wrong pixels (exact, brute) but whose "
                             "checks found pixels that disagree: a bug or a worker returning wrong values")),
      suspectPixels(NewCounter(*registry, "tcfarm_suspect_pixels_total",
                               "Pixels of such jobs that checks found disagreeing")),
      workersDistrusted(NewCounter(*registry, "tcfarm_workers_distrusted_total",
                                   "Workers the coordinator's own trace of a disputed check showed returning "
                                   "wrong values: banned by principal until an admin lifts it")),
      tasksToReferee(NewCounter(*registry, "tcfarm_tasks_traced_by_referee_total",
                                "Checks and repairs no connected worker could take (every one of them was "
                                "checked by it), traced by the coordinator's referee")),
      framesRewritten(NewCounter(*registry, "tcfarm_frames_rewritten_total",
                                 "Frames their values reached, traced again by another worker and rewritten "
                                 "because they differed (finished jobs)")),
      pixelsRewritten(NewCounter(*registry, "tcfarm_pixels_rewritten_total",
                                 "Pixels those rewrites changed (finished jobs)")),
      jobStoreWritesRefused(NewCounter(*registry, "tcfarm_job_store_writes_refused_total",
                                       "Writes of the farm loop the job database refused (disk full or "
                                       "failing); each is retried until it succeeds")),
      taskLatency(prometheus::BuildHistogram()
                      .Name("tcfarm_task_latency_seconds")
                      .Help("From sending a task to receiving its result")
                      .Register(*registry)
                      .Add({}, LatencyBuckets())),
      queueDepth(NewGauge(*registry, "tcfarm_tasks_queued", "Tasks waiting for a worker")),
      tasksInFlight(NewGauge(*registry, "tcfarm_tasks_in_flight", "Tasks held by workers")),
      liveWorkers(NewGauge(*registry, "tcfarm_workers_live", "Workers connected and alive")),
      runningJobs(NewGauge(*registry, "tcfarm_jobs_running", "Jobs being rendered")),
      queuedJobs(NewGauge(*registry, "tcfarm_jobs_queued", "Jobs waiting to start")),
      tracedPixelRatio(NewGauge(*registry, "tcfarm_traced_pixel_ratio",
                                "Pixels traced / pixels rendered, over the jobs finished")) {}

}  // namespace tcfarm
