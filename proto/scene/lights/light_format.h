// What the scene format knows of one kind of light, behind one interface: how it is read
// from scene JSON and written back, and how it moves with the world (TranslateScene). One
// file per kind here (point.cpp, directional.cpp, spot.cpp), each defining the
// <Stem>LightFormat() that TCFARM_LIGHT_KINDS (scene.h) names; the reader, the writer and
// scene.cpp find a kind through FormatOf and FindLightType alone.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

namespace tcfarm {

namespace scene_parse {
class SceneReader;
struct Node;
}  // namespace scene_parse

class LightFormat {
 public:
  virtual ~LightFormat() = default;
  // The kind's "type" in scene JSON.
  virtual const char* Name() const = 0;
  // Whether the kind has a position (which moves with the world) and a direction.
  virtual bool HasPosition() const = 0;
  virtual bool HasDirection() const = 0;
  // Refuses any key of `node` the kind does not take, then reads the kind's own fields
  // into `light`; the reader reads those every light has after ("motion", "range" where
  // the kind took it, "intensity").
  virtual void Read(scene_parse::SceneReader& reader, const scene_parse::Node& node, Light& light) const = 0;
  // The kind's own fields as the parser reads them back (the writer adds the common ones).
  virtual nlohmann::json Write(const Light& light) const = 0;
  // Moves the light's own place by `offset` with the world (its motion is the caller's).
  virtual void Translate(Light&, const Vec3&) const {}
};

#define TCFARM_DECLARE_LIGHT_FORMAT(Stem) const LightFormat& Stem##LightFormat();
TCFARM_LIGHT_KINDS(TCFARM_DECLARE_LIGHT_FORMAT)
#undef TCFARM_DECLARE_LIGHT_FORMAT

const LightFormat& FormatOf(Light::Type type);

// The type a scene's "type" names; none for a name no kind has.
std::optional<Light::Type> FindLightType(const std::string& name);

// Every kind's name, for messages: "\"point\", \"directional\" or \"spot\"".
const std::string& LightTypeChoices();

}  // namespace tcfarm
