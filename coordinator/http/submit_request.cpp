#include "http/submit_request.h"

#include <cmath>
#include <limits>
#include <tuple>
#include <utility>
#include <vector>

#include "http/api_error.h"
#include "json/strict_json.h"
#include "scene/scene.h"
#include "wire/content_hash.h"

namespace tcfarm::http {
namespace {

using nlohmann::json;

constexpr const char* kTopLevelFields[] = {"scene",     "name",      "frames",   "strategy",
                                           "bin_width", "tolerance", "priority", "verify",
                                           "spot_check_share"};
constexpr int kDefaultBinWidth = 10;

// Messages read like the scene parser's: "<pointer without the leading '/'>: <problem>;
// expected <what>", so a client sees one style for every field.
[[noreturn]] void Fail(const char* code, const std::string& pointer, const std::string& problem,
                       const std::string& expected) {
  const std::string where = pointer.empty() ? "request body" : pointer.substr(1);
  throw ApiError(400, code, where + ": " + problem + "; expected " + expected, pointer);
}


// Duplicate keys are refused here, at the body: the scene inside it is re-serialized
// before ParseScene sees it, so the scene's own check could not catch them.
json ParseBody(const std::string& body) {
  try {
    return ParseStrictJson(body);
  } catch (const JsonInputError& error) {
    if (error.pointer().empty() || error.problem().rfind("duplicate", 0) != 0) {
      throw ApiError(400, error_code::kInvalidJson,
                     "request body is not valid JSON: " + std::string(error.what()),
                     error.pointer().empty() ? std::nullopt : std::optional(error.pointer()));
    }
    Fail(error_code::kInvalidJson, error.pointer(), error.problem(), error.expected());
  }
}

bool IsIntegral(const json& value) {
  if (value.is_number_integer()) return true;
  if (!value.is_number_float()) return false;
  const double number = value.get<double>();
  return std::isfinite(number) && std::floor(number) == number;
}

int ReadInteger(const json& value, const std::string& pointer, int low, int high,
                const std::string& expected) {
  if (!IsIntegral(value)) {
    Fail(error_code::kInvalidField, pointer, ShowValue(value) + " is not an integer", expected);
  }
  // The limits are far below 2^53, so comparing as double is exact where it matters.
  const double number = value.get<double>();
  if (number < low || number > high) {
    Fail(error_code::kInvalidField, pointer, ShowValue(value) + " is out of range", expected);
  }
  return static_cast<int>(number);
}

std::string IntegerRange(int low, int high) {
  return "an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
}

void CheckKnownFields(const json& request) {
  std::string known;
  for (const char* field : kTopLevelFields) known += std::string(known.empty() ? "" : ", ") + field;
  for (const auto& item : request.items()) {
    bool isKnown = false;
    for (const char* field : kTopLevelFields) isKnown = isKnown || item.key() == field;
    if (!isKnown) {
      Fail(error_code::kUnknownField, "/" + EscapePointerToken(item.key()), "unknown field",
           "only the fields " + known);
    }
  }
}

std::string ReadName(const json& request) {
  const auto name = request.find("name");
  if (name == request.end()) return "";
  const std::string expected = "a string of at most " + std::to_string(kMaxNameBytes) + " bytes";
  if (!name->is_string()) {
    Fail(error_code::kInvalidField, "/name", ShowValue(*name) + " is not a string", expected);
  }
  if (name->get_ref<const std::string&>().size() > kMaxNameBytes) {
    Fail(error_code::kInvalidField, "/name", "the name is too long", expected);
  }
  return name->get<std::string>();
}

Strategy ReadStrategy(const json& request) {
  const auto strategy = request.find("strategy");
  if (strategy == request.end()) return kDefaultStrategy;
  if (strategy->is_string()) {
    if (std::optional<Strategy> known = StrategyFromString(strategy->get_ref<const std::string&>())) {
      return *known;
    }
  }
  std::string expected = "one of";
  for (const StrategyNameEntry& entry : kStrategyNames) {
    expected += std::string(expected == "one of" ? " \"" : ", \"") + std::string(entry.name) + "\"";
  }
  Fail(error_code::kInvalidField, "/strategy", ShowValue(*strategy) + " is not a supported strategy", expected);
}

int ReadOptionalInteger(const json& request, const char* field, int low, int high, int fallback) {
  const auto value = request.find(field);
  if (value == request.end()) return fallback;
  return ReadInteger(*value, std::string("/") + field, low, high, IntegerRange(low, high));
}

double ReadTolerance(const json& request) {
  const auto tolerance = request.find("tolerance");
  if (tolerance == request.end()) return 0;
  // Pixel values are floats: a tolerance beyond the largest float compares nothing more.
  const std::string expected = "a number in [0, 3.4028234663852886e38]";
  if (!tolerance->is_number()) {
    Fail(error_code::kInvalidField, "/tolerance", ShowValue(*tolerance) + " is not a number", expected);
  }
  const double value = tolerance->get<double>();
  if (!(value >= 0 && value <= std::numeric_limits<float>::max())) {
    Fail(error_code::kInvalidField, "/tolerance", ShowValue(*tolerance) + " is out of range", expected);
  }
  return value;
}

Scene ReadScene(const json& request) {
  const auto scene = request.find("scene");
  if (scene == request.end()) {
    Fail(error_code::kMissingField, "/scene", "missing", "a scene object (proto/scene.md)");
  }
  try {
    // No base directory: a scene from the network must inline its meshes, never name a
    // file on the coordinator's disk.
    return ParseScene(scene->dump());
  } catch (const SceneError& error) {
    // SceneError's text already reads "scene<pointer>: ...", which is this body's pointer.
    throw ApiError(400, error_code::kInvalidScene, error.what(), "/scene" + error.pointer());
  }
}

std::pair<int, int> ReadFrameRange(const json& request, const RenderSettings& render) {
  const int first = render.firstFrame;
  const int last = render.LastFrame();
  const auto frames = request.find("frames");
  if (frames == request.end()) return {first, last};
  if (!frames->is_object()) {
    Fail(error_code::kInvalidField, "/frames", ShowValue(*frames) + " is not an object",
         "{\"start\": first frame, \"end\": last frame}, both inclusive");
  }
  for (const auto& item : frames->items()) {
    if (item.key() != "start" && item.key() != "end") {
      Fail(error_code::kUnknownField, "/frames/" + EscapePointerToken(item.key()), "unknown field",
           "only the fields start, end");
    }
  }
  const std::string inScene = "an integer in the scene's frame range [" + std::to_string(first) +
                              ", " + std::to_string(last) + "]";
  const int start = frames->contains("start")
                        ? ReadInteger(frames->at("start"), "/frames/start", first, last, inScene)
                        : first;
  const int end = frames->contains("end")
                      ? ReadInteger(frames->at("end"), "/frames/end", first, last, inScene)
                      : last;
  if (end < start) {
    Fail(error_code::kInvalidField, "/frames/end",
         std::to_string(end) + " is before frames/start " + std::to_string(start),
         "an end frame at or after the start frame");
  }
  return {start, end};
}

// "verify": {"frames": "all"} or {"sample": K}: frames also rendered brute force and
// compared. Stored in the job's options for the farm.
json ReadVerify(const json& request) {
  const auto verify = request.find("verify");
  if (verify == request.end()) return nullptr;
  const std::string expected = R"({"frames": "all"} or {"sample": K} with K in [1, 100000])";
  if (!verify->is_object() || verify->size() != 1) {
    Fail(error_code::kInvalidField, "/verify", ShowValue(*verify) + " is not a verification request",
         expected);
  }
  if (verify->contains("frames")) {
    if ((*verify)["frames"] != "all") {
      Fail(error_code::kInvalidField, "/verify/frames", ShowValue((*verify)["frames"]) + " is not \"all\"",
           expected);
    }
    return {{"frames", "all"}};
  }
  if (!verify->contains("sample")) {
    Fail(error_code::kUnknownField, "/verify/" + verify->begin().key(), "unknown field", expected);
  }
  return {{"sample", ReadInteger((*verify)["sample"], "/verify/sample", 1, 100000, expected)}};
}

// Share of copied pixels traced again as spot checks, at most 2 %.
json ReadSpotCheckShare(const json& request) {
  const auto share = request.find("spot_check_share");
  if (share == request.end()) return nullptr;
  if (!share->is_number()) {
    Fail(error_code::kInvalidField, "/spot_check_share", ShowValue(*share) + " is not a number", "a number in [0, 0.02]");
  }
  if (!std::isfinite(share->get<double>()) || share->get<double>() < 0 || share->get<double>() > 0.02) {
    Fail(error_code::kInvalidField, "/spot_check_share", ShowValue(*share) + " is out of range",
         "a number in [0, 0.02]");
  }
  return *share;
}

}  // namespace

JobSpec ParseSubmission(const std::string& body) {
  const json request = ParseBody(body);
  if (!request.is_object()) {
    Fail(error_code::kInvalidField, "", ShowValue(request) + " is not an object",
         "a JSON object with at least a \"scene\"");
  }
  CheckKnownFields(request);

  JobSpec spec;
  // Cheap fields first, so a typo in one of them is reported before a long scene parse.
  spec.name = ReadName(request);
  spec.strategy = ReadStrategy(request);
  spec.binWidth = ReadOptionalInteger(request, "bin_width", kMinBinWidth, kMaxBinWidth, kDefaultBinWidth);
  spec.tolerance = ReadTolerance(request);
  spec.priority = ReadOptionalInteger(request, "priority", kMinPriority, kMaxPriority, 0);
  spec.options = json::object();
  if (json verify = ReadVerify(request); !verify.is_null()) spec.options["verify"] = verify;
  if (json share = ReadSpotCheckShare(request); !share.is_null()) {
    spec.options["spot_check_share"] = share;
  }

  const Scene scene = ReadScene(request);
  std::tie(spec.firstFrame, spec.lastFrame) = ReadFrameRange(request, scene.render);
  // The canonical text, not the client's: equal scenes get equal hashes, whatever their
  // key order or spacing, so workers cache them once.
  spec.sceneJson = SerializeScene(scene);
  spec.sceneHash = wire::Sha256Hex(spec.sceneJson);
  spec.frameSize = FrameSize{scene.render.width, scene.render.height};
  spec.cameraOrLightsChange = scene.CameraMoves() || scene.AnyLightChanges();
  return spec;
}

}  // namespace tcfarm::http
