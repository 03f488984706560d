// Reading scene JSON values with their JSON pointers: each check names the pointer of the
// value it refuses and what would have been accepted there. The scene parser's limits.
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

#include "proto/json/strict_json.h"
#include "proto/scene/scene.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm::scene_parse {

using nlohmann::json;

// The scene format's bounds (scene_limits.h) are the parser's.
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

[[noreturn]] void Fail(const std::string& pointer, const std::string& problem, const std::string& expected);

// --- small text helpers ------------------------------------------------------------

std::string FormatNumber(double value);

std::string Quote(const std::string& text);

// What a value is, for "got ..." messages.
std::string Describe(const json& value);

// How a number was written, for "<value> is negative" messages: integers stay integers.
std::string Show(const json& number);

std::string JoinNames(const std::vector<std::string>& names);

json ParseJson(const std::string& text);

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

[[noreturn]] void FailType(const Node& node, const std::string& expected);

// Objects list the keys they accept: a misspelt key is an error, never silently ignored.
void ExpectObject(const Node& node, const std::vector<std::string>& allowed, const std::string& expected);

Node Required(const Node& object, const std::string& key, const std::string& expected);

void ExpectArray(const Node& node, size_t size, const std::string& expected);

double ReadNumber(const Node& node, const std::string& expected);

double ReadNonNegative(const Node& node, const std::string& expected);

double ReadPositive(const Node& node, const std::string& expected);

double ReadInRange(const Node& node, double low, double high, const std::string& expected);

bool IsIntegral(const json& value);

int64_t ReadInteger(const Node& node, int64_t low, int64_t high);

int ReadInt(const Node& node, int low, int high);

const char* const kVec3Expected = "an array of 3 finite numbers [x, y, z]";

Vec3 ReadVec3(const Node& node, const std::string& expected = kVec3Expected);

Vec3 ReadColour(const Node& node);

std::string ReadString(const Node& node, const std::string& expected);

// --- vector helpers ------------------------------------------------------------------

Vec3 Subtract(const Vec3& a, const Vec3& b);
Vec3 Cross(const Vec3& a, const Vec3& b);
double Length(const Vec3& v);
double MaxAbs(const Vec3& v);
std::string FormatVec3(const Vec3& v);

// Squared lengths below the smallest normal double cannot be normalised reliably.
bool IsZeroLength(const Vec3& v);

bool IsDegenerate(const Vec3& edgeA, const Vec3& edgeB);

}  // namespace tcfarm::scene_parse
