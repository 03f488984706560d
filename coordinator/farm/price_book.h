// The segment prices exact jobs measured (planner/segment_plan.h), for auto's model of the
// next job: a scene's own where the farm measured it, else the last exact job's of the same
// kind of scene, else the priors. Prices differ most between scenes whose meshes deform
// (every deforming triangle shortens horizons) and scenes whose meshes are rigid, so that
// is the kind.
//
// Bounded: the last measurement of at most `capacity` scenes, the one longest not measured
// or asked for forgotten first. Owned by the farm loop; not thread-safe.
#pragma once

#include <cstddef>
#include <list>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>

#include "coordinator/planner/segment_plan.h"

namespace tcfarm {

class PriceBook {
 public:
  static constexpr size_t kDefaultCapacity = 1024;
  explicit PriceBook(size_t capacity = kDefaultCapacity) : capacity_(capacity < 1 ? 1 : capacity) {}

  // What an exact job measured on the scene (its content hash), kept within what a segment
  // can cost: a job of a few frames or a noisy machine measures outliers. Returns them so.
  // deforming: nullopt when the job's kind is unknown (stored before the farm kept it).
  SegmentPrices Record(const std::string& sceneHash, std::optional<bool> deforming, const SegmentPrices& measured);
  // The prices for a job of this scene, their source said. deforming: nullopt for a job
  // stored before the farm kept its kind; the farm's last job of either kind then.
  SegmentPrices Quote(const std::string& sceneHash, std::optional<bool> deforming);
  size_t Scenes() const { return byScene_.size(); }

 private:
  using Entry = std::pair<std::string, SegmentPrices>;
  size_t capacity_;
  std::list<Entry> recent_;  // most recently measured or asked first
  std::unordered_map<std::string, std::list<Entry>::iterator> byScene_;
  std::optional<SegmentPrices> lastOfKind_[2];  // [deforming]
  std::optional<SegmentPrices> last_;
};

}  // namespace tcfarm
