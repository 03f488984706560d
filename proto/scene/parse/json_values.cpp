#include "proto/scene/parse/json_values.h"

namespace tcfarm::scene_parse {

[[noreturn]] void Fail(const std::string& pointer, const std::string& problem, const std::string& expected) {
  throw SceneError(pointer, problem + "; expected " + expected);
}

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

[[noreturn]] void FailType(const Node& node, const std::string& expected) {
  Fail(node.pointer, "got " + Describe(node.value), expected);
}

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

Vec3 ReadVec3(const Node& node, const std::string& expected) {
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

Vec3 Subtract(const Vec3& a, const Vec3& b) { return Vec3{a.x - b.x, a.y - b.y, a.z - b.z}; }

Vec3 Cross(const Vec3& a, const Vec3& b) {
  return Vec3{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

double Length(const Vec3& v) { return std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z); }

double MaxAbs(const Vec3& v) { return std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)}); }

std::string FormatVec3(const Vec3& v) {
  return "[" + FormatNumber(v.x) + ", " + FormatNumber(v.y) + ", " + FormatNumber(v.z) + "]";
}

bool IsZeroLength(const Vec3& v) { return v.x * v.x + v.y * v.y + v.z * v.z < std::numeric_limits<double>::min(); }

bool IsDegenerate(const Vec3& edgeA, const Vec3& edgeB) {
  return Length(Cross(edgeA, edgeB)) <= kMinAreaRatio * Length(edgeA) * Length(edgeB) || IsZeroLength(edgeA) ||
         IsZeroLength(edgeB);
}

}  // namespace tcfarm::scene_parse
