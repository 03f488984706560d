#include "proto/wire/wire.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <iterator>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "proto/wire/content_hash.h"

namespace tcfarm::wire {

// Field-by-field equality, for EXPECT_EQ on decoded messages. Floats compare by bits:
// the wire must carry every value (-0, denormals) unchanged.
bool SameBits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}
bool operator==(const Ready& a, const Ready& b) {
  return a.capacity == b.capacity && a.threads == b.threads && a.name == b.name;
}
bool operator==(const Task& a, const Task& b) {
  return a.taskId == b.taskId && a.jobId == b.jobId && a.sceneHash == b.sceneHash && a.frame == b.frame &&
         a.width == b.width && a.height == b.height && a.pixels == b.pixels && a.window == b.window;
}
bool operator==(const Result& a, const Result& b) {
  return a.taskId == b.taskId && a.jobId == b.jobId && a.frame == b.frame && SameBits(a.rgb, b.rgb) &&
         a.horizons == b.horizons && a.traceSeconds == b.traceSeconds &&
         a.traceCpuSeconds == b.traceCpuSeconds && a.primaryRays == b.primaryRays &&
         a.shadowRays == b.shadowRays && a.reflectionRays == b.reflectionRays && a.refractionRays == b.refractionRays;
}
bool operator==(const SceneGet& a, const SceneGet& b) { return a.sceneHash == b.sceneHash; }
bool operator==(const SceneData& a, const SceneData& b) {
  return a.sceneHash == b.sceneHash && a.sceneJson == b.sceneJson;
}
bool operator==(const Heartbeat&, const Heartbeat&) { return true; }
bool operator==(const Error& a, const Error& b) {
  return a.taskId == b.taskId && a.sceneHash == b.sceneHash && a.message == b.message && a.assetHash == b.assetHash;
}
bool operator==(const Disconnect&, const Disconnect&) { return true; }
bool operator==(const AssetGet& a, const AssetGet& b) { return a.assetHash == b.assetHash; }
bool operator==(const AssetPiece& a, const AssetPiece& b) {
  return a.assetHash == b.assetHash && a.offset == b.offset && a.totalSize == b.totalSize && a.bytes == b.bytes;
}

namespace {

using json = nlohmann::json;
using Parts = std::vector<std::string>;

const std::string kSceneJson = R"({"camera":{"position":[0,1,5]},"frames":24})";
const std::string kHash = Sha256Hex(kSceneJson);

// ---------------------------------------------------------------------------------
// Sample messages

Task SampleTask() {
  Task task;
  task.taskId = 42;
  task.jobId = 7;
  task.sceneHash = kHash;
  task.frame = 12;
  task.width = 64;
  task.height = 32;
  task.pixels = PixelSet::FromSpans({{0, 10}, {100, 164}, {2000, 2048}}, 64 * 32);
  task.window = 8;
  return task;
}

Result SampleResult(bool withHorizons) {
  Result result;
  result.taskId = 42;
  result.jobId = 7;
  result.frame = 12;
  result.rgb = {0.25f, 0.5f, 1.0f, -0.0f, std::numeric_limits<float>::denorm_min(), 3.0e38f};
  if (withHorizons) result.horizons = {15, 13};
  result.traceSeconds = 0.0125;
  result.traceCpuSeconds = 0.02;
  result.primaryRays = 2;
  result.shadowRays = 4;
  result.reflectionRays = 1;
  result.refractionRays = 0;
  return result;
}

Error SampleError() { return Error{42, kHash, "scene failed to build: mesh 3 has no triangles", ""}; }

AssetPiece SamplePiece() { return AssetPiece{kHash, 16, 40, std::string("\x89PNG\0\xff", 6)}; }

// One valid message of every command, for the tests that go over them all.
std::vector<Message> SampleMessages() {
  return {Ready{8, 16, "worker-3:4242"}, SampleTask(),          SampleResult(true), SceneGet{kHash},
          SceneData{kHash, kSceneJson},  Heartbeat{},           SampleError(),      Disconnect{},
          AssetGet{kHash},               SamplePiece()};
}

Message RoundTrip(const Message& message) { return Decode(Encode(message)); }

template <typename T>
void ExpectRoundTrip(const T& message) {
  const Message decoded = RoundTrip(message);
  ASSERT_TRUE(std::holds_alternative<T>(decoded)) << "decoded as " << CommandName(CommandOf(decoded));
  EXPECT_TRUE(std::get<T>(decoded) == message);
}

// ---------------------------------------------------------------------------------
// Helpers for building hostile input

json HeaderOf(const Parts& parts) { return json::from_msgpack(parts[2]); }

std::string Msgpack(const json& header) {
  const std::vector<uint8_t> bytes = json::to_msgpack(header);
  return std::string(bytes.begin(), bytes.end());
}

Parts WithHeader(Parts parts, const std::function<void(json&)>& edit) {
  json header = HeaderOf(parts);
  edit(header);
  parts[2] = Msgpack(header);
  return parts;
}

Parts WithField(const Message& message, const std::string& key, const json& value) {
  return WithHeader(Encode(message), [&](json& header) { header[key] = value; });
}

Parts WithPayload(const Message& message, std::string payload) {
  Parts parts = Encode(message);
  parts[3] = std::move(payload);
  return parts;
}

template <typename T>
std::string BytesOf(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

Parts TaskWithSpans(const std::vector<uint32_t>& flatSpans) { return WithPayload(SampleTask(), BytesOf(flatSpans)); }

Parts ResultWithRgb(float value, size_t index) {
  Result result = SampleResult(false);
  result.rgb[index] = value;
  return Encode(result);
}

#define EXPECT_WIRE_ERROR(parts, expectedText)                                                         \
  do {                                                                                                 \
    try {                                                                                              \
      Decode(parts);                                                                                   \
      ADD_FAILURE() << "decoded; expected WireError containing \"" << (expectedText) << "\"";           \
    } catch (const WireError& error) {                                                                 \
      EXPECT_NE(std::string(error.what()).find(expectedText), std::string::npos)                       \
          << "WireError \"" << error.what() << "\" does not mention \"" << (expectedText) << "\"";      \
    }                                                                                                  \
  } while (false)

// ---------------------------------------------------------------------------------
// SHA-256: the FIPS 180-4 / NIST example vectors

TEST(Sha256, EmptyString) {
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(Sha256, Abc) {
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(Sha256, TwoBlockMessage) {
  EXPECT_EQ(Sha256Hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256, MillionAs) {
  EXPECT_EQ(Sha256Hex(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

// Lengths on both sides of the padding boundaries (55/56 bytes, whole blocks), where a
// wrong padding rule shows; expected values from an independent implementation.
TEST(Sha256, PaddingBoundaries) {
  const std::vector<std::pair<size_t, const char*>> cases = {
      {55, "e7313d333c272e639f790978283f9eb392e843d0f29b7016828bb1daa4aac70b"},
      {56, "4324d65f3c103567f5589c710bc08f8523f929a9272e3af36fc968e52abc6c27"},
      {63, "81c80242132f230c3bd41b3e63bbcff16107339549214a99614ff26664625055"},
      {64, "39e3d7b6b5d075d37d053ad89b24b41bef4f3c29760c84447cab3f3be1882241"},
      {65, "aacca6ff74fdbb296d165a45cecfa04e5127bc008770fbbdd48006f2d2fae95e"},
      {119, "9ce7368e4daf32341631b492e80359dc9f594b48453cd0dd5bf0b19279cc177e"},
      {120, "7836b787757e95e58b3ca5aec90b1b004e8deba1e50e9675af9cabf1a13a04b5"},
      {128, "d2742f1f4ac6bb7ca2b239ee18402ba8b3f9f8e652d2a72973c2b9ba11c08cf6"},
  };
  for (const auto& [length, expected] : cases) {
    std::string bytes(length, '\0');
    for (size_t i = 0; i < length; ++i) bytes[i] = static_cast<char>((i * 7 + 3) % 256);
    EXPECT_EQ(Sha256Hex(bytes), expected) << length << " bytes";
  }
}

// Pieces of any size hash as the whole: an asset upload arrives in network-sized chunks.
TEST(Sha256, StreamInPiecesEqualsTheWhole) {
  std::string bytes(1000, '\0');
  for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>((i * 31 + 5) % 256);
  for (size_t piece : {size_t{1}, size_t{55}, size_t{64}, size_t{333}, size_t{1000}}) {
    Sha256Stream stream;
    for (size_t at = 0; at < bytes.size(); at += piece) stream.Update(std::string_view(bytes).substr(at, piece));
    EXPECT_EQ(stream.Hex(), Sha256Hex(bytes)) << piece << "-byte pieces";
  }
  Sha256Stream empty;
  EXPECT_EQ(empty.Hex(), Sha256Hex(""));
  EXPECT_THROW(empty.Update("late"), std::logic_error);
}

// ---------------------------------------------------------------------------------
// Round trips

TEST(WireRoundTrip, Ready) { ExpectRoundTrip(Ready{8, 16, "worker-3:4242"}); }
TEST(WireRoundTrip, ReadyWithLongestName) { ExpectRoundTrip(Ready{kMaxCapacity, 0, std::string(kMaxNameBytes, 'n')}); }
TEST(WireRoundTrip, Task) { ExpectRoundTrip(SampleTask()); }

TEST(WireRoundTrip, TaskWithExtremeFields) {
  Task task = SampleTask();
  task.taskId = std::numeric_limits<uint64_t>::max();
  task.jobId = std::numeric_limits<uint64_t>::max() - 1;
  task.frame = std::numeric_limits<int32_t>::min();
  task.window = std::numeric_limits<int32_t>::max();
  ExpectRoundTrip(task);
}

TEST(WireRoundTrip, TaskOfLargestFrame) {
  Task task = SampleTask();
  task.width = task.height = kMaxImageSide;
  task.pixels = PixelSet::Full(kMaxImageSide * kMaxImageSide);
  ExpectRoundTrip(task);
}

TEST(WireRoundTrip, TaskOfOnePixel) {
  Task task = SampleTask();
  task.width = task.height = 1;
  task.pixels = PixelSet::Full(1);
  task.window = 0;
  ExpectRoundTrip(task);
}

TEST(WireRoundTrip, ResultWithHorizons) { ExpectRoundTrip(SampleResult(true)); }
TEST(WireRoundTrip, ResultWithoutHorizons) { ExpectRoundTrip(SampleResult(false)); }

TEST(WireRoundTrip, ResultWithExtremeCounters) {
  Result result = SampleResult(true);
  result.frame = -3;
  result.primaryRays = result.shadowRays = std::numeric_limits<uint64_t>::max();
  result.traceSeconds = 0;
  ExpectRoundTrip(result);
}

TEST(WireRoundTrip, ResultOfManyPixels) {
  Result result = SampleResult(true);
  result.rgb.resize(3 * 100000);
  result.horizons.resize(100000);
  for (size_t i = 0; i < result.rgb.size(); ++i) result.rgb[i] = static_cast<float>(i) * 0.001f;
  for (size_t i = 0; i < result.horizons.size(); ++i) result.horizons[i] = 13 + static_cast<int32_t>(i % 97);
  ExpectRoundTrip(result);
}

TEST(WireRoundTrip, SceneGet) { ExpectRoundTrip(SceneGet{kHash}); }
TEST(WireRoundTrip, Scene) { ExpectRoundTrip(SceneData{kHash, kSceneJson}); }
TEST(WireRoundTrip, Heartbeat) { ExpectRoundTrip(Heartbeat{}); }
TEST(WireRoundTrip, Error) { ExpectRoundTrip(SampleError()); }
TEST(WireRoundTrip, ErrorAboutNoTaskOrScene) { ExpectRoundTrip(Error{0, "", "out of memory", ""}); }
TEST(WireRoundTrip, ErrorWithLongestMessage) {
  ExpectRoundTrip(Error{1, kHash, std::string(kMaxErrorMessageBytes, 'm'), ""});
}
TEST(WireRoundTrip, Disconnect) { ExpectRoundTrip(Disconnect{}); }
TEST(WireRoundTrip, ErrorAboutAnAsset) { ExpectRoundTrip(Error{0, "", "no asset", kHash}); }
TEST(WireRoundTrip, AssetGet) { ExpectRoundTrip(AssetGet{kHash}); }
TEST(WireRoundTrip, AssetPiece) {
  ExpectRoundTrip(SamplePiece());
  ExpectRoundTrip(AssetPiece{kHash, 0, 0, ""});  // an empty file is one empty piece
  ExpectRoundTrip(AssetPiece{kHash, 0, kMaxAssetPieceBytes, std::string(kMaxAssetPieceBytes, 'x')});
}

TEST(WireRoundTrip, AdjacentSpansArriveMerged) {
  const Message decoded = Decode(TaskWithSpans({0, 4, 4, 9, 20, 30}));
  EXPECT_EQ(std::get<Task>(decoded).pixels, PixelSet::FromSpans({{0, 9}, {20, 30}}, 64 * 32));
}

TEST(WireRoundTrip, UnknownHeaderFieldsAreIgnored) {
  // Within one version, senders may add fields; see proto/wire.md, "Versioning".
  const Parts parts = WithHeader(Encode(SampleTask()), [](json& header) {
    header["priority"] = 3;
    header["hints"] = {{"tile", {8, 8}}};
  });
  EXPECT_TRUE(std::get<Task>(Decode(parts)) == SampleTask());
}

TEST(WireRoundTrip, SmallPositiveIntegersMayBeEncodedSigned) {
  // Another msgpack library may write 5 as int8 (0xd0) rather than a positive fixint.
  Parts parts = Encode(Ready{5, 2, "w"});
  json header = HeaderOf(parts);
  header.erase("capacity");
  std::string bytes = Msgpack(header);
  bytes[0] = static_cast<char>(0x83);  // the map now holds three entries again
  bytes += std::string("\xa8" "capacity" "\xd0\x05", 11);
  parts[2] = bytes;
  EXPECT_EQ(std::get<Ready>(Decode(parts)).capacity, 5u);
}

TEST(WireFraming, EveryMessageIsFourPartsWithVersionAndCommand) {
  for (const Message& message : SampleMessages()) {
    const Parts parts = Encode(message);
    ASSERT_EQ(parts.size(), kPartCount);
    EXPECT_EQ(parts[0], std::string(1, static_cast<char>(kWireVersion)));
    EXPECT_EQ(static_cast<uint8_t>(parts[1][0]), static_cast<uint8_t>(CommandOf(message)));
    EXPECT_TRUE(HeaderOf(parts).is_object());
  }
}

TEST(WireFraming, CommandCodesAndNames) {
  const std::vector<std::pair<Command, std::string>> expected = {
      {Command::kReady, "READY"},         {Command::kTask, "TASK"},   {Command::kResult, "RESULT"},
      {Command::kSceneGet, "SCENE_GET"},  {Command::kScene, "SCENE"}, {Command::kHeartbeat, "HEARTBEAT"},
      {Command::kError, "ERROR"},         {Command::kDisconnect, "DISCONNECT"},
      {Command::kAssetGet, "ASSET_GET"},  {Command::kAsset, "ASSET"}};
  const std::vector<Message> messages = SampleMessages();
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(static_cast<int>(expected[i].first), static_cast<int>(i + 1));
    EXPECT_EQ(CommandName(expected[i].first), expected[i].second);
    EXPECT_EQ(CommandOf(messages[i]), expected[i].first);
  }
}

TEST(WireFraming, SceneHashShape) {
  EXPECT_TRUE(IsSceneHash(kHash));
  EXPECT_FALSE(IsSceneHash(""));
  EXPECT_FALSE(IsSceneHash(kHash.substr(1)));
  EXPECT_FALSE(IsSceneHash(kHash + "0"));
  EXPECT_FALSE(IsSceneHash(std::string(63, 'a') + "A"));
  EXPECT_FALSE(IsSceneHash(std::string(63, 'a') + "g"));
}

TEST(WireEncode, RejectsResultsWithNoEncoding) {
  Result ragged = SampleResult(false);
  ragged.rgb.pop_back();
  EXPECT_THROW(Encode(ragged), std::invalid_argument);
  Result fewHorizons = SampleResult(true);
  fewHorizons.horizons.pop_back();
  EXPECT_THROW(Encode(fewHorizons), std::invalid_argument);
}

// ---------------------------------------------------------------------------------
// Pinned layout: these bytes are the contract in proto/wire.md

TEST(WireLayout, TaskPayloadIsLittleEndianSpanPairs) {
  Task task = SampleTask();
  task.pixels = PixelSet::FromSpans({{1, 3}, {258, 2048}}, 64 * 32);
  const std::string expected("\x01\x00\x00\x00" "\x03\x00\x00\x00" "\x02\x01\x00\x00" "\x00\x08\x00\x00", 16);
  EXPECT_EQ(Encode(task)[3], expected);
}

TEST(WireLayout, TaskHeader) {
  const json expected = {{"task_id", 42}, {"job_id", 7}, {"scene_hash", kHash}, {"frame", 12},
                         {"width", 64},   {"height", 32}, {"window", 8}};
  EXPECT_EQ(HeaderOf(Encode(SampleTask())), expected);
}

TEST(WireLayout, ResultPayloadIsRgbFloatsThenHorizons) {
  Result result = SampleResult(true);
  result.rgb = {1.0f, -2.0f, 0.5f, 0.0f, 0.25f, 3.0f};
  result.horizons = {13, 256};
  const std::string expected(
      "\x00\x00\x80\x3f" "\x00\x00\x00\xc0" "\x00\x00\x00\x3f"     // pixel 0: 1, -2, 0.5
      "\x00\x00\x00\x00" "\x00\x00\x80\x3e" "\x00\x00\x40\x40"     // pixel 1: 0, 0.25, 3
      "\x0d\x00\x00\x00" "\x00\x01\x00\x00",                       // horizons: 13, 256
      32);
  EXPECT_EQ(Encode(result)[3], expected);
}

TEST(WireLayout, ResultHeader) {
  const json expected = {{"task_id", 42},          {"job_id", 7},       {"frame", 12},
                         {"pixel_count", 2},       {"has_horizons", true}, {"trace_seconds", 0.0125},
                         {"trace_cpu_seconds", 0.02},
                         {"primary_rays", 2},      {"shadow_rays", 4},  {"reflection_rays", 1},
                         {"refraction_rays", 0}};
  EXPECT_EQ(HeaderOf(Encode(SampleResult(true))), expected);
}

// A worker that does not report CPU time (an older build) still has its results read.
TEST(WireLayout, ResultWithoutCpuSecondsDecodes) {
  Result result = SampleResult(false);
  result.traceCpuSeconds.reset();
  Parts parts = Encode(result);
  EXPECT_FALSE(HeaderOf(parts).contains("trace_cpu_seconds"));
  const Message decoded = Decode(parts);
  ASSERT_TRUE(std::holds_alternative<Result>(decoded));
  EXPECT_FALSE(std::get<Result>(decoded).traceCpuSeconds.has_value());
  EXPECT_EQ(std::get<Result>(decoded), result);
}

TEST(WireLayout, ReadyHeaderBytes) {
  // A msgpack map with keys in byte order; pins the encoding down to the byte.
  const std::string expected("\x83" "\xa8" "capacity" "\x04" "\xa4" "name" "\xa1" "w" "\xa7" "threads" "\x02", 27);
  EXPECT_EQ(Encode(Ready{4, 2, "w"})[2], expected);
}

TEST(WireLayout, EmptyMessagesCarryAnEmptyMap) {
  EXPECT_EQ(Encode(Heartbeat{}), (Parts{"\x02", "\x06", "\x80", ""}));
  EXPECT_EQ(Encode(Disconnect{}), (Parts{"\x02", "\x08", "\x80", ""}));
}

TEST(WireLayout, AssetPieceHeaderAndPayload) {
  const Parts parts = Encode(SamplePiece());
  EXPECT_EQ(HeaderOf(parts), (json{{"asset_hash", kHash}, {"offset", 16}, {"total_size", 40}}));
  EXPECT_EQ(parts[3], SamplePiece().bytes);
  EXPECT_EQ(HeaderOf(Encode(AssetGet{kHash})), (json{{"asset_hash", kHash}}));
}

TEST(WireLayout, ScenePayloadIsTheJsonBytes) { EXPECT_EQ(Encode(SceneData{kHash, kSceneJson})[3], kSceneJson); }

// ---------------------------------------------------------------------------------
// Hostile input: framing

TEST(WireHostile, WrongPartCount) {
  EXPECT_WIRE_ERROR(Parts{}, "0 parts; expected 4");
  Parts three = Encode(Heartbeat{});
  three.pop_back();
  EXPECT_WIRE_ERROR(three, "3 parts");
  Parts five = Encode(Heartbeat{});
  five.push_back("");
  EXPECT_WIRE_ERROR(five, "5 parts");
}

TEST(WireHostile, WrongVersion) {
  Parts parts = Encode(Heartbeat{});
  parts[0] = "\x01";  // the version before assets travelled
  EXPECT_WIRE_ERROR(parts, "wire version 1 is not supported");
  parts[0] = "\x03";
  EXPECT_WIRE_ERROR(parts, "wire version 3 is not supported");
  parts[0] = std::string(1, '\0');
  EXPECT_WIRE_ERROR(parts, "wire version 0 is not supported");
  parts[0] = "";
  EXPECT_WIRE_ERROR(parts, "version part is 0 bytes");
  parts[0] = "\x01\x01";
  EXPECT_WIRE_ERROR(parts, "version part is 2 bytes");
}

TEST(WireHostile, UnknownCommand) {
  Parts parts = Encode(Heartbeat{});
  for (int code : {0, 11, 255}) {
    parts[1] = std::string(1, static_cast<char>(code));
    EXPECT_WIRE_ERROR(parts, "unknown command " + std::to_string(code));
  }
  parts[1] = "";
  EXPECT_WIRE_ERROR(parts, "command part is 0 bytes");
}

// ---------------------------------------------------------------------------------
// Hostile input: headers

TEST(WireHostile, HeaderNotMsgpack) {
  Parts parts = Encode(SampleTask());
  const std::string valid = parts[2];
  parts[2] = "";
  EXPECT_WIRE_ERROR(parts, "TASK: header is not msgpack");
  parts[2] = "\xc1";  // the one byte msgpack never uses
  EXPECT_WIRE_ERROR(parts, "header is not msgpack");
  parts[2] = valid.substr(0, valid.size() - 1);
  EXPECT_WIRE_ERROR(parts, "header is not msgpack");
  parts[2] = valid + std::string(1, '\0');  // trailing byte
  EXPECT_WIRE_ERROR(parts, "header is not msgpack");
}

TEST(WireHostile, HeaderNotAMap) {
  Parts parts = Encode(Heartbeat{});
  parts[2] = Msgpack(json::array({1, 2}));
  EXPECT_WIRE_ERROR(parts, "HEARTBEAT: header is an array; expected a map");
  parts[2] = Msgpack(7);
  EXPECT_WIRE_ERROR(parts, "header is an integer; expected a map");
  parts[2] = Msgpack("text");
  EXPECT_WIRE_ERROR(parts, "header is a string; expected a map");
}

TEST(WireHostile, HeaderTooLarge) {
  Parts parts = WithField(Heartbeat{}, "padding", std::string(kMaxHeaderBytes, 'p'));
  EXPECT_WIRE_ERROR(parts, "bytes; expected at most " + std::to_string(kMaxHeaderBytes));
}

TEST(WireHostile, HeaderNestedTooDeep) {
  // A map holding an array holding an array ...: one byte per level, so a small header
  // could otherwise recurse thousands of levels deep in the msgpack decoder.
  Parts parts = Encode(Heartbeat{});
  parts[2] = "\x81\xa1x" + std::string(10000, '\x91') + "\xc0";
  EXPECT_WIRE_ERROR(parts, "nests deeper than");
  parts[2] = std::string(10000, '\x81');
  EXPECT_WIRE_ERROR(parts, "header");
}

// Every field of every command is required: removing any one names it.
TEST(WireHostile, MissingFields) {
  for (const Message& message : SampleMessages()) {
    const json header = HeaderOf(Encode(message));
    for (const auto& [key, value] : header.items()) {
      if (key == "trace_cpu_seconds") continue;  // optional: ResultWithoutCpuSecondsDecodes
      const Parts parts = WithHeader(Encode(message), [&](json& edited) { edited.erase(key); });
      EXPECT_WIRE_ERROR(parts, CommandName(CommandOf(message)) + ": header field '" + key + "' is missing");
    }
  }
}

TEST(WireHostile, MistypedFields) {
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "task_id", "42"),
                    "TASK: header field 'task_id' is a string; expected an integer");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "frame", 1.5), "'frame' is a float; expected an integer");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "width", true), "'width' is a boolean; expected an integer");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "height", nullptr), "'height' is nil; expected an integer");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "scene_hash", 5), "'scene_hash' is an integer; expected a string");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "window", json::array({1})), "'window' is an array; expected an integer");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "has_horizons", 1),
                    "'has_horizons' is an integer; expected a boolean");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "trace_seconds", "fast"),
                    "'trace_seconds' is a string; expected a number");
  EXPECT_WIRE_ERROR(WithField(Ready{1, 1, "w"}, "name", json::object()), "'name' is a map; expected a string");
  EXPECT_WIRE_ERROR(WithField(SampleError(), "message", json::binary({1, 2})),
                    "'message' is binary data; expected a string");
}

TEST(WireHostile, IntegersOutOfRange) {
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "frame", int64_t{1} << 31),
                    "'frame' is 2147483648; expected -2147483648..2147483647");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "frame", -(int64_t{1} << 31) - 1), "'frame' is -2147483649");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "task_id", -1), "'task_id' is -1; expected 0..");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "width", 0), "'width' is 0; expected 1..16384");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "width", 16385), "'width' is 16385; expected 1..16384");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "height", uint64_t{1} << 32), "'height' is 4294967296");
  EXPECT_WIRE_ERROR(WithField(SampleTask(), "window", -1), "'window' is -1; expected >= 0");
  EXPECT_WIRE_ERROR(WithField(Ready{1, 1, "w"}, "capacity", 0),
                    "READY: header field 'capacity' is 0; expected 1..4096");
  EXPECT_WIRE_ERROR(WithField(Ready{1, 1, "w"}, "capacity", 4097), "'capacity' is 4097");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "pixel_count", 0), "'pixel_count' is 0; expected 1..268435456");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "pixel_count", (1 << 28) + 1), "'pixel_count' is 268435457");
}

TEST(WireHostile, TraceSecondsMustBeFiniteAndNonNegative) {
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "trace_cpu_seconds", -1.0), "'trace_cpu_seconds' is -1");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "trace_cpu_seconds", "slow"),
                    "'trace_cpu_seconds' is a string; expected a number");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "trace_seconds", -0.5), "'trace_seconds' is -0.5");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "trace_seconds", std::numeric_limits<double>::quiet_NaN()),
                    "expected a finite number >= 0");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "trace_seconds", std::numeric_limits<double>::infinity()),
                    "expected a finite number >= 0");
}

TEST(WireHostile, SceneHashes) {
  const std::string expected = "expected 64 lowercase hex characters";
  for (const std::string& bad : {std::string(""), kHash.substr(1), kHash + "a", std::string(64, 'A'),
                                 std::string(63, '0') + "g", std::string(63, '0') + "\n"}) {
    EXPECT_WIRE_ERROR(WithField(SampleTask(), "scene_hash", bad), "TASK: header field 'scene_hash' is \"");
    EXPECT_WIRE_ERROR(WithField(SceneGet{kHash}, "scene_hash", bad), expected);
    EXPECT_WIRE_ERROR(WithField(SceneData{kHash, kSceneJson}, "scene_hash", bad), expected);
    if (!bad.empty()) EXPECT_WIRE_ERROR(WithField(SampleError(), "scene_hash", bad), expected);
  }
}

TEST(WireHostile, QuotedValuesAreEscaped) {
  // Untrusted text in an error message must not break a log line.
  try {
    Decode(WithField(SceneGet{kHash}, "scene_hash", std::string(63, '0') + "\n"));
    FAIL() << "decoded";
  } catch (const WireError& error) {
    EXPECT_EQ(std::string(error.what()).find('\n'), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("\\x0a"), std::string::npos);
  }
}

TEST(WireHostile, StringsOverLimits) {
  EXPECT_WIRE_ERROR(WithField(Ready{1, 1, "w"}, "name", std::string(kMaxNameBytes + 1, 'n')),
                    "'name' is 257 bytes; expected at most 256");
  EXPECT_WIRE_ERROR(WithField(SampleError(), "message", std::string(kMaxErrorMessageBytes + 1, 'm')),
                    "'message' is 4097 bytes; expected at most 4096");
  EXPECT_WIRE_ERROR(WithField(Ready{1, 1, "w"}, "name", "evil\nFAKE LOG LINE"), "holds control characters");
}

// ---------------------------------------------------------------------------------
// Hostile input: payloads

TEST(WireHostile, PayloadWhereNoneBelongs) {
  for (const Message& message : {Message{Ready{1, 1, "w"}}, Message{SceneGet{kHash}}, Message{Heartbeat{}},
                                 Message{SampleError()}, Message{Disconnect{}}, Message{AssetGet{kHash}}}) {
    EXPECT_WIRE_ERROR(WithPayload(message, "x"),
                      CommandName(CommandOf(message)) + ": payload is 1 bytes; expected none");
  }
}

// A piece must lie inside its asset, be a bounded size, and an asset a bounded size.
TEST(WireHostile, AssetPieceOutOfBounds) {
  AssetPiece past = SamplePiece();
  past.offset = 35;  // 35 + 6 > 40
  EXPECT_WIRE_ERROR(Encode(past), "ASSET: bytes 35..41 lie past total_size 40");
  AssetPiece wrapping = SamplePiece();
  wrapping.offset = std::numeric_limits<uint64_t>::max() - 2;
  wrapping.totalSize = 40;
  EXPECT_WIRE_ERROR(Encode(wrapping), "lie past total_size");
  AssetPiece huge = SamplePiece();
  huge.totalSize = kMaxAssetBytes + 1;
  EXPECT_WIRE_ERROR(Encode(huge), "more than the");
  AssetPiece empty = SamplePiece();
  empty.bytes.clear();
  EXPECT_WIRE_ERROR(Encode(empty), "payload is empty");
  AssetPiece big{kHash, 0, kMaxAssetPieceBytes + 1, std::string(kMaxAssetPieceBytes + 1, 'x')};
  EXPECT_WIRE_ERROR(Encode(big), "expected at most");
  EXPECT_WIRE_ERROR(WithField(AssetGet{kHash}, "asset_hash", "../../etc/passwd"), "expected 64 lowercase hex");
}

TEST(WireHostile, TaskWithEmptyPixelSet) {
  Task task = SampleTask();
  task.pixels = PixelSet();
  EXPECT_WIRE_ERROR(Encode(task), "TASK: payload holds no pixel spans");
}

TEST(WireHostile, TaskPayloadNotWholeSpans) {
  EXPECT_WIRE_ERROR(WithPayload(SampleTask(), std::string(7, '\0')), "payload is 7 bytes; expected a whole number");
  EXPECT_WIRE_ERROR(WithPayload(SampleTask(), std::string(12, '\0')), "payload is 12 bytes");
}

TEST(WireHostile, TaskSpansInvalid) {
  // The frame is 64 x 32 = 2048 pixels.
  EXPECT_WIRE_ERROR(TaskWithSpans({0, 2049}), "TASK: pixel set span 0 [0, 2049) is out of range");
  EXPECT_WIRE_ERROR(TaskWithSpans({5, 5}), "span 0 [5, 5) is empty or reversed");
  EXPECT_WIRE_ERROR(TaskWithSpans({9, 3}), "span 0 [9, 3) is empty or reversed");
  EXPECT_WIRE_ERROR(TaskWithSpans({10, 20, 15, 30}), "span 1 [15, 30) overlaps or precedes");
  EXPECT_WIRE_ERROR(TaskWithSpans({100, 200, 0, 10}), "span 1 [0, 10) overlaps or precedes");
  EXPECT_WIRE_ERROR(TaskWithSpans({0, 0xffffffffu}), "out of range");
}

TEST(WireHostile, TaskWithMoreSpansThanPixels) {
  Parts parts = WithHeader(TaskWithSpans({0, 1, 2, 3}), [](json& header) { header["width"] = header["height"] = 1; });
  EXPECT_WIRE_ERROR(parts, "2 spans cannot fit a frame of 1 pixels");
}

TEST(WireHostile, ResultPayloadSizeMismatch) {
  const Parts valid = Encode(SampleResult(true));  // 2 pixels with horizons: 32 bytes
  Parts parts = valid;
  parts[3].pop_back();
  EXPECT_WIRE_ERROR(parts, "RESULT: payload is 31 bytes; expected 32 (2 pixels x (12 bytes rgb + 4 bytes horizon))");
  parts[3] = valid[3] + "1234";
  EXPECT_WIRE_ERROR(parts, "payload is 36 bytes; expected 32");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "has_horizons", false),
                    "payload is 32 bytes; expected 24 (2 pixels x 12 bytes rgb)");
  EXPECT_WIRE_ERROR(WithField(SampleResult(false), "has_horizons", true), "payload is 24 bytes; expected 32");
  EXPECT_WIRE_ERROR(WithField(SampleResult(true), "pixel_count", 3), "expected 48");
  EXPECT_WIRE_ERROR(WithPayload(SampleResult(true), ""), "payload is 0 bytes");
}

TEST(WireHostile, ResultRgbNonFinite) {
  EXPECT_WIRE_ERROR(ResultWithRgb(std::numeric_limits<float>::quiet_NaN(), 4),
                    "RESULT: rgb value 4 (pixel 1, channel g) is NaN");
  EXPECT_WIRE_ERROR(ResultWithRgb(std::numeric_limits<float>::signaling_NaN(), 0),
                    "rgb value 0 (pixel 0, channel r) is NaN");
  EXPECT_WIRE_ERROR(ResultWithRgb(std::numeric_limits<float>::infinity(), 5),
                    "rgb value 5 (pixel 1, channel b) is infinite");
  EXPECT_WIRE_ERROR(ResultWithRgb(-std::numeric_limits<float>::infinity(), 2), "is infinite");
  // A NaN with a payload and sign bit set is still a NaN.
  Parts parts = Encode(SampleResult(false));
  std::memcpy(parts[3].data() + 4, "\x01\x00\xc0\xff", 4);
  EXPECT_WIRE_ERROR(parts, "rgb value 1 (pixel 0, channel g) is NaN");
}

TEST(WireRoundTrip, SceneWhoseBytesMismatchTheHashStillDecodes) {
  // The worker checks the hash itself, so that it can answer ERROR for the tasks that
  // wait on the scene; dropping the message here would leave them waiting.
  const SceneData scene{kHash, kSceneJson + " "};
  ExpectRoundTrip(scene);
  ExpectRoundTrip(SceneData{kHash, ""});
}

TEST(WireHostile, HorizonNotAfterTracedFrame) {
  Result result = SampleResult(true);  // frame 12
  result.horizons[1] = 12;
  EXPECT_WIRE_ERROR(Encode(result),
                    "RESULT: horizon of pixel 1 is frame 12; expected a frame after the traced frame 12");
  result.horizons[1] = std::numeric_limits<int32_t>::min();
  EXPECT_WIRE_ERROR(Encode(result), "horizon of pixel 1 is frame -2147483648");
  result.frame = std::numeric_limits<int32_t>::max();  // no frame comes after it
  result.horizons = {result.frame, result.frame};
  EXPECT_WIRE_ERROR(Encode(result), "horizon of pixel 0");
}

TEST(WireHostile, SceneOverSizeLimit) {
  Parts parts = Encode(SceneData{kHash, kSceneJson});
  parts[3].assign(kMaxSceneJsonBytes + 1, ' ');
  EXPECT_WIRE_ERROR(parts, "scene JSON is 268435457 bytes; expected at most 268435456");
}

// ---------------------------------------------------------------------------------
// Fuzzing: whatever arrives, Decode either returns a message or throws WireError.

class Mutator {
 public:
  explicit Mutator(uint32_t seed) : random_(seed) {}

  Parts Mutate(Parts parts) {
    const int mutations = 1 + Below(3);
    for (int i = 0; i < mutations; ++i) MutateOnce(parts);
    return parts;
  }

 private:
  size_t Below(size_t bound) { return std::uniform_int_distribution<size_t>(0, bound - 1)(random_); }
  char RandomByte() { return static_cast<char>(Below(256)); }

  std::string RandomBytes(size_t length) {
    std::string bytes(length, '\0');
    for (char& byte : bytes) byte = RandomByte();
    return bytes;
  }

  // Mostly the header and payload: framing bytes only have a few values to try.
  size_t PickPart(const Parts& parts) {
    if (parts.size() == kPartCount && Below(10) < 8) return 2 + Below(2);
    return Below(parts.size());
  }

  // Weighted towards edits inside a part: a wrong part count is caught at once and
  // teaches the decoder nothing.
  void MutateOnce(Parts& parts) {
    if (parts.empty()) {
      parts.push_back(RandomBytes(Below(8)));
      return;
    }
    const size_t choice = Below(16);
    if (choice == 0) {
      parts.erase(parts.begin() + static_cast<std::ptrdiff_t>(Below(parts.size())));
      return;
    }
    if (choice == 1) {
      parts.push_back(RandomBytes(Below(8)));
      return;
    }
    if (choice < 5 && parts.size() == kPartCount && ReplaceHeaderField(parts[2])) return;
    std::string& part = parts[PickPart(parts)];
    if (choice < 8) {
      FlipBytes(part);
    } else if (choice < 10) {
      part.resize(part.empty() ? 0 : Below(part.size()));  // truncate
    } else if (choice < 12) {
      SetInteresting(part);
    } else if (choice < 15) {
      part.insert(part.empty() ? 0 : Below(part.size() + 1), RandomBytes(1 + Below(16)));
    } else {
      part = RandomBytes(Below(64));
    }
  }

  // Keeps the header valid msgpack but gives one field a value of another type or at
  // a boundary, so the typed field checks see as much traffic as the byte parser.
  bool ReplaceHeaderField(std::string& headerBytes) {
    json header = json::from_msgpack(headerBytes, true, false);
    if (!header.is_object() || header.empty()) return false;
    static const std::vector<json> kValues = {
        -1, 0, 1, 16384, 16385, int64_t{1} << 31, -(int64_t{1} << 31) - 1, std::numeric_limits<uint64_t>::max(),
        std::numeric_limits<int64_t>::min(), 0.5, -0.0, std::numeric_limits<double>::quiet_NaN(), true, nullptr,
        "", "x", std::string(64, 'a'), json::array(), json::object()};
    auto field = header.begin();
    std::advance(field, static_cast<std::ptrdiff_t>(Below(header.size())));
    *field = kValues[Below(kValues.size())];
    const std::vector<uint8_t> bytes = json::to_msgpack(header);
    headerBytes.assign(bytes.begin(), bytes.end());
    return true;
  }

  void FlipBytes(std::string& part) {
    if (part.empty()) return;
    const size_t flips = 1 + Below(4);
    for (size_t i = 0; i < flips; ++i) part[Below(part.size())] = RandomByte();
  }

  // Values that sit on boundaries: msgpack type markers, NaN bytes, 0xff runs.
  void SetInteresting(std::string& part) {
    static const std::vector<std::string> kInteresting = {
        std::string("\x00", 1), "\x7f", "\x80", "\xff", "\xc0", "\xc1", "\xc2", "\xc3", "\xcb", "\xcf",
        "\xd3", "\xdc", "\xdd", "\xde", "\xdf", "\x00\x00\xc0\x7f", "\xff\xff\xff\xff"};
    if (part.empty()) return;
    const std::string& value = kInteresting[Below(kInteresting.size())];
    const size_t at = Below(part.size());
    part.replace(at, std::min(value.size(), part.size() - at), value);
  }

  std::mt19937 random_;
};

TEST(WireFuzz, MutatedMessagesDecodeOrThrowWireError) {
  Mutator mutator(20240611);
  const std::vector<Message> seeds = SampleMessages();
  int decoded = 0, rejected = 0;
  for (int i = 0; i < 20000; ++i) {
    const Parts parts = mutator.Mutate(Encode(seeds[static_cast<size_t>(i) % seeds.size()]));
    try {
      Decode(parts);
      ++decoded;
    } catch (const WireError&) {
      ++rejected;
    } catch (const std::exception& error) {
      FAIL() << "iteration " << i << " threw a non-WireError: " << error.what();
    }
  }
  // Both outcomes must occur, or the mutations are not exercising the decoder.
  EXPECT_GT(decoded, 0);
  EXPECT_GT(rejected, decoded);
}

TEST(WireFuzz, RandomPartsThrowWireError) {
  std::mt19937 random(7);
  for (int i = 0; i < 5000; ++i) {
    Parts parts(random() % 6);
    for (std::string& part : parts) {
      part.resize(random() % 40);
      for (char& byte : part) byte = static_cast<char>(random());
    }
    if (i % 2 == 0 && parts.size() == kPartCount) {  // let half reach the header decoder
      parts[0] = std::string(1, static_cast<char>(kWireVersion));
      parts[1] = std::string(1, static_cast<char>(1 + random() % 10));
    }
    try {
      Decode(parts);
    } catch (const WireError&) {
    } catch (const std::exception& error) {
      FAIL() << "iteration " << i << " threw a non-WireError: " << error.what();
    }
  }
}

}  // namespace
}  // namespace tcfarm::wire
