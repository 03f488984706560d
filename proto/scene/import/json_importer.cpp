// tcfarm's own scene JSON (proto/scene.schema.json): the parser is the importer.
#include <string>
#include <vector>

#include "proto/json/strict_json.h"
#include "proto/scene/import/file_sniff.h"
#include "proto/scene/import/import_budget.h"
#include "proto/scene/import/messages.h"
#include "proto/scene/import/importers.h"

namespace tcfarm {
namespace {

class JsonImporter : public SceneImporter {
 public:
  std::string Type() const override { return "tcfarm-json"; }
  std::vector<std::string> Extensions() const override { return {".json"}; }

  // An object at the top, after an optional UTF-8 byte order mark. A glTF file is JSON too:
  // its importer is tried first and claims the objects that hold "asset".
  bool Sniff(std::string_view head) const override {
    if (head.substr(0, 3) == "\xEF\xBB\xBF") head.remove_prefix(3);
    size_t first = head.find_first_not_of(" \t\r\n");
    return first != std::string_view::npos && head[first] == '{';
  }

  // Its syntax: mesh files and textures are what it names.
  void CheckAlone(const ImportInput& input) const override {
    RequireJsonSceneStart(input.bytes, input.displayName);
    if (ChargingImportMemory()) ChargeImportMemory(JsonDomBytes(input.bytes));
    try {
      ParseStrictJson(input.bytes);
    } catch (const JsonInputError& error) {
      FailInput(error.pointer(), input.displayName + ": " + error.what(), "a tcfarm JSON scene (proto/scene.md)");
    }
  }

  Scene Import(const ImportInput& input) const override {
    RequireJsonSceneStart(input.bytes, input.displayName);
    return ParseScene(input.bytes, input.baseDirectory);
  }
};

}  // namespace

std::unique_ptr<SceneImporter> MakeJsonImporter() { return std::make_unique<JsonImporter>(); }

}  // namespace tcfarm
