// Scene JSON -> Scene, Scene -> JSON; mesh "file" references go to the OBJ reader
// (scene/import/obj_reader.h).
//
// The parser is strict on purpose: a scene comes from a user over the network and is then
// trusted by every worker, so each value is checked where it is read, and each error names
// the JSON pointer of the value and what would have been accepted there.
#include <algorithm>
#include <cctype>
#include <iterator>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <system_error>
#include <utility>

#include <nlohmann/json.hpp>

#include "scene/scene.h"

#include "json/strict_json.h"
#include "scene/import/obj_reader.h"
#include "scene/import/scene_files.h"
#include "scene/import/scene_import.h"
#include "scene/scene_limits.h"
#include "wire/content_hash.h"

namespace tcfarm {
namespace {

using nlohmann::json;
using namespace scene_limits;

constexpr size_t kMaxPolynomialTerms = 8;
constexpr int kMaxTerrainCells = 2000;
// sin of the smallest angle between view direction and up that still gives a usable
// camera basis; below it the basis is dominated by rounding.
constexpr double kMinUpSine = 1e-9;
// A triangle or quad whose edges' cross product is this small relative to the edges has
// no area worth tracing.
constexpr double kMinAreaRatio = 1e-12;
// A view direction this short relative to the camera's coordinates is rounding noise.
constexpr double kMinViewRatio = 1e-12;

[[noreturn]] void Fail(const std::string& pointer, const std::string& problem, const std::string& expected) {
  throw SceneError(pointer, problem + "; expected " + expected);
}

// --- small text helpers ------------------------------------------------------------

std::string FormatNumber(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  // Whole numbers read better without nlohmann's ".0"; below 2^53 they print exactly.
  if (std::floor(value) == value && std::fabs(value) < 9007199254740992.0) {
    return std::to_string(static_cast<long long>(value));
  }
  return json(value).dump();
}


std::string Quote(const std::string& text) {
  constexpr size_t kMaxShown = 40;
  std::string shown = text.size() > kMaxShown ? text.substr(0, kMaxShown) + "..." : text;
  return json(shown).dump(-1, ' ', false, json::error_handler_t::replace);
}

// What a value is, for "got ..." messages.
std::string Describe(const json& value) {
  switch (value.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::boolean:
      return std::string("the boolean ") + (value.get<bool>() ? "true" : "false");
    case json::value_t::string:
      return "the string " + Quote(value.get<std::string>());
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
    case json::value_t::number_float:
      return "the number " + FormatNumber(value.get<double>());
    case json::value_t::array:
      return "an array of " + std::to_string(value.size()) + " elements";
    case json::value_t::object:
      return "an object";
    default:
      return "an unsupported value";
  }
}

// How a number was written, for "<value> is negative" messages: integers stay integers.
std::string Show(const json& number) {
  return number.is_number_float() ? FormatNumber(number.get<double>()) : number.dump();
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string joined;
  for (const auto& name : names) joined += (joined.empty() ? "" : ", ") + name;
  return joined;
}

json ParseJson(const std::string& text) {
  try {
    return ParseStrictJson(text);
  } catch (const JsonInputError& error) {
    Fail(error.pointer(), error.problem(), error.expected());
  }
}

// --- reading values with their pointers -----------------------------------------------

// A JSON value and where it sits in the document, so every check can name it.
struct Node {
  const json& value;
  std::string pointer;

  Node Member(const std::string& key) const { return Node{value.at(key), pointer + "/" + EscapePointerToken(key)}; }
  Node Element(size_t index) const { return Node{value.at(index), pointer + "/" + std::to_string(index)}; }
  std::string MemberPointer(const std::string& key) const { return pointer + "/" + EscapePointerToken(key); }
  bool Has(const std::string& key) const { return value.contains(key); }
};

[[noreturn]] void FailType(const Node& node, const std::string& expected) {
  Fail(node.pointer, "got " + Describe(node.value), expected);
}

// Objects list the keys they accept: a misspelt key is an error, never silently ignored.
void ExpectObject(const Node& node, const std::vector<std::string>& allowed, const std::string& expected) {
  if (!node.value.is_object()) FailType(node, expected);
  for (const auto& member : node.value.items()) {
    if (std::find(allowed.begin(), allowed.end(), member.key()) == allowed.end()) {
      Fail(node.MemberPointer(member.key()), "unknown field " + Quote(member.key()),
           "one of the fields " + JoinNames(allowed));
    }
  }
}

Node Required(const Node& object, const std::string& key, const std::string& expected) {
  if (!object.Has(key)) Fail(object.MemberPointer(key), "missing", expected);
  return object.Member(key);
}

void ExpectArray(const Node& node, size_t size, const std::string& expected) {
  if (!node.value.is_array() || node.value.size() != size) FailType(node, expected);
}

double ReadNumber(const Node& node, const std::string& expected) {
  if (!node.value.is_number()) FailType(node, expected);
  double value = node.value.get<double>();
  if (!std::isfinite(value)) Fail(node.pointer, FormatNumber(value) + " is not finite", expected);
  if (std::fabs(value) > kMaxMagnitude) {
    Fail(node.pointer, Show(node.value) + " exceeds 1e30 in magnitude", expected);
  }
  return value;
}

double ReadNonNegative(const Node& node, const std::string& expected) {
  double value = ReadNumber(node, expected);
  if (value < 0) Fail(node.pointer, Show(node.value) + " is negative", expected);
  return value;
}

double ReadPositive(const Node& node, const std::string& expected) {
  double value = ReadNonNegative(node, expected);
  if (value == 0) Fail(node.pointer, Show(node.value) + " is zero", expected);
  return value;
}

double ReadInRange(const Node& node, double low, double high, const std::string& expected) {
  double value = ReadNumber(node, expected);
  if (value < low || value > high) Fail(node.pointer, Show(node.value) + " is out of range", expected);
  return value;
}

bool IsIntegral(const json& value) {
  if (value.is_number_integer()) return true;  // both signed and unsigned
  if (!value.is_number_float()) return false;
  double number = value.get<double>();
  return std::isfinite(number) && std::floor(number) == number;
}

int64_t ReadInteger(const Node& node, int64_t low, int64_t high) {
  std::string expected = "an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
  if (!IsIntegral(node.value)) FailType(node, expected);
  // The limits are far below 2^53, so comparing as double is exact where it matters.
  double value = node.value.get<double>();
  if (value < static_cast<double>(low) || value > static_cast<double>(high)) {
    Fail(node.pointer, Show(node.value) + " is out of range", expected);
  }
  return static_cast<int64_t>(value);
}

int ReadInt(const Node& node, int low, int high) { return static_cast<int>(ReadInteger(node, low, high)); }

const char* const kVec3Expected = "an array of 3 finite numbers [x, y, z]";

Vec3 ReadVec3(const Node& node, const std::string& expected = kVec3Expected) {
  ExpectArray(node, 3, expected);
  Vec3 result;
  for (int axis = 0; axis < 3; ++axis) result[axis] = ReadNumber(node.Element(static_cast<size_t>(axis)), expected);
  return result;
}

Vec3 ReadColour(const Node& node) {
  const std::string expected = "an array of 3 non-negative finite numbers [r, g, b]";
  ExpectArray(node, 3, expected);
  Vec3 result;
  for (int axis = 0; axis < 3; ++axis) {
    result[axis] = ReadNonNegative(node.Element(static_cast<size_t>(axis)), expected);
  }
  return result;
}

std::string ReadString(const Node& node, const std::string& expected) {
  if (!node.value.is_string()) FailType(node, expected);
  return node.value.get<std::string>();
}

// --- vector helpers ------------------------------------------------------------------

Vec3 Subtract(const Vec3& a, const Vec3& b) { return Vec3{a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 Cross(const Vec3& a, const Vec3& b) {
  return Vec3{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double Length(const Vec3& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }
double MaxAbs(const Vec3& v) { return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}); }
std::string FormatVec3(const Vec3& v) {
  return "[" + FormatNumber(v.x) + ", " + FormatNumber(v.y) + ", " + FormatNumber(v.z) + "]";
}

// Squared lengths below the smallest normal double cannot be normalised reliably.
bool IsZeroLength(const Vec3& v) { return v.x * v.x + v.y * v.y + v.z * v.z < std::numeric_limits<double>::min(); }

bool IsDegenerate(const Vec3& edgeA, const Vec3& edgeB) {
  return Length(Cross(edgeA, edgeB)) <= kMinAreaRatio * Length(edgeA) * Length(edgeB) || IsZeroLength(edgeA) ||
         IsZeroLength(edgeB);
}

// --- animated values -----------------------------------------------------------------

struct FrameRange {
  int first;
  int last;
  std::string Text() const { return "frames " + std::to_string(first) + ".." + std::to_string(last); }
};

const char* const kAnimatedExpected =
    "an animated vec3: [x, y, z], {\"polynomial\": [[...], [...], [...]]} or {\"keyframes\": [...]}";

std::vector<double> ReadCoefficients(const Node& node) {
  const std::string expected = "an array of 1 to 8 finite coefficients c0, c1, ... (value = sum c_k * frame^k)";
  if (!node.value.is_array() || node.value.empty() || node.value.size() > kMaxPolynomialTerms) {
    FailType(node, expected);
  }
  std::vector<double> coefficients;
  for (size_t k = 0; k < node.value.size(); ++k) coefficients.push_back(ReadNumber(node.Element(k), expected));
  return coefficients;
}

AnimatedVec3 ReadPolynomial(const Node& node) {
  ExpectArray(node, 3, "an array of 3 coefficient arrays, one per axis");
  std::array<std::vector<double>, 3> coefficients;
  for (size_t axis = 0; axis < 3; ++axis) coefficients[axis] = ReadCoefficients(node.Element(axis));
  return AnimatedVec3::Polynomial(std::move(coefficients));
}

const char* const kInterpolationExpected = "\"linear\", \"step\" or \"cubicspline\"";

// A keyframed value's "interpolation" (linear when absent).
Interpolation ReadInterpolation(const Node& keyed) {
  if (!keyed.Has("interpolation")) return Interpolation::kLinear;
  Node node = keyed.Member("interpolation");
  const std::string name = ReadString(node, kInterpolationExpected);
  if (name == "linear") return Interpolation::kLinear;
  if (name == "step") return Interpolation::kStep;
  if (name == "cubicspline") return Interpolation::kCubicSpline;
  Fail(node.pointer, "unknown interpolation " + Quote(name), kInterpolationExpected);
}

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

AnimatedVec3 ReadKeyframes(const Node& keyed) {
  auto read = [](const Node& value) { return ReadVec3(value); };
  return AnimatedVec3::Keyframes(ReadKeys<AnimatedVec3::Keyframe>(keyed, "[x, y, z]", read, read),
                                 ReadInterpolation(keyed));
}

// Piecewise-linear keyframes reach their extremes over the integer frames of the range at
// the range's ends or next to a key, so a component-wise bound only needs those frames.
// A polynomial gives no such shortcut: every frame.
std::vector<double> ExtremeFrames(const AnimatedVec3& value, const FrameRange& range) {
  std::vector<double> frames{static_cast<double>(range.first), static_cast<double>(range.last)};
  // A polynomial, or a cubic spline, which may overshoot its keys: every frame.
  if (value.kind() == AnimatedVec3::Kind::kPolynomial ||
      (value.kind() == AnimatedVec3::Kind::kKeyframes && value.interpolation() == Interpolation::kCubicSpline)) {
    for (int frame = range.first + 1; frame < range.last; ++frame) frames.push_back(frame);
  } else if (value.kind() == AnimatedVec3::Kind::kKeyframes) {
    for (const auto& key : value.keys()) {
      for (double frame : {std::floor(key.frame), std::ceil(key.frame)}) {
        if (frame >= range.first && frame <= range.last) frames.push_back(frame);
      }
    }
  }
  return frames;
}

// Every frame the check must see: only the first when nothing changes.
std::vector<double> AllFrames(bool animated, const FrameRange& range) {
  std::vector<double> frames{static_cast<double>(range.first)};
  if (!animated) return frames;
  for (int frame = range.first + 1; frame <= range.last; ++frame) frames.push_back(frame);
  return frames;
}

// A cheap upper bound of |polynomial| over the range; when it is small, no frame needs
// evaluating.
bool PolynomialSurelyBounded(const AnimatedVec3& value, const FrameRange& range) {
  double reach = std::max(std::fabs(static_cast<double>(range.first)), std::fabs(static_cast<double>(range.last)));
  for (const auto& axis : value.coefficients()) {
    double bound = 0;
    double power = 1;
    for (double coefficient : axis) {
      bound += std::fabs(coefficient) * power;
      power *= reach;
    }
    // Headroom for the rounding of Horner's evaluation.
    if (!(bound <= kMaxMagnitude / 2)) return false;
  }
  return true;
}

void CheckMagnitude(const AnimatedVec3& value, const Node& node, const FrameRange& range) {
  if (value.kind() == AnimatedVec3::Kind::kPolynomial && PolynomialSurelyBounded(value, range)) return;
  for (double frame : ExtremeFrames(value, range)) {
    Vec3 v = value.Evaluate(frame);
    if (!(MaxAbs(v) <= kMaxMagnitude)) {
      Fail(node.pointer, "evaluates to " + FormatVec3(v) + " at frame " + FormatNumber(frame),
           "finite values of magnitude at most 1e30 over " + range.Text());
    }
  }
}

AnimatedVec3 ReadAnimated(const Node& node, const FrameRange& range) {
  AnimatedVec3 result;
  if (node.value.is_array()) {
    result = AnimatedVec3::Constant(ReadVec3(node, kAnimatedExpected));
  } else if (node.value.is_object()) {
    ExpectObject(node, {"polynomial", "keyframes", "interpolation"}, kAnimatedExpected);
    if (node.Has("polynomial") == node.Has("keyframes")) {
      if (node.Has("polynomial")) Fail(node.pointer, "both \"polynomial\" and \"keyframes\"", "exactly one of them");
      FailType(node, kAnimatedExpected);
    }
    if (node.Has("polynomial") && node.Has("interpolation")) {
      Fail(node.MemberPointer("interpolation"), "an interpolation for a polynomial", "interpolation only with keyframes");
    }
    result = node.Has("polynomial") ? ReadPolynomial(node.Member("polynomial")) : ReadKeyframes(node);
  } else {
    FailType(node, kAnimatedExpected);
  }
  CheckMagnitude(result, node, range);
  return result;
}

// --- motion: translation, rotation, scale about a pivot --------------------------------

const char* const kQuaternionExpected = "a rotation quaternion [x, y, z, w] (glTF's order), not all zero";
const char* const kRotationExpected =
    "a rotation: a quaternion [x, y, z, w], {\"keyframes\": [{\"frame\": f, \"value\": [x, y, z, w]}, ...]}"
    " or a spin {\"axis\": [x, y, z], \"degrees_per_frame\": d, \"degrees\": d0}";
const char* const kMotionExpected =
    "a motion: an animated translation ([x, y, z], {\"polynomial\": ...} or {\"keyframes\": ...}) or "
    "{\"translation\", \"rotation\", \"scale\", \"pivot\"}";

Quaternion ReadQuaternion(const Node& node) {
  ExpectArray(node, 4, kQuaternionExpected);
  Quaternion q{ReadNumber(node.Element(3), kQuaternionExpected), ReadNumber(node.Element(0), kQuaternionExpected),
               ReadNumber(node.Element(1), kQuaternionExpected), ReadNumber(node.Element(2), kQuaternionExpected)};
  double squared = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
  if (!(squared >= 1e-12) || !std::isfinite(squared)) {
    Fail(node.pointer, "quaternion " + Show(node.value) + " has no usable length", kQuaternionExpected);
  }
  return q;
}

// Tangents are any quaternion-shaped values, zero included; keys must have a direction.
Quaternion ReadQuaternionTangent(const Node& node) {
  ExpectArray(node, 4, "a tangent [x, y, z, w] per frame");
  return {ReadNumber(node.Element(3), "a finite number"), ReadNumber(node.Element(0), "a finite number"),
          ReadNumber(node.Element(1), "a finite number"), ReadNumber(node.Element(2), "a finite number")};
}

AnimatedRotation ReadRotationKeyframes(const Node& keyed) {
  auto keys = ReadKeys<AnimatedRotation::Keyframe>(keyed, "[x, y, z, w]", ReadQuaternion, ReadQuaternionTangent);
  return AnimatedRotation::Keyframes(std::move(keys), ReadInterpolation(keyed));
}

AnimatedRotation ReadSpin(const Node& node) {
  ExpectObject(node, {"axis", "degrees_per_frame", "degrees"}, kRotationExpected);
  Node axisNode = Required(node, "axis", "a non-zero rotation axis [x, y, z]");
  Vec3 axis = ReadVec3(axisNode);
  if (IsZeroLength(axis)) Fail(axisNode.pointer, "zero-length axis", "a non-zero rotation axis [x, y, z]");
  const std::string degreesExpected = "finite degrees of magnitude at most 1e9";
  double perFrame = ReadInRange(Required(node, "degrees_per_frame", degreesExpected), -1e9, 1e9, degreesExpected);
  double atZero = node.Has("degrees") ? ReadInRange(node.Member("degrees"), -1e9, 1e9, degreesExpected) : 0;
  return AnimatedRotation::Spin(axis, perFrame, atZero);
}

AnimatedRotation ReadRotation(const Node& node) {
  if (node.value.is_array()) return AnimatedRotation::Constant(ReadQuaternion(node));
  if (!node.value.is_object()) FailType(node, kRotationExpected);
  if (node.Has("keyframes")) {
    ExpectObject(node, {"keyframes", "interpolation"}, kRotationExpected);
    return ReadRotationKeyframes(node);
  }
  return ReadSpin(node);
}

void CheckScale(const AnimatedVec3& scale, const Node& node, const FrameRange& range) {
  for (double frame : AllFrames(scale.IsAnimated(), range)) {
    Vec3 s = scale.Evaluate(frame);
    for (int axis = 0; axis < 3; ++axis) {
      double magnitude = std::fabs(s[axis]);
      if (!(magnitude >= kMinScale && magnitude <= kMaxScale)) {
        Fail(node.pointer, "scale " + FormatVec3(s) + " at frame " + FormatNumber(frame),
             "scale components of magnitude in [1e-6, 1e6] at every frame (negative mirrors)");
      }
    }
  }
}

bool IsTransformObject(const Node& node) {
  if (!node.value.is_object()) return false;
  for (const char* key : {"translation", "rotation", "scale", "pivot", "parent"}) {
    if (node.Has(key)) return true;
  }
  return false;
}

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

NamedTransforms::NamedTransforms(const Node& table, const FrameRange& range)
    : table_(&table.value), tablePointer_(table.pointer), range_(range) {
  if (!table.value.is_object()) FailType(table, "an object mapping names to transforms");
  // Every entry is read and checked, named by a parent or not.
  for (const auto& entry : table.value.items()) Find(Node{json(entry.key()), table.MemberPointer(entry.key())});
}

NamedTransforms::Resolved NamedTransforms::Find(const Node& at) const {
  const std::string name = at.value.get<std::string>();
  if (auto found = read_.find(name); found != read_.end()) return found->second;
  if (!table_ || !table_->contains(name)) {
    Fail(at.pointer, "no transform named " + Quote(name),
         table_ ? "the name of a transform in the scene's \"transforms\"" : "a parent transform object (the scene has no \"transforms\")");
  }
  if (!reading_.insert(name).second) {
    Fail(at.pointer, "transform " + Quote(name) + " is its own ancestor", "a hierarchy without cycles");
  }
  // The names being read are the chain above this one: refused here, before reading
  // deeper, a long chain cannot run the parser out of stack.
  if (reading_.size() > static_cast<size_t>(kMaxMotionDepth)) {
    Fail(at.pointer, "a hierarchy deeper than " + std::to_string(kMaxMotionDepth) + " levels",
         "at most " + std::to_string(kMaxMotionDepth) + " nested parents");
  }
  const Node entry = Node{*table_, tablePointer_}.Member(name);
  if (!IsTransformObject(entry)) FailType(entry, "a transform {\"translation\", \"rotation\", \"scale\", \"pivot\", \"parent\"}");
  int levels = 1;
  Resolved resolved{std::make_shared<const Motion>(ReadMotion(entry, range_, 0, this, &levels)), levels};
  reading_.erase(name);
  return read_[name] = resolved;
}

Motion ReadMotion(const Node& node, const FrameRange& range, int depth, const NamedTransforms* named, int* levels) {
  Motion motion;
  if (!IsTransformObject(node)) {
    if (!node.value.is_array() && !node.value.is_object()) FailType(node, kMotionExpected);
    motion.translation = ReadAnimated(node, range);
    return motion;
  }
  ExpectObject(node, {"translation", "rotation", "scale", "pivot", "parent"}, kMotionExpected);
  if (node.Has("translation")) motion.translation = ReadAnimated(node.Member("translation"), range);
  if (node.Has("rotation")) motion.rotation = ReadRotation(node.Member("rotation"));
  if (node.Has("scale")) {
    motion.scale = ReadAnimated(node.Member("scale"), range);
    CheckScale(motion.scale, node.Member("scale"), range);
  }
  if (node.Has("pivot")) motion.pivot = ReadVec3(node.Member("pivot"));
  if (node.Has("parent")) {
    Node parent = node.Member("parent");
    auto tooDeep = [&] {
      Fail(parent.pointer, "a hierarchy deeper than " + std::to_string(kMaxMotionDepth) + " levels",
           "at most " + std::to_string(kMaxMotionDepth) + " nested parents");
    };
    if (depth + 1 >= kMaxMotionDepth) tooDeep();
    int parentLevels = 1;
    if (parent.value.is_string()) {
      NamedTransforms::Resolved found = (named ? *named : NamedTransforms()).Find(parent);
      if (depth + 1 + found.levels > kMaxMotionDepth) tooDeep();
      motion.parent = found.motion, parentLevels = found.levels;
    } else {
      if (!IsTransformObject(parent)) {
        FailType(parent, "a parent transform {\"translation\", \"rotation\", \"scale\", \"pivot\", \"parent\"} or the name of one in \"transforms\"");
      }
      motion.parent = std::make_shared<const Motion>(ReadMotion(parent, range, depth + 1, named, &parentLevels));
    }
    if (levels) *levels = 1 + parentLevels;
  }
  return motion;
}

void CheckNonNegative(const AnimatedVec3& value, const Node& node, const FrameRange& range) {
  for (double frame : ExtremeFrames(value, range)) {
    Vec3 v = value.Evaluate(frame);
    if (v.x < 0 || v.y < 0 || v.z < 0) {
      Fail(node.pointer, "has a negative component " + FormatVec3(v) + " at frame " + FormatNumber(frame),
           "non-negative intensity components");
    }
  }
}

// --- the scene ------------------------------------------------------------------------

const char* const kDefaultMaterial = "default";

class SceneReader {
 public:
  SceneReader(std::optional<std::filesystem::path> baseDirectory, Checkpoint checkpoint = {})
      : baseDirectory_(std::move(baseDirectory)), checkpoint_(std::move(checkpoint)) {}

  Scene Read(const json& document) {
    Node root{document, ""};
    ExpectObject(root,
                 {"import", "camera", "lights", "materials", "meshes", "transforms", "shapes", "background", "render"},
                 "a scene object");
    // An imported file is the base the rest of the document adds to (proto/scene.md, "Importing").
    Scene scene = root.Has("import") ? ReadImport(root) : Scene{};
    const bool imported = root.Has("import");
    sharedMeshes_ = scene.meshes;
    if (!imported || root.Has("render")) {
      scene.render = ReadRender(Required(root, "render", "render settings {\"width\", \"height\", ...}"),
                                imported ? std::optional(scene.render) : std::nullopt);
    }
    range_ = FrameRange{scene.render.firstFrame, scene.render.LastFrame()};
    if (root.Has("transforms")) named_ = NamedTransforms(root.Member("transforms"), range_);
    scene.materials = ReadMaterials(root, std::move(scene.materials));
    if (!imported || root.Has("camera")) {
      scene.camera = ReadCamera(Required(root, "camera", "a camera {\"position\", \"look_at\", ...}"));
    }
    if (root.Has("lights")) Append(scene.lights, ReadLights(root.Member("lights")));
    if (root.Has("meshes")) AddSharedMeshes(scene, root.Member("meshes"));
    if (root.Has("shapes")) Append(scene.shapes, ReadShapes(root.Member("shapes")));
    if (root.Has("background")) scene.background = ReadColour(root.Member("background"));
    // Terrain meshes are generated only once the whole scene is known to be valid: a
    // rejected scene should cost no geometry.
    for (Shape& shape : scene.shapes) {
      if (shape.type == Shape::Type::kTerrain) shape.mesh = GenerateTerrain(shape.terrain, checkpoint_);
    }
    return scene;
  }

 private:
  template <typename T>
  static void Append(std::vector<T>& to, std::vector<T> more) {
    to.insert(to.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
  }

  // import ---------------------------------------------------------------------------

  // {"import": {"file": "shot.glb", "animation", "camera", "fps"}}: the file's scene, read
  // by its importer with the render size and samples the document asks for (a glTF
  // camera's aspect follows the size).
  Scene ReadImport(const Node& root) {
    const Node node = root.Member("import");
    const std::string expected = "{\"file\": a glTF or OBJ file in the scene's folder, \"animation\", \"camera\", \"fps\"}";
    ExpectObject(node, {"file", "animation", "camera", "fps"}, expected);
    const Node file = Required(node, "file", expected);
    const std::string name = ReadString(file, "a glTF or OBJ file inside the scene folder");
    if (!baseDirectory_) {
      Fail(file.pointer, "file " + Quote(name) + " cannot be resolved: the scene was submitted without a folder",
           "the file uploaded with the scene (tcfarm submit uploads the files a scene names)");
    }
    const std::filesystem::path path = ResolveInsideFolder(*baseDirectory_, name, file.pointer, "imported file");
    std::string extension = path.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
    // By extension only: a scene that sniffed as JSON could import itself.
    if (extension != ".gltf" && extension != ".glb" && extension != ".obj") {
      Fail(file.pointer, Quote(name) + " is not a glTF or OBJ file", "a .gltf, .glb or .obj file; tcfarm scenes do not nest");
    }
    const ImportOptions options = ReadImportOptions(root, node);
    try {
      return ImportScene(path, options);
    } catch (const SceneError& error) {
      throw SceneError(file.pointer, error.what());
    }
  }

  ImportOptions ReadImportOptions(const Node& root, const Node& node) const {
    ImportOptions options;
    if (node.Has("fps")) options.framesPerSecond = ReadInRange(node.Member("fps"), kMinFramesPerSecond, kMaxFramesPerSecond, "frames per second");
    for (const char* key : {"animation", "camera"}) {
      if (!node.Has(key)) continue;
      const Node choice = node.Member(key);
      if (!choice.value.is_string() && !IsIntegral(choice.value)) FailType(choice, "a name or an index");
      (std::string(key) == "animation" ? options.animation : options.camera) =
          choice.value.is_string() ? choice.value.get<std::string>() : std::to_string(choice.value.get<int64_t>());
    }
    if (root.Has("render") && root.value["render"].is_object()) {
      const Node render = root.Member("render");
      if (render.Has("width")) options.width = ReadInt(render.Member("width"), 1, kMaxImageSide);
      if (render.Has("height")) options.height = ReadInt(render.Member("height"), 1, kMaxImageSide);
      if (render.Has("samples_per_pixel")) options.samplesPerPixel = ReadInt(render.Member("samples_per_pixel"), 1, kMaxSamplesPerPixel);
    }
    return options;
  }

  // render ---------------------------------------------------------------------------

  // base: an imported scene's settings, which the document's override field by field
  // (width and height then optional).
  RenderSettings ReadRender(const Node& node, const std::optional<RenderSettings>& base = std::nullopt) {
    ExpectObject(node, {"width", "height", "frames", "samples_per_pixel", "max_depth"}, "render settings");
    RenderSettings render = base.value_or(RenderSettings{});
    const std::string sideExpected = "an integer in [1, " + std::to_string(kMaxImageSide) + "]";
    if (!base || node.Has("width")) render.width = ReadInt(Required(node, "width", sideExpected), 1, kMaxImageSide);
    if (!base || node.Has("height")) render.height = ReadInt(Required(node, "height", sideExpected), 1, kMaxImageSide);
    if (node.Has("frames")) {
      Node frames = node.Member("frames");
      ExpectObject(frames, {"start", "count"}, "{\"start\": first frame, \"count\": number of frames}");
      if (frames.Has("start")) render.firstFrame = ReadInt(frames.Member("start"), 0, kMaxFirstFrame);
      if (frames.Has("count")) render.frameCount = ReadInt(frames.Member("count"), 1, kMaxFrameCount);
    }
    if (node.Has("samples_per_pixel")) render.samplesPerPixel = ReadInt(node.Member("samples_per_pixel"), 1, kMaxSamplesPerPixel);
    if (node.Has("max_depth")) render.maxDepth = ReadInt(node.Member("max_depth"), 0, kMaxBounceDepth);
    return render;
  }

  // materials ------------------------------------------------------------------------

  // base: an imported scene's materials, "default" first; the document's add to them, or
  // replace one of the same name.
  std::vector<Material> ReadMaterials(const Node& root, std::vector<Material> base) {
    std::vector<Material> materials = std::move(base);
    if (materials.empty()) {
      materials.push_back(Material{});
      materials[0].name = kDefaultMaterial;
    }
    for (size_t i = 0; i < materials.size(); ++i) materialIndex_[materials[i].name] = static_cast<int>(i);
    if (!root.Has("materials")) return materials;
    Node node = root.Member("materials");
    if (!node.value.is_object()) FailType(node, "an object mapping material names to materials");
    for (const auto& entry : node.value.items()) {
      Material material = ReadMaterial(node.Member(entry.key()));
      material.name = entry.key();
      // A user "default" replaces the built-in one, so a written scene reads back the same;
      // a material named like an imported one replaces it.
      if (auto known = materialIndex_.find(material.name); known != materialIndex_.end()) {
        materials[static_cast<size_t>(known->second)] = material;
      } else {
        materialIndex_[material.name] = static_cast<int>(materials.size());
        materials.push_back(material);
      }
    }
    return materials;
  }

  Material ReadMaterial(const Node& node) {
    ExpectObject(node, {"diffuse", "specular", "shininess", "reflectivity", "transparency", "ior", "diffuse_texture",
                        "emission"},
                 "a material");
    Material material;
    if (node.Has("diffuse_texture")) material.diffuseTexture = ReadTexture(node.Member("diffuse_texture"));
    if (node.Has("diffuse")) material.diffuse = ReadColour(node.Member("diffuse"));
    if (node.Has("emission")) material.emission = ReadColour(node.Member("emission"));
    if (node.Has("specular")) material.specular = ReadColour(node.Member("specular"));
    if (node.Has("shininess")) {
      material.shininess = ReadNonNegative(node.Member("shininess"), "a non-negative Phong exponent");
    }
    if (node.Has("reflectivity")) {
      material.reflectivity = ReadInRange(node.Member("reflectivity"), 0, 1, "a number in [0, 1]");
    }
    if (node.Has("transparency")) {
      material.transparency = ReadInRange(node.Member("transparency"), 0, 1, "a number in [0, 1]");
    }
    if (node.Has("ior")) {
      material.indexOfRefraction = ReadInRange(node.Member("ior"), kMinIndexOfRefraction, kMaxIndexOfRefraction, "an index of refraction in [1, 10]");
    }
    if (material.reflectivity + material.transparency > 1) {
      Fail(node.MemberPointer(node.Has("transparency") ? "transparency" : "reflectivity"),
           "reflectivity " + FormatNumber(material.reflectivity) + " + transparency " +
               FormatNumber(material.transparency) + " exceeds 1",
           "reflectivity + transparency <= 1 (they share the light that is not absorbed)");
    }
    return material;
  }

  Texture ReadTexture(const Node& node) {
    const std::string expected =
        "a texture {\"image\": file or \"asset\": SHA-256, \"wrap_s\", \"wrap_t\", \"filter\"}";
    ExpectObject(node, {"image", "asset", "wrap_s", "wrap_t", "filter"}, expected);
    if (node.Has("image") == node.Has("asset")) {
      Fail(node.pointer, node.Has("image") ? "both an image and an asset" : "neither an image nor an asset",
           "exactly one of \"image\" (a file inside the scene folder) and \"asset\" (the SHA-256 of an image the farm holds)");
    }
    Texture texture;
    if (node.Has("asset")) {
      Node asset = node.Member("asset");
      texture.asset = ReadString(asset, "the SHA-256 of an image file, 64 lowercase hex characters");
      if (!wire::IsSha256Hex(texture.asset)) {
        Fail(asset.pointer, Quote(texture.asset) + " is not a SHA-256", "64 lowercase hex characters");
      }
    } else {
      ReadTextureFile(node.Member("image"), texture);
    }
    const std::string wrapExpected = "\"repeat\", \"clamp_to_edge\" or \"mirrored_repeat\"";
    for (const char* key : {"wrap_s", "wrap_t"}) {
      if (!node.Has(key)) continue;
      Node wrap = node.Member(key);
      const std::string name = ReadString(wrap, wrapExpected);
      Texture::Wrap mode = name == "repeat"          ? Texture::Wrap::kRepeat
                           : name == "clamp_to_edge" ? Texture::Wrap::kClampToEdge
                           : name == "mirrored_repeat" ? Texture::Wrap::kMirroredRepeat
                                                     : (Fail(wrap.pointer, "unknown wrap mode " + Quote(name), wrapExpected),
                                                        Texture::Wrap::kRepeat);
      (std::string(key) == "wrap_s" ? texture.wrapS : texture.wrapT) = mode;
    }
    if (node.Has("filter")) {
      Node filter = node.Member("filter");
      const std::string name = ReadString(filter, "\"linear\" or \"nearest\"");
      if (name != "linear" && name != "nearest") Fail(filter.pointer, "unknown filter " + Quote(name), "\"linear\" or \"nearest\"");
      texture.filter = name == "nearest" ? Texture::Filter::kNearest : Texture::Filter::kLinear;
    }
    return texture;
  }

  void ReadTextureFile(const Node& image, Texture& texture) {
    texture.image = ReadString(image, "a PNG or JPEG file inside the scene folder");
    if (!baseDirectory_) {
      Fail(image.pointer, "texture image " + Quote(texture.image) + " cannot be resolved: the scene was submitted without a folder",
           "an image uploaded with the scene (tcfarm submit uploads the files a scene names), or {\"asset\": its SHA-256}");
    }
    texture.file = ResolveInsideFolder(*baseDirectory_, texture.image, image.pointer, "texture image");
    std::error_code error;
    if (!std::filesystem::is_regular_file(texture.file, error)) {
      Fail(image.pointer, "cannot read texture image " + Quote(texture.image), "a readable image file inside the scene folder");
    }
  }

  // camera ---------------------------------------------------------------------------

  Camera ReadCamera(const Node& node) {
    ExpectObject(node, {"position", "look_at", "up", "fov_degrees", "motion", "projection", "ortho_height"}, "a camera");
    Camera camera;
    if (node.Has("motion")) camera.rig = ReadMotion(node.Member("motion"), range_, 0, &named_);
    camera.position = ReadAnimated(Required(node, "position", kAnimatedExpected), range_);
    camera.lookAt = ReadAnimated(Required(node, "look_at", kAnimatedExpected), range_);
    if (node.Has("up")) camera.up = ReadVec3(node.Member("up"));
    if (IsZeroLength(camera.up)) Fail(node.MemberPointer("up"), "zero-length up vector", "a non-zero up direction");
    if (node.Has("fov_degrees")) {
      Node fov = node.Member("fov_degrees");
      camera.verticalFovDegrees = ReadNumber(fov, "a vertical field of view in (0, 180) degrees");
      if (camera.verticalFovDegrees <= 0 || camera.verticalFovDegrees >= 180) {
        Fail(fov.pointer, Show(fov.value) + " is out of range", "a vertical field of view in (0, 180) degrees");
      }
    }
    ReadProjection(node, camera);
    CheckCameraBasis(camera, node);
    return camera;
  }

  void ReadProjection(const Node& node, Camera& camera) const {
    const std::string expected = "\"perspective\" or \"orthographic\"";
    if (node.Has("projection")) {
      Node projection = node.Member("projection");
      const std::string name = ReadString(projection, expected);
      if (name != "perspective" && name != "orthographic") {
        Fail(projection.pointer, "unknown projection " + Quote(name), expected);
      }
      camera.orthographic = name == "orthographic";
    }
    if (node.Has("ortho_height")) {
      Node height = node.Member("ortho_height");
      if (!camera.orthographic) {
        Fail(height.pointer, "an orthographic height for a perspective camera", "ortho_height only with \"projection\": \"orthographic\"");
      }
      camera.orthographicHeight = ReadInRange(height, 1e-9, 1e9, "a positive height of the image plane in [1e-9, 1e9]");
    }
  }

  void CheckCameraBasis(const Camera& camera, const Node& node) const {
    for (double frame : AllFrames(camera.Moves(), range_)) {
      const CameraPose pose = camera.At(frame);
      const Vec3& position = pose.position;
      const Vec3& lookAt = pose.lookAt;
      Vec3 view = Subtract(lookAt, position);
      if (IsZeroLength(view) || Length(view) <= kMinViewRatio * std::max(MaxAbs(position), MaxAbs(lookAt))) {
        Fail(node.MemberPointer("look_at"), "look_at equals position " + FormatVec3(position) + " at frame " +
                                                FormatNumber(frame),
             "a look_at point distinct from the camera position at every frame");
      }
      if (Length(Cross(view, pose.up)) <= kMinUpSine * Length(view) * Length(pose.up)) {
        Fail(node.MemberPointer("up"), "up " + FormatVec3(pose.up) + " is parallel to the view direction " +
                                           FormatVec3(view) + " at frame " + FormatNumber(frame),
             "an up vector not parallel to the view direction");
      }
    }
  }

  // lights ---------------------------------------------------------------------------

  std::vector<Light> ReadLights(const Node& node) {
    if (!node.value.is_array()) FailType(node, "an array of lights");
    std::vector<Light> lights;
    for (size_t i = 0; i < node.value.size(); ++i) lights.push_back(ReadLight(node.Element(i)));
    return lights;
  }

  Light ReadLight(const Node& node) {
    const std::string expected = "a light {\"type\": \"point\", \"directional\" or \"spot\", ...}";
    if (!node.value.is_object()) FailType(node, expected);
    const std::string typeExpected = "\"point\", \"directional\" or \"spot\"";
    std::string type = ReadString(Required(node, "type", typeExpected), typeExpected);
    Light light;
    if (type == "point") {
      ExpectObject(node, {"type", "position", "intensity", "motion"}, "a point light");
      light.type = Light::Type::kPoint;
      light.position = ReadAnimated(Required(node, "position", kAnimatedExpected), range_);
    } else if (type == "directional") {
      ExpectObject(node, {"type", "direction", "intensity", "motion"}, "a directional light");
      light.type = Light::Type::kDirectional;
      Node direction = Required(node, "direction", kAnimatedExpected);
      light.direction = ReadAnimated(direction, range_);
      CheckDirection(light.direction, direction);
    } else if (type == "spot") {
      ExpectObject(node, {"type", "position", "direction", "intensity", "inner_cone_degrees", "outer_cone_degrees", "motion"},
                   "a spot light");
      light.type = Light::Type::kSpot;
      light.position = ReadAnimated(Required(node, "position", kAnimatedExpected), range_);
      Node direction = Required(node, "direction", kAnimatedExpected);
      light.direction = ReadAnimated(direction, range_);
      CheckDirection(light.direction, direction);
      ReadCone(node, light);
    } else {
      Fail(node.MemberPointer("type"), "unknown light type " + Quote(type), typeExpected);
    }
    if (node.Has("motion")) light.motion = ReadMotion(node.Member("motion"), range_, 0, &named_);
    Node intensity = Required(node, "intensity", kAnimatedExpected);
    light.intensity = ReadAnimated(intensity, range_);
    CheckNonNegative(light.intensity, intensity, range_);
    return light;
  }

  // glTF's bounds: 0 <= inner < outer <= 90 degrees.
  void ReadCone(const Node& node, Light& light) const {
    const std::string outerExpected = "an outer cone angle in (0, 90] degrees from the axis";
    if (node.Has("outer_cone_degrees")) {
      Node outer = node.Member("outer_cone_degrees");
      light.outerConeDegrees = ReadNumber(outer, outerExpected);
      if (!(light.outerConeDegrees > 0 && light.outerConeDegrees <= 90)) {
        Fail(outer.pointer, Show(outer.value) + " is out of range", outerExpected);
      }
    }
    if (node.Has("inner_cone_degrees")) {
      Node inner = node.Member("inner_cone_degrees");
      const std::string innerExpected = "an inner cone angle in [0, outer_cone_degrees) degrees";
      light.innerConeDegrees = ReadNumber(inner, innerExpected);
      if (!(light.innerConeDegrees >= 0 && light.innerConeDegrees < light.outerConeDegrees)) {
        Fail(inner.pointer, Show(inner.value) + " is not below the outer cone's " + FormatNumber(light.outerConeDegrees),
             innerExpected);
      }
    }
  }

  void CheckDirection(const AnimatedVec3& direction, const Node& node) const {
    for (double frame : AllFrames(direction.IsAnimated(), range_)) {
      if (IsZeroLength(direction.Evaluate(frame))) {
        Fail(node.pointer, "zero-length direction at frame " + FormatNumber(frame), "a non-zero direction");
      }
    }
  }

  // shapes ---------------------------------------------------------------------------

  std::vector<Shape> ReadShapes(const Node& node) {
    if (!node.value.is_array()) FailType(node, "an array of shapes");
    std::vector<Shape> shapes;
    for (size_t i = 0; i < node.value.size(); ++i) shapes.push_back(ReadShape(node.Element(i)));
    return shapes;
  }

  Shape ReadShape(const Node& node) {
    const std::string typeExpected = "\"sphere\", \"quad\", \"mesh\" or \"terrain\"";
    if (!node.value.is_object()) FailType(node, "a shape {\"type\": " + typeExpected + ", ...}");
    std::string type = ReadString(Required(node, "type", typeExpected), typeExpected);
    Shape shape;
    if (type == "sphere") {
      ReadSphere(node, shape);
    } else if (type == "quad") {
      ReadQuad(node, shape);
    } else if (type == "mesh") {
      ReadMesh(node, shape);
    } else if (type == "terrain") {
      ReadTerrain(node, shape);
    } else {
      Fail(node.MemberPointer("type"), "unknown shape type " + Quote(type), typeExpected);
    }
    ReadCommonShapeFields(node, shape);
    return shape;
  }

  static std::vector<std::string> ShapeFields(std::vector<std::string> specific) {
    specific.insert(specific.begin(), {"type", "name", "material", "motion"});
    return specific;
  }

  void ReadCommonShapeFields(const Node& node, Shape& shape) {
    if (node.Has("name")) shape.name = ReadString(node.Member("name"), "a string");
    if (node.Has("motion")) shape.motion = ReadMotion(node.Member("motion"), range_, 0, &named_);
    if (node.Has("material")) {
      Node material = node.Member("material");
      std::string name = ReadString(material, "the name of a material");
      auto found = materialIndex_.find(name);
      if (found == materialIndex_.end()) Fail(material.pointer, "unknown material " + Quote(name), MaterialChoices());
      shape.material = found->second;
    }
  }

  std::string MaterialChoices() const {
    std::vector<std::string> names;
    for (const auto& entry : materialIndex_) names.push_back(Quote(entry.first));
    return "one of the materials " + JoinNames(names);
  }

  void ReadSphere(const Node& node, Shape& shape) {
    ExpectObject(node, ShapeFields({"center", "radius"}), "a sphere");
    shape.type = Shape::Type::kSphere;
    shape.center = ReadVec3(Required(node, "center", kVec3Expected));
    shape.radius = ReadPositive(Required(node, "radius", "a positive finite number"), "a positive finite number");
  }

  void ReadQuad(const Node& node, Shape& shape) {
    ExpectObject(node, ShapeFields({"corner", "edge_u", "edge_v"}), "a quad");
    shape.type = Shape::Type::kQuad;
    shape.corner = ReadVec3(Required(node, "corner", kVec3Expected));
    shape.edgeU = ReadVec3(Required(node, "edge_u", kVec3Expected));
    shape.edgeV = ReadVec3(Required(node, "edge_v", kVec3Expected));
    if (IsDegenerate(shape.edgeU, shape.edgeV)) {
      Fail(node.pointer, "edge_u x edge_v is zero: the quad has no area",
           "edge_u and edge_v non-zero and not parallel");
    }
  }

  void ReadMesh(const Node& node, Shape& shape) {
    ExpectObject(node, ShapeFields({"vertices", "triangles", "normals", "uvs", "colors", "file", "mesh_ref", "skin", "morph"}),
                 "a mesh");
    shape.type = Shape::Type::kMesh;
    if (node.Has("mesh_ref")) {
      ReadMeshRef(node, shape);
    } else {
      shape.mesh = ReadMeshGeometry(node);
    }
    ReadDeformation(node, shape);
  }

  // --- deforming meshes (deformation.h) ---

  void ReadDeformation(const Node& node, Shape& shape) const {
    if (!node.Has("skin") && !node.Has("morph")) return;
    auto deformation = std::make_shared<Deformation>();
    if (node.Has("morph")) {
      deformation->hasMorph = true;
      deformation->morph = ReadMorph(node.Member("morph"));
    }
    if (node.Has("skin")) {
      if (node.Has("motion")) {
        Fail(node.MemberPointer("motion"), "a motion on a skinned mesh",
             "no motion: a skinned mesh is placed by its joints alone");
      }
      deformation->hasSkin = true;
      deformation->skin = ReadSkin(node.Member("skin"));
    }
    for (const DeformationProblem& problem : CheckDeformation(*deformation, shape.Mesh().vertices.size())) {
      Fail(node.pointer + problem.where, problem.problem, problem.expected);
    }
    shape.deformation = std::move(deformation);
  }

  static std::vector<Vec3> ReadVec3List(const Node& node, const std::string& what) {
    if (!node.value.is_array()) FailType(node, "an array of " + what + " [x, y, z]");
    std::vector<Vec3> values;
    values.reserve(node.value.size());
    for (size_t i = 0; i < node.value.size(); ++i) values.push_back(ReadVec3(node.Element(i)));
    return values;
  }

  static std::vector<double> ReadWeightList(const Node& node, size_t count, const std::string& expected) {
    if (!node.value.is_array() || (count != 0 && node.value.size() != count)) FailType(node, expected);
    std::vector<double> values;
    for (size_t i = 0; i < node.value.size(); ++i) values.push_back(ReadNumber(node.Element(i), expected));
    return values;
  }

  static MorphTargets ReadMorph(const Node& node) {
    ExpectObject(node, {"targets", "weights"}, "morph targets {\"targets\": [...], \"weights\": ...}");
    MorphTargets morph;
    Node targets = Required(node, "targets", "an array of morph targets {\"positions\", \"normals\"}");
    if (!targets.value.is_array() || targets.value.empty()) {
      FailType(targets, "a non-empty array of morph targets {\"positions\": [...], \"normals\": [...]}");
    }
    for (size_t t = 0; t < targets.value.size(); ++t) {
      Node target = targets.Element(t);
      ExpectObject(target, {"positions", "normals"}, "a morph target {\"positions\": [...], \"normals\": [...]}");
      morph.positionDeltas.push_back(
          ReadVec3List(Required(target, "positions", "position deltas, one per vertex"), "position deltas"));
      morph.normalDeltas.push_back(target.Has("normals") ? ReadVec3List(target.Member("normals"), "normal deltas")
                                                         : std::vector<Vec3>{});
    }
    const size_t count = morph.positionDeltas.size();
    const std::string expected = "an array of " + std::to_string(count) + " weights (one per target)";
    Node weights = Required(node, "weights", "the targets' weights: [w, ...] or {\"keyframes\": [...]}");
    if (weights.value.is_array()) {
      morph.weights = AnimatedWeights::Constant(ReadWeightList(weights, count, expected));
    } else {
      if (!weights.value.is_object()) FailType(weights, "[w, ...] or {\"keyframes\": [...]}");
      ExpectObject(weights, {"keyframes", "interpolation"}, "weight keyframes {\"keyframes\": [...]}");
      auto read = [&](const Node& value) { return ReadWeightList(value, count, expected); };
      morph.weights = AnimatedWeights::Keyframes(ReadKeys<AnimatedWeights::Keyframe>(weights, "[w, ...]", read, read),
                                                 ReadInterpolation(weights));
    }
    return morph;
  }

  Skin ReadSkin(const Node& node) const {
    ExpectObject(node, {"joints", "inverse_bind_matrices", "vertex_joints", "vertex_weights", "offset"},
                 "a skin {\"joints\", \"inverse_bind_matrices\", \"vertex_joints\", \"vertex_weights\"}");
    Skin skin;
    Node joints = Required(node, "joints", "an array of joint transforms");
    if (!joints.value.is_array() || joints.value.empty() || joints.value.size() > kMaxJoints) {
      FailType(joints, "an array of 1 to " + std::to_string(kMaxJoints) + " joint transforms");
    }
    for (size_t j = 0; j < joints.value.size(); ++j) skin.joints.push_back(ReadMotion(joints.Element(j), range_, 0, &named_));
    const std::string matrixExpected = "a 3x4 matrix [m00, m01, m02, m03, m10, ..., m23] (row-major, finite)";
    Node matrices = Required(node, "inverse_bind_matrices", "one inverse bind matrix per joint");
    if (!matrices.value.is_array()) FailType(matrices, "an array of " + matrixExpected);
    for (size_t j = 0; j < matrices.value.size(); ++j) {
      Node matrix = matrices.Element(j);
      ExpectArray(matrix, 12, matrixExpected);
      Affine affine;
      for (int row = 0; row < 3; ++row) {
        for (int column = 0; column < 3; ++column) affine.linear[row][column] = ReadNumber(matrix.Element(4 * row + column), matrixExpected);
        affine.offset[row] = ReadNumber(matrix.Element(4 * row + 3), matrixExpected);
      }
      skin.inverseBind.push_back(affine);
    }
    ReadInfluences(node, skin);
    if (node.Has("offset")) skin.worldOffset = ReadVec3(node.Member("offset"));
    return skin;
  }

  // Per vertex, 4 or 8 joint indices and as many weights.
  static void ReadInfluences(const Node& node, Skin& skin) {
    Node joints = Required(node, "vertex_joints", "per vertex, an array of 4 or 8 joint indices");
    Node weights = Required(node, "vertex_weights", "per vertex, an array of 4 or 8 weights");
    if (!joints.value.is_array() || joints.value.empty()) FailType(joints, "a non-empty array, one entry per vertex");
    if (!weights.value.is_array()) FailType(weights, "an array, one entry per vertex");
    const Node first = joints.Element(0);
    skin.influencesPerVertex = first.value.is_array() && first.value.size() == 8 ? 8 : 4;
    const size_t k = static_cast<size_t>(skin.influencesPerVertex);
    const std::string jointsExpected = "an array of " + std::to_string(k) + " joint indices (as the first vertex has)";
    const std::string weightsExpected = "an array of " + std::to_string(k) + " weights >= 0";
    for (size_t v = 0; v < joints.value.size(); ++v) {
      Node entry = joints.Element(v);
      ExpectArray(entry, k, jointsExpected);
      for (size_t i = 0; i < k; ++i) {
        skin.vertexJoints.push_back(static_cast<uint32_t>(ReadInteger(entry.Element(i), 0, kMaxJoints - 1)));
      }
    }
    for (size_t v = 0; v < weights.value.size(); ++v) {
      const std::vector<double> values = ReadWeightList(weights.Element(v), k, weightsExpected);
      skin.vertexWeights.insert(skin.vertexWeights.end(), values.begin(), values.end());
    }
  }

  // A mesh's own triangles, inline or from an OBJ file: a mesh shape's, or a shared one's.
  TriangleMesh ReadMeshGeometry(const Node& node) {
    TriangleMesh mesh;
    if (node.Has("file")) {
      if (HasInlineGeometry(node)) {
        Fail(node.MemberPointer("file"), "both a file and inline geometry",
             "either \"file\" or inline \"vertices\" and \"triangles\"");
      }
      mesh = LoadMeshFile(node.Member("file"));
      CheckMesh(mesh, node.Member("file"), node.Member("file"));
      return mesh;
    }
    const std::string expected = "inline \"vertices\" and \"triangles\", or a \"file\"";
    Node vertices = Required(node, "vertices", expected);
    Node triangles = Required(node, "triangles", expected);
    mesh.vertices = ReadVertices(vertices);
    mesh.triangles = ReadTriangles(triangles, mesh.vertices.size());
    if (node.Has("normals")) mesh.normals = ReadNormals(node.Member("normals"), mesh.vertices.size());
    if (node.Has("uvs")) mesh.uvs = ReadUvs(node.Member("uvs"), mesh.vertices.size());
    if (node.Has("colors")) mesh.colors = ReadVertexColors(node.Member("colors"), mesh.vertices.size());
    CheckMesh(mesh, vertices, triangles);
    return mesh;
  }

  static bool HasInlineGeometry(const Node& node) {
    return node.Has("vertices") || node.Has("triangles") || node.Has("normals") || node.Has("uvs") ||
           node.Has("colors");
  }

  // Every shared mesh is read and checked, used or not: a scene holds no invalid geometry.
  // The document's shared meshes, beside an imported scene's (which its shapes may place too).
  void AddSharedMeshes(Scene& scene, const Node& node) {
    if (!node.value.is_object()) FailType(node, "an object mapping mesh names to meshes");
    for (const auto& entry : node.value.items()) {
      if (scene.meshes.count(entry.key())) {
        Fail(node.MemberPointer(entry.key()), "the imported file has a mesh named " + Quote(entry.key()),
             "a name of its own");
      }
    }
    std::map<std::string, std::shared_ptr<const TriangleMesh>> imported = std::move(scene.meshes);
    scene.meshes = ReadSharedMeshes(node);
    scene.meshes.insert(imported.begin(), imported.end());
  }

  std::map<std::string, std::shared_ptr<const TriangleMesh>> ReadSharedMeshes(const Node& node) {
    if (!node.value.is_object()) FailType(node, "an object mapping mesh names to meshes");
    for (const auto& entry : node.value.items()) {
      Node mesh = node.Member(entry.key());
      ExpectObject(mesh, {"vertices", "triangles", "normals", "uvs", "colors", "file"}, "a shared mesh");
      sharedMeshes_[entry.key()] = std::make_shared<const TriangleMesh>(ReadMeshGeometry(mesh));
      unplacedMeshes_.insert(entry.key());
    }
    return sharedMeshes_;
  }

  void ReadMeshRef(const Node& node, Shape& shape) {
    Node ref = node.Member("mesh_ref");
    if (HasInlineGeometry(node) || node.Has("file")) {
      Fail(ref.pointer, "both a shared mesh and geometry of its own",
           "either \"mesh_ref\" or inline \"vertices\" and \"triangles\" or a \"file\"");
    }
    shape.meshRef = ReadString(ref, "the name of a shared mesh");
    auto found = sharedMeshes_.find(shape.meshRef);
    if (found == sharedMeshes_.end()) {
      Fail(ref.pointer, "unknown mesh " + Quote(shape.meshRef), SharedMeshChoices());
    }
    shape.sharedMesh = found->second;
    // The table charged the mesh once; every further placement costs a worker its
    // triangles again (a still one is built in place, as an inline copy).
    if (unplacedMeshes_.erase(shape.meshRef) == 0) ChargeTriangles(shape.sharedMesh->triangles.size(), ref);
  }

  std::string SharedMeshChoices() const {
    if (sharedMeshes_.empty()) return "the name of a mesh in the scene's \"meshes\" (it has none)";
    std::vector<std::string> names;
    for (const auto& entry : sharedMeshes_) names.push_back(Quote(entry.first));
    return "one of the shared meshes " + JoinNames(names);
  }

  static void ExpectOnePerVertex(const Node& node, size_t vertexCount, const std::string& what) {
    if (node.value.size() != vertexCount) {
      Fail(node.pointer, std::to_string(node.value.size()) + " " + what + "s for " + std::to_string(vertexCount) +
                             " vertices",
           "one " + what + " per vertex, in the order of \"vertices\"");
    }
  }

  // One value per vertex, each read by `read`: what (e.g. "normal"), as an array says it.
  template <typename Read>
  static std::vector<Vec3> ReadPerVertex(const Node& node, size_t vertexCount, const std::string& what,
                                         const std::string& arrayOf, Read read) {
    if (!node.value.is_array()) FailType(node, "an array of " + arrayOf + ", one per vertex");
    ExpectOnePerVertex(node, vertexCount, what);
    std::vector<Vec3> values;
    values.reserve(node.value.size());
    for (size_t i = 0; i < node.value.size(); ++i) values.push_back(read(node.Element(i)));
    return values;
  }

  static std::vector<Vec3> ReadNormals(const Node& node, size_t vertexCount) {
    return ReadPerVertex(node, vertexCount, "normal", "normals [x, y, z]",
                         [](const Node& element) { return ReadVec3(element); });
  }

  static std::vector<std::array<double, 2>> ReadUvs(const Node& node, size_t vertexCount) {
    if (!node.value.is_array()) FailType(node, "an array of texture coordinates [u, v], one per vertex");
    ExpectOnePerVertex(node, vertexCount, "texture coordinate");
    const std::string expected = "an array of 2 finite numbers [u, v]";
    std::vector<std::array<double, 2>> uvs;
    uvs.reserve(node.value.size());
    for (size_t i = 0; i < node.value.size(); ++i) {
      Node uv = node.Element(i);
      ExpectArray(uv, 2, expected);
      uvs.push_back({ReadNumber(uv.Element(0), expected), ReadNumber(uv.Element(1), expected)});
    }
    return uvs;
  }

  static std::vector<Vec3> ReadVertexColors(const Node& node, size_t vertexCount) {
    return ReadPerVertex(node, vertexCount, "colour", "linear RGB colours [r, g, b]", ReadColour);
  }

  std::vector<Vec3> ReadVertices(const Node& node) {
    if (!node.value.is_array()) FailType(node, "an array of vertices [x, y, z]");
    std::vector<Vec3> vertices;
    vertices.reserve(node.value.size());
    for (size_t i = 0; i < node.value.size(); ++i) vertices.push_back(ReadVec3(node.Element(i)));
    return vertices;
  }

  std::vector<std::array<uint32_t, 3>> ReadTriangles(const Node& node, size_t vertexCount) {
    if (!node.value.is_array()) FailType(node, "an array of triangles [i, j, k]");
    ChargeTriangles(node.value.size(), node);
    std::vector<std::array<uint32_t, 3>> triangles;
    triangles.reserve(node.value.size());
    const std::string expected = "a triangle [i, j, k] of vertex indices";
    for (size_t t = 0; t < node.value.size(); ++t) {
      Node triangle = node.Element(t);
      ExpectArray(triangle, 3, expected);
      std::array<uint32_t, 3> corners{};
      for (size_t c = 0; c < 3; ++c) corners[c] = ReadVertexIndex(triangle.Element(c), vertexCount);
      triangles.push_back(corners);
    }
    return triangles;
  }

  static uint32_t ReadVertexIndex(const Node& node, size_t vertexCount) {
    std::string expected = "an integer in [0, " + std::to_string(vertexCount) + "), the index of one of the mesh's " +
                           std::to_string(vertexCount) + " vertices";
    if (!IsIntegral(node.value)) FailType(node, expected);
    double index = node.value.get<double>();
    if (index < 0 || index >= static_cast<double>(vertexCount)) {
      Fail(node.pointer, "index " + Show(node.value) + " is out of range", expected);
    }
    return static_cast<uint32_t>(index);
  }

  static void CheckMesh(const TriangleMesh& mesh, const Node& verticesNode, const Node& trianglesNode) {
    if (mesh.vertices.empty()) {
      Fail(verticesNode.pointer, "the mesh has no vertices", "a mesh with at least 3 vertices");
    }
    if (mesh.triangles.empty()) Fail(trianglesNode.pointer, "the mesh has no triangles", "at least one triangle");
    for (const auto& t : mesh.triangles) {
      const Vec3& a = mesh.vertices[t[0]];
      if (!IsDegenerate(Subtract(mesh.vertices[t[1]], a), Subtract(mesh.vertices[t[2]], a))) return;
    }
    Fail(trianglesNode.pointer, "every triangle of the mesh has zero area", "at least one triangle with area");
  }

  void ChargeTriangles(size_t count, const Node& node) {
    if (count > kMaxTriangles - triangleCount_) {
      Fail(node.pointer, "the scene would have " + std::to_string(triangleCount_ + count) + " triangles",
           "at most 20000000 triangles in the whole scene");
    }
    triangleCount_ += count;
  }

  TriangleMesh LoadMeshFile(const Node& node) {
    std::string name = ReadString(node, "a path to an OBJ file inside the scene folder");
    if (!baseDirectory_) {
      Fail(node.pointer, "mesh file " + Quote(name) + " cannot be resolved: the scene was submitted without a folder",
           "inline \"vertices\" and \"triangles\" (scenes submitted without a folder must inline their meshes)");
    }
    std::string text = ReadSceneFile(ResolveInsideBase(node, name), name, node.pointer, "mesh file",
                                     "a readable OBJ file inside the scene folder");
    // Geometry only: the JSON shape names the material, so the file's mtllib/usemtl are
    // not read (a whole OBJ imported as a scene keeps them).
    ObjReadOptions options;
    options.pointer = node.pointer;
    options.displayName = name;
    options.triangleBudget = kMaxTriangles - triangleCount_;
    options.triangleLimit = kMaxTriangles;
    TriangleMesh mesh = ReadObj(text, options).mesh;
    triangleCount_ += mesh.triangles.size();
    return mesh;
  }

  std::filesystem::path ResolveInsideBase(const Node& node, const std::string& name) const {
    return ResolveInsideFolder(*baseDirectory_, name, node.pointer, "mesh file");
  }

  void ReadTerrain(const Node& node, Shape& shape) {
    ExpectObject(node, ShapeFields({"origin", "size", "height", "cells", "seed"}), "a terrain");
    shape.type = Shape::Type::kTerrain;
    Shape::Terrain& terrain = shape.terrain;
    terrain.origin = ReadVec3(Required(node, "origin", kVec3Expected));
    const std::string sizeExpected = "[size_x, size_z], two positive finite numbers";
    Node size = Required(node, "size", sizeExpected);
    ExpectArray(size, 2, sizeExpected);
    terrain.sizeX = ReadPositive(size.Element(0), sizeExpected);
    terrain.sizeZ = ReadPositive(size.Element(1), sizeExpected);
    if (node.Has("height")) terrain.height = ReadNonNegative(node.Member("height"), "a non-negative finite height");
    if (node.Has("cells")) ReadTerrainCells(node.Member("cells"), terrain);
    if (node.Has("seed")) terrain.seed = ReadSeed(node.Member("seed"));
    ChargeTriangles(2 * static_cast<size_t>(terrain.cellsX) * static_cast<size_t>(terrain.cellsZ),
                    node.Has("cells") ? node.Member("cells") : node);
  }

  static void ReadTerrainCells(const Node& node, Shape::Terrain& terrain) {
    ExpectArray(node, 2, "[cells_x, cells_z], two integers in [1, 2000]");
    terrain.cellsX = ReadInt(node.Element(0), 1, kMaxTerrainCells);
    terrain.cellsZ = ReadInt(node.Element(1), 1, kMaxTerrainCells);
  }

  static uint64_t ReadSeed(const Node& node) {
    const std::string expected = "an integer in [0, 18446744073709551615]";
    if (node.value.is_number_unsigned()) return node.value.get<uint64_t>();
    if (node.value.is_number_integer()) Fail(node.pointer, Show(node.value) + " is negative", expected);
    FailType(node, expected);
  }

  std::optional<std::filesystem::path> baseDirectory_;
  Checkpoint checkpoint_;
  FrameRange range_{0, 0};
  NamedTransforms named_;
  std::map<std::string, int> materialIndex_;
  std::map<std::string, std::shared_ptr<const TriangleMesh>> sharedMeshes_;
  std::set<std::string> unplacedMeshes_;  // shared meshes no shape has placed yet
  size_t triangleCount_ = 0;
};

// --- writing -------------------------------------------------------------------------

json Vec3Json(const Vec3& v) { return json::array({v.x, v.y, v.z}); }

// Linear, the default, is left out: scenes written before splines keep their bytes.
json WithInterpolation(json keyed, Interpolation interpolation) {
  if (interpolation == Interpolation::kStep) keyed["interpolation"] = "step";
  if (interpolation == Interpolation::kCubicSpline) keyed["interpolation"] = "cubicspline";
  return keyed;
}

json AnimatedJson(const AnimatedVec3& value) {
  switch (value.kind()) {
    case AnimatedVec3::Kind::kConstant:
      return Vec3Json(value.constant());
    case AnimatedVec3::Kind::kPolynomial: {
      json axes = json::array();
      for (const auto& axis : value.coefficients()) axes.push_back(axis);
      return json{{"polynomial", axes}};
    }
    case AnimatedVec3::Kind::kKeyframes: {
      const bool cubic = value.interpolation() == Interpolation::kCubicSpline;
      json keys = json::array();
      for (const auto& key : value.keys()) {
        json entry{{"frame", key.frame}, {"value", Vec3Json(key.value)}};
        if (cubic) entry["in_tangent"] = Vec3Json(key.inTangent), entry["out_tangent"] = Vec3Json(key.outTangent);
        keys.push_back(std::move(entry));
      }
      return WithInterpolation(json{{"keyframes", keys}}, value.interpolation());
    }
  }
  return Vec3Json(value.constant());
}

json QuaternionJson(const Quaternion& q) { return json::array({q.x, q.y, q.z, q.w}); }

json RotationJson(const AnimatedRotation& rotation) {
  switch (rotation.kind()) {
    case AnimatedRotation::Kind::kConstant:
      return QuaternionJson(rotation.constant());
    case AnimatedRotation::Kind::kKeyframes: {
      const bool cubic = rotation.interpolation() == Interpolation::kCubicSpline;
      json keys = json::array();
      for (const auto& key : rotation.keys()) {
        json entry{{"frame", key.frame}, {"value", QuaternionJson(key.value)}};
        if (cubic) entry["in_tangent"] = QuaternionJson(key.inTangent), entry["out_tangent"] = QuaternionJson(key.outTangent);
        keys.push_back(std::move(entry));
      }
      return WithInterpolation(json{{"keyframes", keys}}, rotation.interpolation());
    }
    case AnimatedRotation::Kind::kSpin:
      return json{{"axis", Vec3Json(rotation.axis())},
                  {"degrees_per_frame", rotation.degreesPerFrame()},
                  {"degrees", rotation.degreesAtZero()}};
  }
  return json::array();
}

// A translation alone is written as the paper's motion always was, so the text (and the
// hash) of a scene without rotation or scale does not change.
// The parents that several transforms share (by object: a glTF node's, or a named
// transform's), written once in "transforms" and named by the transforms they carry. A
// parent of one transform stays inline, so a scene without shared parents keeps its bytes.
class SharedParents {
 public:
  explicit SharedParents(const Scene& scene) {
    Visit(scene.camera.rig);
    for (const Light& light : scene.lights) Visit(light.motion);
    for (const Shape& shape : scene.shapes) {
      Visit(shape.motion);
      if (shape.deformation && shape.deformation->hasSkin) {
        for (const Motion& joint : shape.deformation->skin.joints) Visit(joint);
      }
    }
    for (const Motion* parent : order_) {
      if (uses_[parent] > 1) names_[parent] = "t" + std::to_string(names_.size());
    }
  }
  // The name a shared parent is written under; null for one written inline.
  const std::string* NameOf(const Motion* parent) const {
    auto found = names_.find(parent);
    return found == names_.end() ? nullptr : &found->second;
  }
  // "transforms": each shared parent, in the order first met.
  json Table() const;

 private:
  void Visit(const Motion& motion) {
    const Motion* parent = motion.parent.get();
    if (!parent || parent->IsNone()) return;
    if (uses_[parent]++ == 0) {
      order_.push_back(parent);
      Visit(*parent);  // its own parent is counted once, however many carry it
    }
  }
  std::map<const Motion*, int> uses_;
  std::vector<const Motion*> order_;
  std::map<const Motion*, std::string> names_;
};

json TransformJson(const Motion& motion, const SharedParents& shared) {
  json result{{"translation", AnimatedJson(motion.translation)},
              {"rotation", RotationJson(motion.rotation)},
              {"scale", AnimatedJson(motion.scale)},
              {"pivot", Vec3Json(motion.pivot)}};
  if (motion.parent && !motion.parent->IsNone()) {
    const std::string* name = shared.NameOf(motion.parent.get());
    result["parent"] = name ? json(*name) : TransformJson(*motion.parent, shared);
  }
  return result;
}

json SharedParents::Table() const {
  json table = json::object();
  for (const Motion* parent : order_) {
    if (const std::string* name = NameOf(parent)) table[*name] = TransformJson(*parent, *this);
  }
  return table;
}

json MotionJson(const Motion& motion, const SharedParents& shared) {
  return motion.IsTranslationOnly() ? AnimatedJson(motion.translation) : TransformJson(motion, shared);
}

json CameraJson(const Camera& camera, const SharedParents& shared) {
  json result{{"position", AnimatedJson(camera.position)},
              {"look_at", AnimatedJson(camera.lookAt)},
              {"up", Vec3Json(camera.up)},
              {"fov_degrees", camera.verticalFovDegrees}};
  if (camera.orthographic) result["projection"] = "orthographic", result["ortho_height"] = camera.orthographicHeight;
  if (!camera.rig.IsNone()) result["motion"] = MotionJson(camera.rig, shared);
  return result;
}

json LightJson(const Light& light, const SharedParents& shared) {
  json result{{"intensity", AnimatedJson(light.intensity)}};
  static const char* const kTypeNames[] = {"point", "directional", "spot"};
  result["type"] = kTypeNames[static_cast<int>(light.type)];
  if (light.HasPosition()) result["position"] = AnimatedJson(light.position);
  if (light.HasDirection()) result["direction"] = AnimatedJson(light.direction);
  if (light.type == Light::Type::kSpot) {
    result["inner_cone_degrees"] = light.innerConeDegrees;
    result["outer_cone_degrees"] = light.outerConeDegrees;
  }
  if (!light.motion.IsNone()) result["motion"] = MotionJson(light.motion, shared);
  return result;
}

json TextureJson(const Texture& texture) {
  static const char* const kWraps[] = {"repeat", "clamp_to_edge", "mirrored_repeat"};
  return json{{texture.asset.empty() ? "image" : "asset", texture.asset.empty() ? texture.image : texture.asset},
              {"wrap_s", kWraps[static_cast<int>(texture.wrapS)]},
              {"wrap_t", kWraps[static_cast<int>(texture.wrapT)]},
              {"filter", texture.filter == Texture::Filter::kNearest ? "nearest" : "linear"}};
}

json MaterialJson(const Material& material) {
  json result{{"diffuse", Vec3Json(material.diffuse)},   {"specular", Vec3Json(material.specular)},
              {"shininess", material.shininess},         {"reflectivity", material.reflectivity},
              {"transparency", material.transparency}, {"ior", material.indexOfRefraction}};
  if (material.diffuseTexture) result["diffuse_texture"] = TextureJson(*material.diffuseTexture);
  if (material.emission != Vec3{}) result["emission"] = Vec3Json(material.emission);
  return result;
}

json MeshJson(const TriangleMesh& mesh, json result) {
  json vertices = json::array();
  for (const auto& v : mesh.vertices) vertices.push_back(Vec3Json(v));
  json triangles = json::array();
  for (const auto& t : mesh.triangles) triangles.push_back(json::array({t[0], t[1], t[2]}));
  result["vertices"] = std::move(vertices);
  result["triangles"] = std::move(triangles);
  if (!mesh.normals.empty()) {
    json normals = json::array();
    for (const auto& n : mesh.normals) normals.push_back(Vec3Json(n));
    result["normals"] = std::move(normals);
  }
  if (!mesh.uvs.empty()) {
    json uvs = json::array();
    for (const auto& uv : mesh.uvs) uvs.push_back(json::array({uv[0], uv[1]}));
    result["uvs"] = std::move(uvs);
  }
  if (!mesh.colors.empty()) {
    json colors = json::array();
    for (const auto& c : mesh.colors) colors.push_back(Vec3Json(c));
    result["colors"] = std::move(colors);
  }
  return result;
}

json ShapeGeometryJson(const Shape& shape) {
  switch (shape.type) {
    case Shape::Type::kSphere:
      return json{{"type", "sphere"}, {"center", Vec3Json(shape.center)}, {"radius", shape.radius}};
    case Shape::Type::kQuad:
      return json{{"type", "quad"},
                  {"corner", Vec3Json(shape.corner)},
                  {"edge_u", Vec3Json(shape.edgeU)},
                  {"edge_v", Vec3Json(shape.edgeV)}};
    case Shape::Type::kMesh:
      if (shape.SharesMesh()) return json{{"type", "mesh"}, {"mesh_ref", shape.meshRef}};
      return MeshJson(shape.mesh, json{{"type", "mesh"}});
    case Shape::Type::kTerrain: {
      const Shape::Terrain& t = shape.terrain;
      return json{{"type", "terrain"},       {"origin", Vec3Json(t.origin)},
                  {"size", {t.sizeX, t.sizeZ}}, {"height", t.height},
                  {"cells", {t.cellsX, t.cellsZ}}, {"seed", t.seed}};
    }
  }
  return json::object();
}

json WeightsJson(const AnimatedWeights& weights) {
  if (weights.IsConstant()) return weights.constant();
  const bool cubic = weights.interpolation() == Interpolation::kCubicSpline;
  json keys = json::array();
  for (const auto& key : weights.keys()) {
    json entry{{"frame", key.frame}, {"value", key.values}};
    if (cubic) entry["in_tangent"] = key.inTangent, entry["out_tangent"] = key.outTangent;
    keys.push_back(std::move(entry));
  }
  return WithInterpolation(json{{"keyframes", keys}}, weights.interpolation());
}

json Vec3ListJson(const std::vector<Vec3>& values) {
  json list = json::array();
  for (const Vec3& v : values) list.push_back(Vec3Json(v));
  return list;
}

json MorphJson(const MorphTargets& morph) {
  json targets = json::array();
  for (size_t t = 0; t < morph.TargetCount(); ++t) {
    json target{{"positions", Vec3ListJson(morph.positionDeltas[t])}};
    if (!morph.normalDeltas[t].empty()) target["normals"] = Vec3ListJson(morph.normalDeltas[t]);
    targets.push_back(std::move(target));
  }
  return json{{"targets", std::move(targets)}, {"weights", WeightsJson(morph.weights)}};
}

json SkinJson(const Skin& skin, const SharedParents& shared) {
  json joints = json::array(), matrices = json::array(), vertexJoints = json::array(), vertexWeights = json::array();
  for (const Motion& joint : skin.joints) joints.push_back(MotionJson(joint, shared));
  for (const Affine& m : skin.inverseBind) {
    json matrix = json::array();
    for (int row = 0; row < 3; ++row) {
      matrix.insert(matrix.end(), {m.linear[row][0], m.linear[row][1], m.linear[row][2], m.offset[row]});
    }
    matrices.push_back(std::move(matrix));
  }
  const size_t k = static_cast<size_t>(skin.influencesPerVertex);
  for (size_t v = 0; v * k < skin.vertexJoints.size(); ++v) {
    vertexJoints.push_back(std::vector<uint32_t>(skin.vertexJoints.begin() + v * k, skin.vertexJoints.begin() + (v + 1) * k));
    vertexWeights.push_back(std::vector<double>(skin.vertexWeights.begin() + v * k, skin.vertexWeights.begin() + (v + 1) * k));
  }
  json result{{"joints", std::move(joints)},
              {"inverse_bind_matrices", std::move(matrices)},
              {"vertex_joints", std::move(vertexJoints)},
              {"vertex_weights", std::move(vertexWeights)}};
  if (skin.worldOffset != Vec3{}) result["offset"] = Vec3Json(skin.worldOffset);
  return result;
}

json ShapeJson(const Shape& shape, const std::vector<Material>& materials, const SharedParents& shared) {
  json result = ShapeGeometryJson(shape);
  if (shape.deformation && shape.deformation->hasMorph) result["morph"] = MorphJson(shape.deformation->morph);
  if (shape.deformation && shape.deformation->hasSkin) result["skin"] = SkinJson(shape.deformation->skin, shared);
  if (!shape.name.empty()) result["name"] = shape.name;
  result["material"] = materials.at(static_cast<size_t>(shape.material)).name;
  // A skinned mesh has no motion of its own (its joints place it), and the parser refuses one.
  if (!(shape.deformation && shape.deformation->hasSkin)) result["motion"] = MotionJson(shape.motion, shared);
  return result;
}

json SharedMeshesJson(const std::map<std::string, std::shared_ptr<const TriangleMesh>>& meshes) {
  json result = json::object();
  for (const auto& [name, mesh] : meshes) result[name] = MeshJson(*mesh, json::object());
  return result;
}

json RenderJson(const RenderSettings& render) {
  return json{{"width", render.width},
              {"height", render.height},
              {"frames", {{"start", render.firstFrame}, {"count", render.frameCount}}},
              {"samples_per_pixel", render.samplesPerPixel},
              {"max_depth", render.maxDepth}};
}

}  // namespace

Scene ParseScene(const std::string& jsonText, const std::optional<std::filesystem::path>& baseDirectory,
                 const Checkpoint& checkpoint) {
  json document = ParseJson(jsonText);
  return SceneReader(baseDirectory, checkpoint).Read(document);
}

Scene LoadSceneFile(const std::filesystem::path& path) {
  std::error_code error;
  std::ifstream in(path, std::ios::binary);
  if (!std::filesystem::is_regular_file(path, error) || !in) {
    Fail("", "cannot read scene file " + path.string(), "a readable scene file");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return ParseScene(text.str(), std::filesystem::absolute(path).parent_path());
}

std::string SerializeScene(const Scene& scene) {
  const SharedParents shared(scene);
  json materials = json::object();
  for (const auto& material : scene.materials) materials[material.name] = MaterialJson(material);
  json lights = json::array();
  for (const auto& light : scene.lights) lights.push_back(LightJson(light, shared));
  json shapes = json::array();
  for (const auto& shape : scene.shapes) shapes.push_back(ShapeJson(shape, scene.materials, shared));
  json document{{"camera", CameraJson(scene.camera, shared)}, {"lights", lights},
                {"materials", materials},             {"shapes", shapes},
                {"background", Vec3Json(scene.background)}, {"render", RenderJson(scene.render)}};
  // Only scenes with shared meshes have the key: every other scene keeps its bytes (and hash).
  if (!scene.meshes.empty()) document["meshes"] = SharedMeshesJson(scene.meshes);
  if (json table = shared.Table(); !table.empty()) document["transforms"] = std::move(table);
  return document.dump();
}

}  // namespace tcfarm
