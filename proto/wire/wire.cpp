#include "proto/wire/wire.h"

#include <nlohmann/json.hpp>

#include "proto/wire/content_hash.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <type_traits>
#include <utility>

namespace tcfarm::wire {

// Payloads are little-endian IEEE 754 and are copied whole between the wire and the
// vectors; a big-endian host would need a byte swap here instead of a memcpy.
static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "the wire payload is little-endian");
static_assert(std::numeric_limits<float>::is_iec559 && sizeof(float) == 4, "rgb travels as IEEE 754 binary32");
static_assert(std::is_trivially_copyable_v<Span> && sizeof(Span) == 8 && offsetof(Span, end) == 4,
              "spans travel as (begin, end) uint32 pairs, copied as a block");

namespace {

using json = nlohmann::json;

constexpr size_t kRgbBytesPerPixel = 3 * sizeof(float);
constexpr size_t kHorizonBytesPerPixel = sizeof(int32_t);
constexpr uint32_t kMaxPixelCount = kMaxImageSide * kMaxImageSide;  // 2^28: fits uint32
constexpr size_t kQuotedExcerptBytes = 64;

// ---------------------------------------------------------------------------------
// Error text

[[noreturn]] void Fail(Command command, const std::string& problem) {
  throw WireError(CommandName(command) + ": " + problem);
}

// Untrusted bytes quoted for an error message: printable ASCII kept, the rest escaped,
// long text cut, so a hostile peer cannot forge log lines or flood them.
std::string Quote(std::string_view text) {
  static constexpr char kHexDigits[] = "0123456789abcdef";
  std::string out = "\"";
  for (size_t i = 0; i < text.size() && i < kQuotedExcerptBytes; ++i) {
    const auto byte = static_cast<unsigned char>(text[i]);
    if (byte >= 0x20 && byte < 0x7f && byte != '"' && byte != '\\') {
      out.push_back(static_cast<char>(byte));
    } else {
      out += {'\\', 'x', kHexDigits[byte >> 4], kHexDigits[byte & 0xf]};
    }
  }
  out += text.size() > kQuotedExcerptBytes ? "\"..." : "\"";
  return out;
}

// "a float", "an integer", ...: msgpack's distinction, which json::type_name() blurs
// into "number" even though it is often the very mistake.
std::string Described(const json& value) {
  if (value.is_number_float()) return "a float";
  if (value.is_number()) return "an integer";
  if (value.is_object()) return "a map";
  if (value.is_array()) return "an array";
  if (value.is_binary()) return "binary data";
  if (value.is_null()) return "nil";
  return std::string("a ") + value.type_name();  // string, boolean
}

// ---------------------------------------------------------------------------------
// Header parsing

// Collects the header's top-level map from msgpack events. nlohmann's decoder
// recurses once per nesting level, so this refuses deep nesting before a hostile
// header can exhaust the stack; nested values (which version 1 never sends) are kept
// only as empty placeholders so that a known key holding one reads as mistyped.
class HeaderCollector : public nlohmann::json_sax<json> {
 public:
  json& header() { return header_; }
  const std::string& problem() const { return problem_; }

  bool null() override { return Scalar(nullptr); }
  bool boolean(bool value) override { return Scalar(value); }
  bool number_integer(number_integer_t value) override { return Scalar(value); }
  bool number_unsigned(number_unsigned_t value) override { return Scalar(value); }
  bool number_float(number_float_t value, const string_t&) override { return Scalar(value); }
  bool string(string_t& value) override { return Scalar(std::move(value)); }
  bool binary(binary_t& value) override { return Scalar(json::binary(std::move(value))); }
  bool start_object(std::size_t) override { return Open(json::object()); }
  bool start_array(std::size_t) override { return Open(json::array()); }
  bool end_object() override { return Close(); }
  bool end_array() override { return Close(); }

  bool key(string_t& key) override {
    if (depth_ == 1) key_ = std::move(key);
    return true;
  }

  bool parse_error(std::size_t, const std::string&, const json::exception& error) override {
    return Reject("is not msgpack (" + std::string(error.what()) + ")");
  }

 private:
  bool Scalar(json value) {
    if (depth_ == 0) return Reject("is " + Described(value) + "; expected a map");
    if (depth_ == 1) header_[key_] = std::move(value);
    return true;
  }

  bool Open(json container) {
    if (depth_ == 0 && !container.is_object()) return Reject("is an array; expected a map");
    if (depth_ == 1) header_[key_] = std::move(container);
    if (++depth_ > kMaxHeaderNesting) {
      return Reject("nests deeper than " + std::to_string(kMaxHeaderNesting) + " levels");
    }
    return true;
  }

  bool Close() {
    --depth_;
    return true;
  }

  bool Reject(std::string problem) {
    if (problem_.empty()) problem_ = std::move(problem);
    return false;
  }

  json header_ = json::object();
  std::string key_;
  int depth_ = 0;
  std::string problem_;
};

// Typed, checked access to the fields of a received header. Every accessor throws
// WireError naming the command and the field.
class Header {
 public:
  Header(Command command, const std::string& bytes) : command_(command) { Parse(bytes); }

  Command command() const { return command_; }

  uint64_t U64(const char* key) const { return Integer<uint64_t>(key); }
  uint32_t U32(const char* key) const { return Integer<uint32_t>(key); }
  int32_t I32(const char* key) const { return Integer<int32_t>(key); }

  uint32_t U32InRange(const char* key, uint32_t low, uint32_t high) const {
    const uint32_t value = U32(key);
    if (value < low || value > high) FailRange(key, std::to_string(value), low, high);
    return value;
  }

  bool Has(const char* key) const { return fields_.find(key) != fields_.end(); }

  bool Bool(const char* key) const {
    const json& value = Field(key);
    if (!value.is_boolean()) FailType(key, value, "a boolean");
    return value.get<bool>();
  }

  double FiniteNonNegative(const char* key) const {
    const json& value = Field(key);
    if (!value.is_number()) FailType(key, value, "a number");
    const double number = value.get<double>();
    if (!std::isfinite(number) || number < 0) {
      Fail(command_, "header field '" + std::string(key) + "' is " + std::to_string(number) +
                         "; expected a finite number >= 0");
    }
    return number;
  }

  std::string String(const char* key, size_t maxBytes) const {
    const json& value = Field(key);
    if (!value.is_string()) FailType(key, value, "a string");
    const auto& text = value.get_ref<const std::string&>();
    if (text.size() > maxBytes) {
      Fail(command_, "header field '" + std::string(key) + "' is " + std::to_string(text.size()) +
                         " bytes; expected at most " + std::to_string(maxBytes));
    }
    return text;
  }

  // Read with the header's own bound so that a hash of the wrong length gets the
  // hash message rather than a length one. Scenes and assets are named alike.
  std::string SceneHash(const char* key) const {
    std::string hash = String(key, kMaxHeaderBytes);
    if (!IsSceneHash(hash)) FailHash(key, hash);
    return hash;
  }

  // ERROR may concern no scene at all.
  std::string SceneHashOrEmpty(const char* key) const {
    std::string hash = String(key, kMaxHeaderBytes);
    if (!hash.empty() && !IsSceneHash(hash)) FailHash(key, hash);
    return hash;
  }

 private:
  void Parse(const std::string& bytes) {
    if (bytes.size() > kMaxHeaderBytes) {
      Fail(command_, "header is " + std::to_string(bytes.size()) + " bytes; expected at most " +
                         std::to_string(kMaxHeaderBytes));
    }
    HeaderCollector collector;
    bool parsed = false;
    try {
      parsed = json::sax_parse(bytes, &collector, json::input_format_t::msgpack, /*strict=*/true);
    } catch (const json::exception& error) {
      Fail(command_, "header is not msgpack (" + std::string(error.what()) + ")");
    }
    if (!parsed) Fail(command_, "header " + collector.problem());
    fields_ = std::move(collector.header());
  }

  const json& Field(const char* key) const {
    const auto it = fields_.find(key);
    if (it == fields_.end()) Fail(command_, "header field '" + std::string(key) + "' is missing");
    return *it;
  }

  // Accepts any msgpack integer encoding whose value fits Int: senders other than
  // nlohmann may write a small positive number as a signed type.
  template <typename Int>
  Int Integer(const char* key) const {
    const json& value = Field(key);
    if (value.is_number_unsigned()) return FitUnsigned<Int>(key, value.get<uint64_t>());
    if (!value.is_number_integer()) FailType(key, value, "an integer");
    const int64_t number = value.get<int64_t>();
    if (number >= 0) return FitUnsigned<Int>(key, static_cast<uint64_t>(number));
    if (!std::is_signed_v<Int> || number < static_cast<int64_t>(std::numeric_limits<Int>::min())) {
      FailRange(key, std::to_string(number), std::numeric_limits<Int>::min(), std::numeric_limits<Int>::max());
    }
    return static_cast<Int>(number);
  }

  template <typename Int>
  Int FitUnsigned(const char* key, uint64_t number) const {
    if (number > static_cast<uint64_t>(std::numeric_limits<Int>::max())) {
      FailRange(key, std::to_string(number), std::numeric_limits<Int>::min(), std::numeric_limits<Int>::max());
    }
    return static_cast<Int>(number);
  }

  template <typename Bound>
  [[noreturn]] void FailRange(const char* key, const std::string& value, Bound low, Bound high) const {
    Fail(command_, "header field '" + std::string(key) + "' is " + value + "; expected " + std::to_string(low) +
                       ".." + std::to_string(high));
  }

  [[noreturn]] void FailType(const char* key, const json& value, const char* expected) const {
    Fail(command_, "header field '" + std::string(key) + "' is " + Described(value) + "; expected " + expected);
  }

  [[noreturn]] void FailHash(const char* key, const std::string& hash) const {
    Fail(command_, "header field '" + std::string(key) + "' is " + Quote(hash) +
                       "; expected 64 lowercase hex characters (a SHA-256)");
  }

  Command command_;
  json fields_;
};

// ---------------------------------------------------------------------------------
// Payload blocks

// Appends the vector's memory as is: the host's layout is the wire's (see the
// static_asserts above).
template <typename T>
void AppendBytes(const std::vector<T>& values, std::string& bytes) {
  bytes.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

template <typename T>
std::vector<T> ValuesOf(const char* bytes, size_t count) {
  std::vector<T> values(count);
  if (count > 0) std::memcpy(values.data(), bytes, count * sizeof(T));
  return values;
}

// One branch-free pass (it vectorizes) for the common all-finite case; the slow search
// for the culprit runs only when a bad value exists.
bool AllFinite(const std::vector<float>& values) {
  constexpr uint32_t kExponentMask = 0x7f800000;  // all ones: Inf or NaN
  uint32_t anyNonFinite = 0;
  for (float value : values) {
    uint32_t bits;
    std::memcpy(&bits, &value, sizeof bits);
    anyNonFinite |= static_cast<uint32_t>((bits & kExponentMask) == kExponentMask);
  }
  return anyNonFinite == 0;
}

void CheckRgbFinite(const std::vector<float>& rgb) {
  if (AllFinite(rgb)) return;
  for (size_t i = 0; i < rgb.size(); ++i) {
    if (std::isfinite(rgb[i])) continue;
    Fail(Command::kResult, "rgb value " + std::to_string(i) + " (pixel " + std::to_string(i / 3) + ", channel " +
                               "rgb"[i % 3] + ") is " + (std::isnan(rgb[i]) ? "NaN" : "infinite") +
                               "; a result must hold finite values only");
  }
}

void CheckEmptyPayload(Command command, const std::string& payload) {
  if (!payload.empty()) Fail(command, "payload is " + std::to_string(payload.size()) + " bytes; expected none");
}

// ---------------------------------------------------------------------------------
// Encoding, one overload per message

struct Body {
  Command command;
  json header;
  std::string payload;
};

Body EncodeBody(const Ready& ready) {
  return {Command::kReady, {{"capacity", ready.capacity}, {"threads", ready.threads}, {"name", ready.name}}, {}};
}

Body EncodeBody(const Task& task) {
  json header = {{"task_id", task.taskId}, {"job_id", task.jobId}, {"scene_hash", task.sceneHash},
                 {"frame", task.frame},    {"width", task.width}, {"height", task.height},
                 {"window", task.window}};
  std::string payload;
  AppendBytes(task.pixels.spans(), payload);
  return {Command::kTask, std::move(header), std::move(payload)};
}

Body EncodeBody(const Result& result) {
  if (result.rgb.size() % 3 != 0) {
    throw std::invalid_argument("RESULT rgb holds " + std::to_string(result.rgb.size()) +
                                " floats; expected 3 per pixel");
  }
  if (!result.horizons.empty() && result.horizons.size() != result.PixelCount()) {
    throw std::invalid_argument("RESULT holds " + std::to_string(result.horizons.size()) + " horizons for " +
                                std::to_string(result.PixelCount()) + " pixels; expected none or one per pixel");
  }
  json header = {{"task_id", result.taskId},
                 {"job_id", result.jobId},
                 {"frame", result.frame},
                 {"pixel_count", result.PixelCount()},
                 {"has_horizons", !result.horizons.empty()},
                 {"trace_seconds", result.traceSeconds},
                 {"primary_rays", result.primaryRays},
                 {"shadow_rays", result.shadowRays},
                 {"reflection_rays", result.reflectionRays},
                 {"refraction_rays", result.refractionRays}};
  if (result.traceCpuSeconds) header["trace_cpu_seconds"] = *result.traceCpuSeconds;
  std::string payload;
  payload.reserve(result.rgb.size() * sizeof(float) + result.horizons.size() * sizeof(int32_t));
  AppendBytes(result.rgb, payload);
  AppendBytes(result.horizons, payload);
  return {Command::kResult, std::move(header), std::move(payload)};
}

Body EncodeBody(const SceneGet& sceneGet) {
  return {Command::kSceneGet, {{"scene_hash", sceneGet.sceneHash}}, {}};
}

Body EncodeBody(const SceneData& scene) {
  return {Command::kScene, {{"scene_hash", scene.sceneHash}}, scene.sceneJson};
}

Body EncodeBody(const Heartbeat&) { return {Command::kHeartbeat, json::object(), {}}; }

Body EncodeBody(const Error& error) {
  json header = {{"task_id", error.taskId}, {"scene_hash", error.sceneHash}, {"message", error.message}};
  if (!error.assetHash.empty()) header["asset_hash"] = error.assetHash;
  return {Command::kError, std::move(header), {}};
}

Body EncodeBody(const Disconnect&) { return {Command::kDisconnect, json::object(), {}}; }

Body EncodeBody(const AssetGet& assetGet) { return {Command::kAssetGet, {{"asset_hash", assetGet.assetHash}}, {}}; }

Body EncodeBody(const AssetPiece& piece) {
  json header = {{"asset_hash", piece.assetHash}, {"offset", piece.offset}, {"total_size", piece.totalSize}};
  return {Command::kAsset, std::move(header), piece.bytes};
}

// ---------------------------------------------------------------------------------
// Decoding, one function per command

Ready DecodeReady(const Header& header, const std::string& payload) {
  CheckEmptyPayload(header.command(), payload);
  Ready ready;
  ready.capacity = header.U32InRange("capacity", 1, kMaxCapacity);
  ready.threads = header.U32("threads");
  ready.name = header.String("name", kMaxNameBytes);
  for (char c : ready.name) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      Fail(Command::kReady, "name " + Quote(ready.name) + " holds control characters; it is written to logs");
    }
  }
  return ready;
}

PixelSet DecodeSpans(const std::string& payload, uint32_t pixelCount) {
  if (payload.empty()) Fail(Command::kTask, "payload holds no pixel spans; a task must cover at least one pixel");
  if (payload.size() % sizeof(Span) != 0) {
    Fail(Command::kTask, "payload is " + std::to_string(payload.size()) +
                             " bytes; expected a whole number of 8-byte (begin, end) spans");
  }
  const size_t spanCount = payload.size() / sizeof(Span);
  // Spans are non-empty and disjoint, so more spans than pixels cannot be valid; this
  // also keeps a hostile payload from costing more than one cheap check.
  if (spanCount > pixelCount) {
    Fail(Command::kTask, std::to_string(spanCount) + " spans cannot fit a frame of " + std::to_string(pixelCount) +
                             " pixels");
  }
  try {
    return PixelSet::FromSpans(ValuesOf<Span>(payload.data(), spanCount), pixelCount);
  } catch (const std::invalid_argument& error) {
    Fail(Command::kTask, error.what());
  }
}

Task DecodeTask(const Header& header, const std::string& payload) {
  Task task;
  task.taskId = header.U64("task_id");
  task.jobId = header.U64("job_id");
  task.sceneHash = header.SceneHash("scene_hash");
  task.frame = header.I32("frame");
  task.width = header.U32InRange("width", 1, kMaxImageSide);
  task.height = header.U32InRange("height", 1, kMaxImageSide);
  task.window = header.I32("window");
  if (task.window < 0) {
    Fail(Command::kTask, "header field 'window' is " + std::to_string(task.window) + "; expected >= 0");
  }
  task.pixels = DecodeSpans(payload, task.width * task.height);
  return task;
}

// A horizon is the first frame after the traced one at which the pixel may change;
// one at or before the traced frame would send the planner backwards.
void CheckHorizonsAfterFrame(const std::vector<int32_t>& horizons, int32_t frame) {
  int32_t earliest = std::numeric_limits<int32_t>::max();
  for (int32_t horizon : horizons) earliest = std::min(earliest, horizon);
  if (horizons.empty() || earliest > frame) return;
  for (size_t i = 0; i < horizons.size(); ++i) {
    if (horizons[i] > frame) continue;
    Fail(Command::kResult, "horizon of pixel " + std::to_string(i) + " is frame " + std::to_string(horizons[i]) +
                               "; expected a frame after the traced frame " + std::to_string(frame));
  }
}

void DecodeResultPayload(const std::string& payload, uint32_t pixelCount, bool hasHorizons, Result& result) {
  const size_t rgbBytes = size_t{pixelCount} * kRgbBytesPerPixel;
  const size_t horizonBytes = hasHorizons ? size_t{pixelCount} * kHorizonBytesPerPixel : 0;
  if (payload.size() != rgbBytes + horizonBytes) {
    Fail(Command::kResult, "payload is " + std::to_string(payload.size()) + " bytes; expected " +
                               std::to_string(rgbBytes + horizonBytes) + " (" + std::to_string(pixelCount) +
                               " pixels x " + (hasHorizons ? "(12 bytes rgb + 4 bytes horizon))" : "12 bytes rgb)"));
  }
  result.rgb = ValuesOf<float>(payload.data(), size_t{pixelCount} * 3);
  CheckRgbFinite(result.rgb);
  if (!hasHorizons) return;
  result.horizons = ValuesOf<int32_t>(payload.data() + rgbBytes, pixelCount);
  CheckHorizonsAfterFrame(result.horizons, result.frame);
}

Result DecodeResult(const Header& header, const std::string& payload) {
  Result result;
  result.taskId = header.U64("task_id");
  result.jobId = header.U64("job_id");
  result.frame = header.I32("frame");
  const uint32_t pixelCount = header.U32InRange("pixel_count", 1, kMaxPixelCount);
  const bool hasHorizons = header.Bool("has_horizons");
  result.traceSeconds = header.FiniteNonNegative("trace_seconds");
  if (header.Has("trace_cpu_seconds")) result.traceCpuSeconds = header.FiniteNonNegative("trace_cpu_seconds");
  result.primaryRays = header.U64("primary_rays");
  result.shadowRays = header.U64("shadow_rays");
  result.reflectionRays = header.U64("reflection_rays");
  result.refractionRays = header.U64("refraction_rays");
  DecodeResultPayload(payload, pixelCount, hasHorizons, result);
  return result;
}

SceneGet DecodeSceneGet(const Header& header, const std::string& payload) {
  CheckEmptyPayload(header.command(), payload);
  return SceneGet{header.SceneHash("scene_hash")};
}

// The payload is not checked against the hash here: the worker does that, because on
// a mismatch it must answer ERROR for the tasks waiting on the scene rather than drop
// the message and leave them waiting.
SceneData DecodeScene(const Header& header, const std::string& payload) {
  SceneData scene;
  scene.sceneHash = header.SceneHash("scene_hash");
  if (payload.size() > kMaxSceneJsonBytes) {
    Fail(Command::kScene, "scene JSON is " + std::to_string(payload.size()) + " bytes; expected at most " +
                              std::to_string(kMaxSceneJsonBytes));
  }
  scene.sceneJson = payload;
  return scene;
}

Heartbeat DecodeHeartbeat(const Header& header, const std::string& payload) {
  CheckEmptyPayload(header.command(), payload);
  return {};
}

Error DecodeError(const Header& header, const std::string& payload) {
  CheckEmptyPayload(header.command(), payload);
  Error error;
  error.taskId = header.U64("task_id");
  error.sceneHash = header.SceneHashOrEmpty("scene_hash");
  error.message = header.String("message", kMaxErrorMessageBytes);
  if (header.Has("asset_hash")) error.assetHash = header.SceneHash("asset_hash");
  return error;
}

Disconnect DecodeDisconnect(const Header& header, const std::string& payload) {
  CheckEmptyPayload(header.command(), payload);
  return {};
}

AssetGet DecodeAssetGet(const Header& header, const std::string& payload) {
  CheckEmptyPayload(header.command(), payload);
  return AssetGet{header.SceneHash("asset_hash")};
}

// The bytes are not checked against the hash here: only the whole asset can be, and the
// worker does that when the last piece has arrived.
AssetPiece DecodeAssetPiece(const Header& header, const std::string& payload) {
  AssetPiece piece;
  piece.assetHash = header.SceneHash("asset_hash");
  piece.offset = header.U64("offset");
  piece.totalSize = header.U64("total_size");
  if (piece.totalSize > kMaxAssetBytes) {
    Fail(Command::kAsset, "total_size " + std::to_string(piece.totalSize) + " is more than the " +
                              std::to_string(kMaxAssetBytes) + " bytes an asset may have");
  }
  if (payload.size() > kMaxAssetPieceBytes) {
    Fail(Command::kAsset, "payload is " + std::to_string(payload.size()) + " bytes; expected at most " +
                              std::to_string(kMaxAssetPieceBytes));
  }
  if (piece.offset > piece.totalSize || payload.size() > piece.totalSize - piece.offset) {
    Fail(Command::kAsset, "bytes " + std::to_string(piece.offset) + ".." + std::to_string(piece.offset + payload.size()) +
                              " lie past total_size " + std::to_string(piece.totalSize));
  }
  if (payload.empty() && piece.totalSize > 0) {
    Fail(Command::kAsset, "payload is empty; expected a piece of a " + std::to_string(piece.totalSize) + "-byte asset");
  }
  piece.bytes = payload;
  return piece;
}

// ---------------------------------------------------------------------------------
// Framing

void CheckVersion(const std::string& part) {
  if (part.size() != 1) {
    throw WireError("version part is " + std::to_string(part.size()) + " bytes; expected 1");
  }
  const auto version = static_cast<uint8_t>(part[0]);
  if (version != kWireVersion) {
    throw WireError("wire version " + std::to_string(version) + " is not supported; expected " +
                    std::to_string(kWireVersion));
  }
}

Command ParseCommand(const std::string& part) {
  if (part.size() != 1) {
    throw WireError("command part is " + std::to_string(part.size()) + " bytes; expected 1");
  }
  const auto code = static_cast<uint8_t>(part[0]);
  if (code < static_cast<uint8_t>(Command::kReady) || code > static_cast<uint8_t>(Command::kAsset)) {
    throw WireError("unknown command " + std::to_string(code));
  }
  return static_cast<Command>(code);
}

Message DecodeBody(const Header& header, const std::string& payload) {
  switch (header.command()) {
    case Command::kReady: return DecodeReady(header, payload);
    case Command::kTask: return DecodeTask(header, payload);
    case Command::kResult: return DecodeResult(header, payload);
    case Command::kSceneGet: return DecodeSceneGet(header, payload);
    case Command::kScene: return DecodeScene(header, payload);
    case Command::kHeartbeat: return DecodeHeartbeat(header, payload);
    case Command::kError: return DecodeError(header, payload);
    case Command::kDisconnect: return DecodeDisconnect(header, payload);
    case Command::kAssetGet: return DecodeAssetGet(header, payload);
    case Command::kAsset: return DecodeAssetPiece(header, payload);
  }
  throw WireError("unknown command");  // unreachable: ParseCommand admits only the above
}


std::vector<std::string> Framed(Body body) {
  std::vector<std::string> parts;
  parts.reserve(kPartCount);
  parts.emplace_back(1, static_cast<char>(kWireVersion));
  parts.emplace_back(1, static_cast<char>(body.command));
  const std::vector<uint8_t> header = json::to_msgpack(body.header);
  parts.emplace_back(header.begin(), header.end());
  parts.push_back(std::move(body.payload));
  return parts;
}

}  // namespace

std::vector<std::string> Encode(const Message& message) {
  return std::visit([](const auto& typed) { return Framed(EncodeBody(typed)); }, message);
}

std::vector<std::string> Encode(const Ready& ready) { return Framed(EncodeBody(ready)); }
std::vector<std::string> Encode(const Task& task) { return Framed(EncodeBody(task)); }
std::vector<std::string> Encode(const Result& result) { return Framed(EncodeBody(result)); }
std::vector<std::string> Encode(const SceneGet& sceneGet) { return Framed(EncodeBody(sceneGet)); }
std::vector<std::string> Encode(const SceneData& scene) { return Framed(EncodeBody(scene)); }
std::vector<std::string> Encode(const Heartbeat& heartbeat) { return Framed(EncodeBody(heartbeat)); }
std::vector<std::string> Encode(const Error& error) { return Framed(EncodeBody(error)); }
std::vector<std::string> Encode(const Disconnect& disconnect) { return Framed(EncodeBody(disconnect)); }
std::vector<std::string> Encode(const AssetGet& assetGet) { return Framed(EncodeBody(assetGet)); }
std::vector<std::string> Encode(const AssetPiece& piece) { return Framed(EncodeBody(piece)); }

Message Decode(const std::vector<std::string>& parts) {
  if (parts.size() != kPartCount) {
    throw WireError("message has " + std::to_string(parts.size()) + " parts; expected " + std::to_string(kPartCount) +
                    " [version][command][header][payload]");
  }
  CheckVersion(parts[0]);
  const Header header(ParseCommand(parts[1]), parts[2]);
  return DecodeBody(header, parts[3]);
}

Command CommandOf(const Message& message) {
  // The variant lists the messages in command order, READY = 1 first.
  static_assert(std::variant_size_v<Message> == 10 && std::is_same_v<std::variant_alternative_t<0, Message>, Ready> &&
                std::is_same_v<std::variant_alternative_t<1, Message>, Task> &&
                std::is_same_v<std::variant_alternative_t<2, Message>, Result> &&
                std::is_same_v<std::variant_alternative_t<3, Message>, SceneGet> &&
                std::is_same_v<std::variant_alternative_t<4, Message>, SceneData> &&
                std::is_same_v<std::variant_alternative_t<5, Message>, Heartbeat> &&
                std::is_same_v<std::variant_alternative_t<6, Message>, Error> &&
                std::is_same_v<std::variant_alternative_t<7, Message>, Disconnect> &&
                std::is_same_v<std::variant_alternative_t<8, Message>, AssetGet> &&
                std::is_same_v<std::variant_alternative_t<9, Message>, AssetPiece>);
  return static_cast<Command>(message.index() + 1);
}

std::string CommandName(Command command) {
  switch (command) {
    case Command::kReady: return "READY";
    case Command::kTask: return "TASK";
    case Command::kResult: return "RESULT";
    case Command::kSceneGet: return "SCENE_GET";
    case Command::kScene: return "SCENE";
    case Command::kHeartbeat: return "HEARTBEAT";
    case Command::kError: return "ERROR";
    case Command::kDisconnect: return "DISCONNECT";
    case Command::kAssetGet: return "ASSET_GET";
    case Command::kAsset: return "ASSET";
  }
  return "UNKNOWN";
}

bool IsSceneHash(std::string_view text) { return IsSha256Hex(text); }

}  // namespace tcfarm::wire
