#include "daemon/scene_cache.h"

namespace tcfarm {

Tracer* SceneCache::Find(const std::string& hash) {
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    if (it->hash == hash) {
      entries_.splice(entries_.begin(), entries_, it);
      ++hits_;
      return entries_.front().tracer.get();
    }
  }
  ++misses_;
  return nullptr;
}

Tracer* SceneCache::Add(const std::string& hash, const std::string& sceneJson) {
  Entry entry;
  entry.hash = hash;
  entry.scene = std::make_unique<Scene>(ParseScene(sceneJson));
  RebaseOnCamera(*entry.scene);  // as the reference renderer does: the same bits
  entry.tracer = std::make_unique<Tracer>(device_, *entry.scene, pool_);
  entries_.push_front(std::move(entry));
  while (entries_.size() > capacity_) entries_.pop_back();
  return entries_.front().tracer.get();
}

}  // namespace tcfarm
