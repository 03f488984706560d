// Reading animated values (constant, polynomial, keyframed) and motions (translation,
// rotation, scale about a pivot, parents inline or named), checked over the frame range.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/scene.h"

#include "proto/scene/parse/json_values.h"

namespace tcfarm::scene_parse {

// --- animated values -----------------------------------------------------------------

struct FrameRange {
  int first;
  int last;
  std::string Text() const { return "frames " + std::to_string(first) + ".." + std::to_string(last); }
};

const char* const kAnimatedExpected =
    "an animated vec3: [x, y, z], {\"polynomial\": [[...], [...], [...]]} or {\"keyframes\": [...]}";

std::vector<double> ReadCoefficients(const Node& node);

AnimatedVec3 ReadPolynomial(const Node& node);

const char* const kInterpolationExpected = "\"linear\", \"step\" or \"cubicspline\"";

// A keyframed value's "interpolation" (linear when absent).
Interpolation ReadInterpolation(const Node& keyed);

// Keyframes {"frame": f, "value": V} (with "in_tangent" and "out_tangent", per frame, for a
// cubic spline), frames strictly increasing; `readValue(node)` reads a V, `readTangent` a
// tangent, `valueText` shows a V.
template <typename Keyframe, typename ReadValue, typename ReadTangent>
std::vector<Keyframe> ReadKeys(const Node& keyed, const std::string& valueText, ReadValue readValue,
                               ReadTangent readTangent) {
  const Interpolation interpolation = ReadInterpolation(keyed);
  const Node node = keyed.Member("keyframes");
  const bool cubic = interpolation == Interpolation::kCubicSpline;
  const std::string keyText = "{\"frame\": number, \"value\": " + valueText +
                              (cubic ? ", \"in_tangent\": " + valueText + ", \"out_tangent\": " + valueText : "") + "}";
  if (!node.value.is_array() || node.value.empty()) FailType(node, "a non-empty array of " + keyText);
  std::vector<Keyframe> keys;
  for (size_t i = 0; i < node.value.size(); ++i) {
    Node key = node.Element(i);
    if (cubic) {
      ExpectObject(key, {"frame", "value", "in_tangent", "out_tangent"}, "a keyframe " + keyText);
    } else {
      ExpectObject(key, {"frame", "value"}, "a keyframe " + keyText);
    }
    Node frameNode = Required(key, "frame", "a finite frame number");
    double frame = ReadNumber(frameNode, "a finite frame number");
    if (!keys.empty() && frame <= keys.back().frame) {
      Fail(frameNode.pointer, "frame " + FormatNumber(frame) + " does not come after frame " +
                                  FormatNumber(keys.back().frame),
           "keyframes with strictly increasing frames");
    }
    Keyframe keyframe{frame, readValue(Required(key, "value", valueText))};
    if (key.Has("in_tangent")) keyframe.inTangent = readTangent(key.Member("in_tangent"));
    if (key.Has("out_tangent")) keyframe.outTangent = readTangent(key.Member("out_tangent"));
    keys.push_back(keyframe);
  }
  return keys;
}

AnimatedVec3 ReadKeyframes(const Node& keyed);

// Piecewise-linear keyframes reach their extremes over the integer frames of the range at
// the range's ends or next to a key, so a component-wise bound only needs those frames.
// A polynomial gives no such shortcut: every frame.
std::vector<double> ExtremeFrames(const AnimatedVec3& value, const FrameRange& range);

// Every frame the check must see: only the first when nothing changes.
std::vector<double> AllFrames(bool animated, const FrameRange& range);

// A cheap upper bound of |polynomial| over the range; when it is small, no frame needs
// evaluating.
bool PolynomialSurelyBounded(const AnimatedVec3& value, const FrameRange& range);

void CheckMagnitude(const AnimatedVec3& value, const Node& node, const FrameRange& range);

AnimatedVec3 ReadAnimated(const Node& node, const FrameRange& range);

// --- motion: translation, rotation, scale about a pivot --------------------------------

const char* const kQuaternionExpected = "a rotation quaternion [x, y, z, w] (glTF's order), not all zero";
const char* const kRotationExpected =
    "a rotation: a quaternion [x, y, z, w], {\"keyframes\": [{\"frame\": f, \"value\": [x, y, z, w]}, ...]}"
    " or a spin {\"axis\": [x, y, z], \"degrees_per_frame\": d, \"degrees\": d0}";
const char* const kMotionExpected =
    "a motion: an animated translation ([x, y, z], {\"polynomial\": ...} or {\"keyframes\": ...}) or "
    "{\"translation\", \"rotation\", \"scale\", \"pivot\"}";

Quaternion ReadQuaternion(const Node& node);

// Tangents are any quaternion-shaped values, zero included; keys must have a direction.
Quaternion ReadQuaternionTangent(const Node& node);

AnimatedRotation ReadRotationKeyframes(const Node& keyed);

AnimatedRotation ReadSpin(const Node& node);

AnimatedRotation ReadRotation(const Node& node);

void CheckScale(const AnimatedVec3& scale, const Node& node, const FrameRange& range);

bool IsTransformObject(const Node& node);

// The document's named transforms ("transforms"), which a transform's "parent" may name
// instead of holding its parent inline: a skeleton's joints then share their ancestors
// instead of each writing its whole chain.
class NamedTransforms {
 public:
  NamedTransforms() = default;
  NamedTransforms(const Node& table, const FrameRange& range);
  struct Resolved {
    std::shared_ptr<const Motion> motion;
    int levels;  // in its chain, itself included
  };
  // The transform named by `name` (a parent's string at `at`); fails naming `at` when the
  // table has none of that name, or when it is its own ancestor.
  Resolved Find(const Node& at) const;

 private:
  const json* table_ = nullptr;  // the document's, which outlives the reading
  std::string tablePointer_;
  FrameRange range_{};
  mutable std::map<std::string, Resolved> read_;
  mutable std::set<std::string> reading_;
};

Motion ReadMotion(const Node& node, const FrameRange& range, int depth = 0,
                  const NamedTransforms* named = nullptr, int* levels = nullptr);

void CheckNonNegative(const AnimatedVec3& value, const Node& node, const FrameRange& range);

}  // namespace tcfarm::scene_parse
