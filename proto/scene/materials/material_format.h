// What the scene format knows of one material model, behind one interface: which keys of a
// material object are its own, how it reads them (and checks them together) and how it
// writes them back. One file per model here (phong.cpp, metallic_roughness.cpp), each
// defining the <Stem>MaterialFormat() that TCFARM_MATERIAL_MODELS (material.h) names; the
// reader and the writer find a model through MaterialFormatOf alone.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/material.h"

namespace tcfarm {

namespace scene_parse {
class SceneReader;
struct Node;
}  // namespace scene_parse

class MaterialFormat {
 public:
  virtual ~MaterialFormat() = default;
  // The keys of a material object that belong to the model: naming any of them picks it.
  virtual const std::vector<std::string>& Keys() const = 0;
  // For the message that refuses two models in one material: one of its keys ("a Phong
  // parameter"), and all of them ("Phong's parameters").
  virtual const char* OneKey() const = 0;
  virtual const char* AllKeys() const = 0;
  // Reads the model's keys of material object `node` into `material.model`.
  virtual void Read(scene_parse::SceneReader& reader, const scene_parse::Node& node, Material& material) const = 0;
  // The material object's fields as the reader reads them back (the writer adds none).
  virtual nlohmann::json Write(const Material& material) const = 0;
};

#define TCFARM_DECLARE_MATERIAL_FORMAT(Stem) const MaterialFormat& Stem##MaterialFormat();
TCFARM_MATERIAL_MODELS(TCFARM_DECLARE_MATERIAL_FORMAT)
#undef TCFARM_DECLARE_MATERIAL_FORMAT

// The format of the model a material holds.
const MaterialFormat& MaterialFormatOf(const Material& material);

// Every model's format, in the list's order: the first is a material's default.
const std::vector<const MaterialFormat*>& MaterialFormats();

}  // namespace tcfarm
