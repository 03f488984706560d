// Scenes a worker has built, by content hash. A worker serves many jobs over its life;
// building a scene (parsing, BVH) costs far more than one task, so scenes stay cached
// until evicted by newer ones.
#pragma once

#include <list>
#include <memory>
#include <string>

#include "embree/device.h"
#include "scene/scene.h"
#include "trace/tracer.h"
#include "util/tracing_threads.h"

namespace tcfarm {

class SceneCache {
 public:
  // Scenes kept built: several jobs share a farm, each with its own scene.
  static constexpr size_t kDefaultCapacity = 4;

  SceneCache(const EmbreeDevice& device, TracingThreads& pool, size_t capacity = kDefaultCapacity)
      : device_(device), pool_(pool), capacity_(capacity) {}

  // A scene parsed and built, not yet in the cache.
  struct Built {
    std::unique_ptr<Scene> scene;  // the tracer refers to it: keep it at a fixed address
    std::unique_ptr<Tracer> tracer;
  };

  // The tracer of a cached scene, or nullptr; a hit makes it most recently used.
  Tracer* Find(const std::string& hash);
  // Parses and builds a scene received from the coordinator. Throws SceneError (bad
  // scene) or EmbreeError. Safe beside tracing and the cache's other calls: the worker
  // builds scenes off its loop.
  Built Build(const std::string& sceneJson) const;
  // Caches a built scene, evicting the least recently used beyond capacity.
  Tracer* Insert(const std::string& hash, Built built);
  // Build, then Insert; the cache is unchanged when the build throws.
  Tracer* Add(const std::string& hash, const std::string& sceneJson) { return Insert(hash, Build(sceneJson)); }

  uint64_t hits() const { return hits_; }
  uint64_t misses() const { return misses_; }

 private:
  struct Entry {
    std::string hash;
    Built built;
  };
  const EmbreeDevice& device_;
  TracingThreads& pool_;
  size_t capacity_;
  std::list<Entry> entries_;  // most recently used first
  uint64_t hits_ = 0, misses_ = 0;
};

}  // namespace tcfarm
