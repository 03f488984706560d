#include "proto/scene/parse/animated_values.h"

namespace tcfarm::scene_parse {

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

Interpolation ReadInterpolation(const Node& keyed) {
  if (!keyed.Has("interpolation")) return Interpolation::kLinear;
  Node node = keyed.Member("interpolation");
  const std::string name = ReadString(node, kInterpolationExpected);
  if (name == "linear") return Interpolation::kLinear;
  if (name == "step") return Interpolation::kStep;
  if (name == "cubicspline") return Interpolation::kCubicSpline;
  Fail(node.pointer, "unknown interpolation " + Quote(name), kInterpolationExpected);
}

AnimatedVec3 ReadKeyframes(const Node& keyed) {
  auto read = [](const Node& value) { return ReadVec3(value); };
  return AnimatedVec3::Keyframes(ReadKeys<AnimatedVec3::Keyframe>(keyed, "[x, y, z]", read, read),
                                 ReadInterpolation(keyed));
}

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

std::vector<double> AllFrames(bool animated, const FrameRange& range) {
  std::vector<double> frames{static_cast<double>(range.first)};
  if (!animated) return frames;
  for (int frame = range.first + 1; frame <= range.last; ++frame) frames.push_back(frame);
  return frames;
}

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

}  // namespace tcfarm::scene_parse
