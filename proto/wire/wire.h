// The wire protocol between the coordinator and its workers: every message is four
// ZeroMQ frames [version][command][header][payload]. The header is a msgpack map of
// small fields; bulk data (pixel spans, RGB, horizons, scene JSON) travels in the
// payload as raw little-endian binary, so the hot path is a size check and a memcpy.
// proto/wire.md is the full contract; this codec knows nothing about sockets.
//
// Every byte that arrives is untrusted: Decode checks all of it and throws WireError
// rather than hand the daemon a message it would have to second-guess.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "proto/pixel_set/pixel_set.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm::wire {

// Bumped on any change an old receiver could misread; see proto/wire.md, "Versioning".
inline constexpr uint8_t kWireVersion = 2;
inline constexpr size_t kPartCount = 4;

enum class Command : uint8_t {
  kReady = 1,
  kTask = 2,
  kResult = 3,
  kSceneGet = 4,
  kScene = 5,
  kHeartbeat = 6,
  kError = 7,
  kDisconnect = 8,
  kAssetGet = 9,
  kAsset = 10,
};

// Limits on what a receiver accepts. Each is far above any honest message and low
// enough that a hostile one cannot make a daemon allocate or log without bound.
inline constexpr uint32_t kMaxImageSide = scene_limits::kMaxImageSide;  // a TASK renders a scene's frame
inline constexpr size_t kMaxNameBytes = 256;                    // READY name, shows up in logs
inline constexpr size_t kMaxErrorMessageBytes = 4096;           // ERROR message, shows up in logs
inline constexpr size_t kMaxSceneJsonBytes = size_t{256} << 20; // 256 MiB; the largest terrains are tens of MiB
inline constexpr size_t kMaxHeaderBytes = 16 * 1024;            // the largest honest header (ERROR) is ~4.2 KiB
inline constexpr int kMaxHeaderNesting = 8;                     // the decoder recurses per level
inline constexpr uint32_t kMaxCapacity = 4096;                  // tasks in flight per worker
inline constexpr size_t kSceneHashChars = 64;                   // SHA-256 in lowercase hex
// An asset travels in pieces of at most this much, so that no one ZeroMQ message holds a
// whole 512 MiB texture and the coordinator's loop reads a bounded amount per turn.
inline constexpr size_t kMaxAssetPieceBytes = size_t{16} << 20;
inline constexpr uint64_t kMaxAssetBytes = uint64_t{64} << 30;  // any one asset; daemons set lower limits

// worker -> coordinator, on every (re)connect: "I accept up to `capacity` tasks in flight".
struct Ready {
  uint32_t capacity = 1;
  uint32_t threads = 1;
  std::string name;  // host:pid or similar, for logs and the dashboard
};

// coordinator -> worker: trace `pixels` of `frame`.
struct Task {
  uint64_t taskId = 0;
  uint64_t jobId = 0;
  std::string sceneHash;
  int32_t frame = 0;
  uint32_t width = 0;
  uint32_t height = 0;
  PixelSet pixels;     // never empty
  int32_t window = 0;  // look-ahead frames for validity horizons; 0 = no horizons
};

// worker -> coordinator: the traced values of a task's pixels, in pixel-set order.
struct Result {
  uint64_t taskId = 0;
  uint64_t jobId = 0;
  int32_t frame = 0;
  std::vector<float> rgb;         // 3 per pixel, all finite
  std::vector<int32_t> horizons;  // empty, or 1 per pixel
  double traceSeconds = 0;
  // CPU seconds of the tracing threads, summed; absent from workers that do not report it.
  std::optional<double> traceCpuSeconds;
  uint64_t primaryRays = 0;
  uint64_t shadowRays = 0;
  uint64_t reflectionRays = 0;
  uint64_t refractionRays = 0;

  size_t PixelCount() const { return rgb.size() / 3; }
};

// worker -> coordinator: "send me this scene".
struct SceneGet {
  std::string sceneHash;
};

// coordinator -> worker: the scene, as the exact bytes whose SHA-256 is sceneHash.
struct SceneData {
  std::string sceneHash;
  std::string sceneJson;
};

// worker -> coordinator when idle; carries nothing, since any message proves liveness.
struct Heartbeat {};

// worker -> coordinator: a task (or a scene) could not be done, e.g. the scene failed to build.
struct Error {
  uint64_t taskId = 0;    // 0 when the error is not about one task
  std::string sceneHash;  // empty, or the scene at fault
  std::string message;
  std::string assetHash;  // empty, or the asset the coordinator cannot serve (optional on the wire)
};

// either side: "I am going away", so the other need not wait out the liveness timeout.
struct Disconnect {};

// worker -> coordinator: "send me the file whose SHA-256 is assetHash" (a texture a scene
// names by hash).
struct AssetGet {
  std::string assetHash;
};

// coordinator -> worker: bytes [offset, offset + bytes.size()) of the asset, which is
// totalSize bytes long. Pieces arrive in order of offset.
struct AssetPiece {
  std::string assetHash;
  uint64_t offset = 0;
  uint64_t totalSize = 0;
  std::string bytes;

  bool IsLast() const { return offset + bytes.size() == totalSize; }
};

using Message =
    std::variant<Ready, Task, Result, SceneGet, SceneData, Heartbeat, Error, Disconnect, AssetGet, AssetPiece>;

// Everything Decode rejects. what() names the command (when known) and the problem.
class WireError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Always kPartCount parts. Throws std::invalid_argument for a message that has no
// encoding (RESULT rgb not a multiple of 3, horizons neither empty nor one per pixel);
// everything else is left for the receiver to judge, so tests can send bad messages.
std::vector<std::string> Encode(const Message& message);
// The same, for a message not held in a Message: converting a Result or a scene to a
// Message first would copy its bulk data.
std::vector<std::string> Encode(const Ready& ready);
std::vector<std::string> Encode(const Task& task);
std::vector<std::string> Encode(const Result& result);
std::vector<std::string> Encode(const SceneGet& sceneGet);
std::vector<std::string> Encode(const SceneData& scene);
std::vector<std::string> Encode(const Heartbeat& heartbeat);
std::vector<std::string> Encode(const Error& error);
std::vector<std::string> Encode(const Disconnect& disconnect);
std::vector<std::string> Encode(const AssetGet& assetGet);
std::vector<std::string> Encode(const AssetPiece& piece);

// Checks everything listed in proto/wire.md, "Receiving"; throws WireError otherwise.
Message Decode(const std::vector<std::string>& parts);

Command CommandOf(const Message& message);
std::string CommandName(Command command);  // "READY", "SCENE_GET", ...; for logs and metric labels

// True for 64 lowercase hex characters: the only form a scene (or asset) hash takes.
bool IsSceneHash(std::string_view text);

}  // namespace tcfarm::wire
