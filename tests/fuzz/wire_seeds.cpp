// Writes one seed per wire command (and a few variants) into the folder given, each in the
// harness's input layout (fuzz_input.h), so the wire fuzzer starts from messages that
// decode and mutates their fields rather than rediscovering the framing and msgpack.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "fuzz_input.h"
#include "proto/wire/wire.h"

namespace {

using namespace tcfarm::wire;

const std::string kHash(64, 'a');

std::vector<std::pair<std::string, Message>> SeedMessages() {
  Task task{7, 3, kHash, 12, 64, 48, tcfarm::PixelSet::FromSpans({{1, 3}, {258, 2048}}, 64 * 48), 8};
  Task wholeFrame{8, 3, kHash, 0, 4, 4, tcfarm::PixelSet::Full(16), 0};
  Result result{7, 3, 12, {1.0f, -2.0f, 0.5f, 0.0f, 0.25f, 3.0f}, {13, 256}, 0.5, 0.25, 2, 1, 0, 0};
  Result noHorizons{8, 3, 0, {0.5f, 0.5f, 0.5f}, {}, 0.01, std::nullopt, 1, 0, 1, 1};
  return {
      {"ready", Ready{4, 2, "host:123"}},
      {"task", task},
      {"task_whole_frame", wholeFrame},
      {"result", result},
      {"result_no_horizons", noHorizons},
      {"scene_get", SceneGet{kHash}},
      {"scene", SceneData{kHash, R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]}})"}},
      {"heartbeat", Heartbeat{}},
      {"error", Error{7, kHash, "scene failed to build", ""}},
      {"error_asset", Error{0, "", "no such asset", kHash}},
      {"disconnect", Disconnect{}},
      {"asset_get", AssetGet{kHash}},
      {"asset", AssetPiece{kHash, 0, 10, "0123456789"}},
      {"asset_middle", AssetPiece{kHash, 4, 10, "4567"}},
  };
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: wire_seeds OUT_DIR\n");
    return 2;
  }
  for (const auto& [name, message] : SeedMessages()) {
    const std::string path = std::string(argv[1]) + "/" + name;
    std::ofstream(path, std::ios::binary) << tcfarm::fuzz::JoinParts(Encode(message));
  }
  return 0;
}
