// The table of material models, built from TCFARM_MATERIAL_MODELS in the order of
// Material::model's alternatives.
#include "proto/scene/materials/material_format.h"

namespace tcfarm {

const std::vector<const MaterialFormat*>& MaterialFormats() {
#define TCFARM_MATERIAL_FORMAT_ENTRY(Stem) &Stem##MaterialFormat(),
  static const std::vector<const MaterialFormat*> formats{TCFARM_MATERIAL_MODELS(TCFARM_MATERIAL_FORMAT_ENTRY)};
#undef TCFARM_MATERIAL_FORMAT_ENTRY
  return formats;
}

const MaterialFormat& MaterialFormatOf(const Material& material) { return *MaterialFormats().at(material.model.index()); }

}  // namespace tcfarm
