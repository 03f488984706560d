// libFuzzer harness: the glTF importer over the input as one file, .gltf JSON or GLB (the
// importer tells them apart by GLB's magic), with no base directory, as files uploaded to
// the farm are imported. Bad input must be a SceneError; the scene an import gives must
// pass ParseScene again, as the coordinator stores it serialized.
#include <cstddef>
#include <cstdint>
#include <string>

#include "proto/scene/import/scene_import.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    const tcfarm::Scene scene = tcfarm::ImportSceneBytes(bytes, "gltf");
    (void)tcfarm::ParseScene(tcfarm::SerializeScene(scene));
  } catch (const tcfarm::SceneError&) {
  }
  return 0;
}
