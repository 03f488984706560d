#include "coordinator/farm/price_book.h"

#include <algorithm>

namespace tcfarm {

SegmentPrices PriceBook::Record(const std::string& sceneHash, std::optional<bool> deforming,
                                const SegmentPrices& measured) {
  SegmentPrices kept;
  kept.startPrice = std::clamp(measured.startPrice, 1.0, 20.0);
  kept.framePrice = std::clamp(measured.framePrice, 0.001, 5.0);
  if (deforming) lastOfKind_[*deforming ? 1 : 0] = kept;
  last_ = kept;
  if (auto known = byScene_.find(sceneHash); known != byScene_.end()) {
    recent_.erase(known->second);
    byScene_.erase(known);
  }
  recent_.emplace_front(sceneHash, kept);
  byScene_[sceneHash] = recent_.begin();
  if (recent_.size() > capacity_) {
    byScene_.erase(recent_.back().first);
    recent_.pop_back();
  }
  return kept;
}

SegmentPrices PriceBook::Quote(const std::string& sceneHash, std::optional<bool> deforming) {
  if (auto known = byScene_.find(sceneHash); known != byScene_.end()) {
    recent_.splice(recent_.begin(), recent_, known->second);
    SegmentPrices prices = known->second->second;
    prices.source = PriceSource::kScene;
    return prices;
  }
  const std::optional<SegmentPrices>& ofKind = deforming ? lastOfKind_[*deforming ? 1 : 0] : last_;
  if (!ofKind) return SegmentPrices{};
  SegmentPrices prices = *ofKind;
  prices.source = PriceSource::kFarm;
  return prices;
}

}  // namespace tcfarm
