// Scene JSON -> Scene (scene_write.cpp writes it); mesh "file" references go to the OBJ reader
// (scene/import/obj_reader.h).
//
// The parser is strict on purpose: a scene comes from a user over the network and is then
// trusted by every worker, so each value is checked where it is read, and each error names
// the JSON pointer of the value and what would have been accepted there.
//
// The reading is in scene/parse/: json_values (values with their pointers),
// animated_values (animation and motion), and SceneReader by part of the scene.
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>

#include "proto/json/strict_json.h"
#include "proto/scene/import/import_budget.h"
#include "proto/scene/parse/json_values.h"
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/scene.h"

namespace tcfarm {

Scene ParseScene(const std::string& jsonText, const std::optional<std::filesystem::path>& baseDirectory,
                 const Checkpoint& checkpoint) {
  // The document, and the scene read from it (its numbers as doubles, smaller than the
  // document's values), alive together.
  if (ChargingImportMemory()) ChargeImportMemory(2 * JsonDomBytes(jsonText));
  const nlohmann::json document = scene_parse::ParseJson(jsonText);
  return scene_parse::SceneReader(baseDirectory, checkpoint).Read(document);
}

Scene LoadSceneFile(const std::filesystem::path& path) {
  std::error_code error;
  std::ifstream in(path, std::ios::binary);
  if (!std::filesystem::is_regular_file(path, error) || !in) {
    scene_parse::Fail("", "cannot read scene file " + path.string(), "a readable scene file");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return ParseScene(text.str(), std::filesystem::absolute(path).parent_path());
}

}  // namespace tcfarm
