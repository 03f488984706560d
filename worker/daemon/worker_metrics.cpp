#include "worker/daemon/worker_metrics.h"

#include "proto/metrics/metric_builders.h"

namespace tcfarm {
namespace {

prometheus::Family<prometheus::Counter>& RayFamily(prometheus::Registry& registry) {
  return NewCounterFamily(registry, "tcfarm_worker_rays_total",
                          "Rays cast by this worker, by ray type");
}

}  // namespace

WorkerMetrics::WorkerMetrics()
    : registry(std::make_shared<prometheus::Registry>()),
      tasks(NewCounter(*registry, "tcfarm_worker_tasks_total", "Tasks traced")),
      pixels(NewCounter(*registry, "tcfarm_worker_pixels_total", "Pixels traced")),
      traceSeconds(NewCounter(*registry, "tcfarm_worker_trace_seconds_total",
                              "Seconds spent tracing tasks")),
      traceCpuSeconds(NewCounter(*registry, "tcfarm_worker_trace_cpu_seconds_total",
                                 "CPU seconds of the tracing threads, summed over threads")),
      raysPrimary(RayFamily(*registry).Add({{"type", "primary"}})),
      raysShadow(RayFamily(*registry).Add({{"type", "shadow"}})),
      raysReflection(RayFamily(*registry).Add({{"type", "reflection"}})),
      raysRefraction(RayFamily(*registry).Add({{"type", "refraction"}})),
      sceneCacheHits(NewCounter(*registry, "tcfarm_worker_scene_cache_hits_total",
                                "Tasks whose scene was already built")),
      sceneCacheMisses(NewCounter(*registry, "tcfarm_worker_scene_cache_misses_total",
                                  "Scenes fetched from the coordinator and built")),
      sceneErrors(NewCounter(*registry, "tcfarm_worker_scene_errors_total",
                             "Scenes that could not be built")),
      assetsFetched(NewCounter(*registry, "tcfarm_worker_assets_fetched_total",
                               "Assets (texture images) asked of the coordinator because the cache lacked them")),
      assetBytes(NewCounter(*registry, "tcfarm_worker_asset_bytes_total", "Bytes of assets received")),
      messagesMalformed(NewCounter(*registry, "tcfarm_worker_messages_malformed_total",
                                   "Inbound messages dropped as malformed")),
      reconnects(NewCounter(*registry, "tcfarm_worker_reconnects_total",
                            "Reconnections after the coordinator went silent")),
      handshakesRefused(NewCounter(*registry, "tcfarm_worker_handshakes_refused_total",
                                   "Connections whose handshake the coordinator refused (keys, CURVE)")),
      posesComputed(NewCounter(*registry, "tcfarm_worker_poses_total",
                               "Poses of deforming meshes computed: vertices skinned or morphed, tree refit")),
      posesShared(NewCounter(*registry, "tcfarm_worker_poses_shared_total",
                             "Frames whose deforming mesh reused a pose: joints and weights unchanged")),
      verticesDeformed(NewCounter(*registry, "tcfarm_worker_vertices_deformed_total",
                                  "Vertices skinned or morphed")),
      raysPerSecond(NewGauge(*registry, "tcfarm_worker_rays_per_second",
                             "Rays per second of tracing time, last task")),
      coordinatorUp(NewGauge(*registry, "tcfarm_worker_coordinator_up",
                             "1 while the coordinator answers, 0 while it is silent")),
      threads(NewGauge(*registry, "tcfarm_worker_threads", "Tracing threads")),
      sceneBuilds(NewGauge(*registry, "tcfarm_worker_scene_builds",
                           "Scene builds under way (a stopped one until it has given up)")) {}

void WorkerMetrics::RecordDeformation(const SceneGeometry::DeformationWork& work) {
  posesComputed.Increment(static_cast<double>(work.posesComputed));
  posesShared.Increment(static_cast<double>(work.posesShared));
  verticesDeformed.Increment(static_cast<double>(work.verticesDeformed));
}

void WorkerMetrics::RecordTask(size_t pixelCount, const RayCounts& rays, double seconds,
                               double cpuSeconds) {
  tasks.Increment();
  pixels.Increment(static_cast<double>(pixelCount));
  traceSeconds.Increment(seconds);
  traceCpuSeconds.Increment(cpuSeconds);
  raysPrimary.Increment(static_cast<double>(rays.primary));
  raysShadow.Increment(static_cast<double>(rays.shadow));
  raysReflection.Increment(static_cast<double>(rays.reflection));
  raysRefraction.Increment(static_cast<double>(rays.refraction));
  if (seconds > 0) raysPerSecond.Set(static_cast<double>(rays.Total()) / seconds);
}

}  // namespace tcfarm
