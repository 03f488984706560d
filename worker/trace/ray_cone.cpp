#include "worker/trace/ray_cone.h"

#include <cmath>

namespace tcfarm {

float Log2UvWidth(float coneWidth, float cosine, double uvArea, double worldArea) {
  if (!(coneWidth > 0) || !(uvArea > 0) || !(worldArea > 0)) return UvFootprint::kPoint;
  // A grazing ray's footprint stretches without bound: the last mip level takes it.
  const double across = std::fabs(static_cast<double>(cosine));
  const double log2Width = std::log2(static_cast<double>(coneWidth) / across) + 0.5 * std::log2(uvArea / worldArea);
  return std::isnan(log2Width) ? UvFootprint::kPoint : static_cast<float>(log2Width);
}

double UvArea2(const std::array<float, 2>* uvs, const std::array<uint32_t, 3>& corner) {
  const auto &a = uvs[corner[0]], &b = uvs[corner[1]], &c = uvs[corner[2]];
  const double du1 = static_cast<double>(b[0]) - a[0], dv1 = static_cast<double>(b[1]) - a[1];
  const double du2 = static_cast<double>(c[0]) - a[0], dv2 = static_cast<double>(c[1]) - a[1];
  return std::fabs(du1 * dv2 - du2 * dv1);
}

}  // namespace tcfarm
