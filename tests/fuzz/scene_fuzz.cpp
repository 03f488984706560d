// libFuzzer harness: ParseScene over the input as scene JSON, with no base directory (as
// scenes arriving over the network are parsed). Bad input must be a SceneError; anything
// else escaping is a crash. A scene that parses must serialize and parse again to itself,
// since the farm stores and hashes the serialized form.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "proto/scene/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const tcfarm::Scene scene = tcfarm::ParseScene(text);
    const std::string serialized = tcfarm::SerializeScene(scene);
    if (tcfarm::SerializeScene(tcfarm::ParseScene(serialized)) != serialized) std::abort();
  } catch (const tcfarm::SceneError&) {
  }
  return 0;
}
