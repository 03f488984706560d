// The table of light kinds, built from TCFARM_LIGHT_KINDS in Light::Type's order.
#include "proto/scene/lights/light_format.h"

#include <array>

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
  for (size_t i = 0; i < Formats().size(); ++i) {
    if (name == Formats()[i]->Name()) return static_cast<Light::Type>(i);
  }
  return std::nullopt;
}

const std::string& LightTypeChoices() {
  static const std::string choices = [] {
    std::string joined;
    for (size_t i = 0; i < Formats().size(); ++i) {
      if (i > 0) joined += i + 1 == Formats().size() ? " or " : ", ";
      joined += "\"" + std::string(Formats()[i]->Name()) + "\"";
    }
    return joined;
  }();
  return choices;
}

}  // namespace tcfarm
