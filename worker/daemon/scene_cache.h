// Scenes a worker has built, by content hash. A worker serves many jobs over its life;
// building a scene (parsing, BVH) costs far more than one task, so scenes stay cached
// until evicted by newer ones.
#pragma once

#include <list>
#include <memory>
#include <string>
#include <vector>

#include "worker/daemon/asset_cache.h"
#include "worker/tracing.h"
#include "proto/scene/scene.h"

namespace tcfarm {

class SceneCache {
 public:
  // Scenes kept built: several jobs share a farm, each with its own scene.
  static constexpr size_t kDefaultCapacity = 4;

  SceneCache(const EmbreeDevice& device, TracingThreads& pool, size_t capacity = kDefaultCapacity)
      : device_(device), pool_(pool), capacity_(capacity) {}

  // A scene parsed and built, not yet in the cache; or parsed only, waiting for the
  // assets it names (missingAssets) to arrive.
  struct Built {
    std::unique_ptr<Scene> scene;  // the tracer refers to it: keep it at a fixed address
    std::unique_ptr<Tracer> tracer;
    std::vector<std::string> missingAssets;  // hashes; the tracer is built only when none
  };

  // The tracer of a cached scene, or nullptr; a hit makes it most recently used.
  Tracer* Find(const std::string& hash);
  // Parses a scene received from the coordinator and, when `assets` holds every texture
  // it names, builds it. Throws SceneError (bad scene), TextureError, EmbreeError, or
  // BuildStopped once `stop` is set (util/build_stop.h). Safe beside tracing and the
  // cache's other calls: the worker builds scenes off its loop.
  Built Build(const std::string& sceneJson, const AssetCache& assets, BuildStop stop = nullptr) const;
  // Builds a parsed scene whose assets have arrived since (or reports the ones still missing).
  Built Finish(std::unique_ptr<Scene> scene, const AssetCache& assets, BuildStop stop = nullptr) const;
  // Caches a built scene, evicting the least recently used beyond capacity.
  Tracer* Insert(const std::string& hash, Built built);

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
