// A worker's own Prometheus metrics: what it traced, how fast, and how its scene cache
// and connection fare. Families are built once and their children kept, so the tracing
// loop only increments. Scraped at the worker's /metrics (see MetricsEndpoint).
#pragma once

#include <memory>

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/registry.h>

#include "worker/tracing.h"

namespace tcfarm {

struct WorkerMetrics {
  WorkerMetrics();

  // One finished task: its pixels, the rays it cast by type, its tracing time elapsed and
  // the CPU time of its tracing threads.
  void RecordTask(size_t pixels, const RayCounts& rays, double traceSeconds, double traceCpuSeconds);
  // Deforming meshes' work a task caused (posing is per frame, so most tasks add nothing).
  void RecordDeformation(const SceneGeometry::DeformationWork& work);

  std::shared_ptr<prometheus::Registry> registry;
  prometheus::Counter& tasks;
  prometheus::Counter& pixels;
  prometheus::Counter& traceSeconds;
  prometheus::Counter& traceCpuSeconds;
  prometheus::Counter& raysPrimary;
  prometheus::Counter& raysShadow;
  prometheus::Counter& raysReflection;
  prometheus::Counter& raysRefraction;
  prometheus::Counter& sceneCacheHits;    // tasks whose scene was already built
  prometheus::Counter& sceneCacheMisses;  // scenes fetched from the coordinator
  prometheus::Counter& sceneErrors;       // scenes that failed to build
  prometheus::Counter& assetsFetched;     // assets asked of the coordinator (not in the cache)
  prometheus::Counter& assetBytes;        // bytes of assets received
  prometheus::Counter& messagesMalformed;
  prometheus::Counter& reconnects;
  prometheus::Counter& handshakesRefused;  // connections the coordinator refused (CURVE keys)
  prometheus::Counter& posesComputed;     // deforming meshes posed (vertices deformed, tree refit)
  prometheus::Counter& posesShared;       // frames that reused a pose: joints and weights unchanged
  prometheus::Counter& verticesDeformed;  // vertices skinned or morphed
  prometheus::Gauge& raysPerSecond;  // rays / tracing second of the last task
  prometheus::Gauge& coordinatorUp;  // 1 while the coordinator answers
  prometheus::Gauge& threads;
  prometheus::Gauge& sceneBuilds;  // scene builds under way, stopped ones until they give up
};

}  // namespace tcfarm
