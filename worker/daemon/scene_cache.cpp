#include "daemon/scene_cache.h"

namespace tcfarm {

Tracer* SceneCache::Find(const std::string& hash) {
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    if (it->hash == hash) {
      entries_.splice(entries_.begin(), entries_, it);
      ++hits_;
      return entries_.front().built.tracer.get();
    }
  }
  ++misses_;
  return nullptr;
}

SceneCache::Built SceneCache::Build(const std::string& sceneJson) const {
  Built built;
  built.scene = std::make_unique<Scene>(ParseScene(sceneJson));
  PrepareForTracing(*built.scene);  // as the reference renderer does: the same bits
  built.tracer = std::make_unique<Tracer>(device_, *built.scene, pool_);
  return built;
}

Tracer* SceneCache::Insert(const std::string& hash, Built built) {
  entries_.push_front(Entry{hash, std::move(built)});
  while (entries_.size() > capacity_) entries_.pop_back();
  return entries_.front().built.tracer.get();
}

}  // namespace tcfarm
