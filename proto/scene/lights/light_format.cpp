// The table of light kinds, built from TCFARM_LIGHT_KINDS in Light::Type's order.
#include "proto/scene/lights/light_format.h"

#include <array>

#include "proto/scene/kind_table.h"

namespace tcfarm {
namespace {

const std::array<const LightFormat*, Light::kTypeCount>& Formats() {
#define TCFARM_LIGHT_FORMAT_ENTRY(Stem) &Stem##LightFormat(),
  static const std::array<const LightFormat*, Light::kTypeCount> formats{
      TCFARM_LIGHT_KINDS(TCFARM_LIGHT_FORMAT_ENTRY)};
#undef TCFARM_LIGHT_FORMAT_ENTRY
  return formats;
}

}  // namespace

const LightFormat& FormatOf(Light::Type type) { return *Formats().at(static_cast<size_t>(type)); }

std::optional<Light::Type> FindLightType(const std::string& name) {
  const std::optional<size_t> index = FindKindIndex(Formats(), name);
  return index ? std::optional(static_cast<Light::Type>(*index)) : std::nullopt;
}

const std::string& LightTypeChoices() {
  static const std::string choices = KindChoices(Formats());
  return choices;
}

}  // namespace tcfarm
