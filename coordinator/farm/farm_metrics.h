// The coordinator's Prometheus metrics. Families are built once and their children kept,
// so the hot path only increments. No job or task ids as labels: their cardinality grows
// without bound; per-job figures live in the job records of the HTTP API instead.
#pragma once

#include <memory>

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

namespace tcfarm {

struct FarmMetrics {
  FarmMetrics();

  std::shared_ptr<prometheus::Registry> registry;
  prometheus::Counter& pixelsTraced;
  prometheus::Counter& pixelsCopied;
  prometheus::Counter& tasksDispatched;
  prometheus::Counter& taskResults;
  prometheus::Counter& tasksRequeued;
  prometheus::Counter& messagesMalformed;
  prometheus::Counter& foreignReplies;
  prometheus::Counter& workersDropped;
  prometheus::Counter& taskErrorsRetried;
  prometheus::Counter& workersRefusedKey;
  prometheus::Counter& workersRefusedHandshake;
  prometheus::Counter& framesWritten;
  prometheus::Counter& raysPrimary;
  prometheus::Counter& raysShadow;
  prometheus::Counter& raysReflection;
  prometheus::Counter& raysRefraction;
  prometheus::Counter& jobsFinishedCompleted;
  prometheus::Counter& jobsFinishedFailed;
  prometheus::Counter& jobsFinishedCanceled;
  prometheus::Counter& spotCheckPixels;
  prometheus::Counter& spotCheckMismatches;
  prometheus::Counter& verifiedFrames;
  prometheus::Counter& verifiedPixelsDiffering;
  prometheus::Counter& suspectJobs;  // jobs promising exactness whose checks disagreed
  prometheus::Counter& suspectPixels;
  prometheus::Counter& workersDistrusted;  // found returning wrong values by the referee
  prometheus::Counter& tasksToReferee;     // checks no other worker could take (TakeStranded)
  prometheus::Counter& framesRewritten;    // traced again because of them, and different
  prometheus::Counter& pixelsRewritten;
  prometheus::Counter& jobStoreWritesRefused;  // the farm loop's, retried later
  prometheus::Histogram& taskLatency;
  prometheus::Gauge& queueDepth;      // tasks waiting for a worker
  prometheus::Gauge& tasksInFlight;
  prometheus::Gauge& liveWorkers;
  prometheus::Gauge& runningJobs;
  prometheus::Gauge& queuedJobs;
  prometheus::Gauge& tracedPixelRatio;  // of the jobs finished so far, pixels traced / pixels
};

}  // namespace tcfarm
