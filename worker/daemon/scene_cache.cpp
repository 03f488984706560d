#include "worker/daemon/scene_cache.h"

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

SceneCache::Built SceneCache::Build(const std::string& sceneJson, const AssetCache& assets, BuildStop stop) const {
  auto scene = std::make_unique<Scene>(ParseScene(sceneJson, std::nullopt, [stop] { ThrowIfStopRequested(stop); }));
  return Finish(std::move(scene), assets, stop);
}

SceneCache::Built SceneCache::Finish(std::unique_ptr<Scene> scene, const AssetCache& assets, BuildStop stop) const {
  Built built;
  for (Material& material : scene->materials) {
    material.ForEachTexture([&](Texture& texture, const std::string&) {
      if (texture.asset.empty()) return;
      if (auto file = assets.Find(texture.asset)) {
        texture.file = *file;
      } else {
        built.missingAssets.push_back(texture.asset);
      }
    });
  }
  built.scene = std::move(scene);
  if (!built.missingAssets.empty()) return built;
  PrepareForTracing(*built.scene);  // as the reference renderer does: the same bits
  ThrowIfStopRequested(stop);
  built.tracer = std::make_unique<Tracer>(device_, *built.scene, pool_, stop);
  return built;
}

Tracer* SceneCache::Insert(const std::string& hash, Built built) {
  entries_.push_front(Entry{hash, std::move(built)});
  while (entries_.size() > capacity_) entries_.pop_back();
  return entries_.front().built.tracer.get();
}

}  // namespace tcfarm
