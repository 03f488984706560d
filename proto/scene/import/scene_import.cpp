#include "scene/import/scene_import.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <memory>
#include <sstream>
#include <system_error>

#include "scene/import/importers.h"
#include "scene/import/messages.h"

namespace tcfarm {
namespace {

// Enough to see past a licence comment at the top of an OBJ file.
constexpr size_t kSniffBytes = 4096;

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

std::string KnownTypes() {
  std::string types;
  for (const SceneImporter* importer : SceneImporters()) {
    types += (types.empty() ? "" : ", ") + QuoteInput(importer->Type());
  }
  return types;
}

std::string KnownExtensions() {
  std::string extensions;
  for (const SceneImporter* importer : SceneImporters()) {
    for (const auto& extension : importer->Extensions()) extensions += (extensions.empty() ? "" : ", ") + extension;
  }
  return extensions;
}

}  // namespace

// The registry is this one list, not self-registration: static initialisers in a static
// library are dropped by the linker unless something references their object file.
const std::vector<const SceneImporter*>& SceneImporters() {
  static const std::vector<std::unique_ptr<SceneImporter>> owned = [] {
    std::vector<std::unique_ptr<SceneImporter>> importers;
    importers.push_back(MakeJsonImporter());
    importers.push_back(MakeObjImporter());
    return importers;
  }();
  static const std::vector<const SceneImporter*> importers = [] {
    std::vector<const SceneImporter*> pointers;
    for (const auto& importer : owned) pointers.push_back(importer.get());
    return pointers;
  }();
  return importers;
}

const SceneImporter* FindImporterByType(const std::string& type) {
  for (const SceneImporter* importer : SceneImporters()) {
    if (importer->Type() == type) return importer;
  }
  return nullptr;
}

const SceneImporter* FindImporterForFile(const std::filesystem::path& path, std::string_view head) {
  const std::string extension = Lower(path.extension().string());
  for (const SceneImporter* importer : SceneImporters()) {
    const auto extensions = importer->Extensions();
    if (std::find(extensions.begin(), extensions.end(), extension) != extensions.end()) return importer;
  }
  head = head.substr(0, kSniffBytes);
  for (const SceneImporter* importer : SceneImporters()) {
    if (importer->Sniff(head)) return importer;
  }
  return nullptr;
}

Scene ImportScene(const std::filesystem::path& path) {
  // The message LoadSceneFile has always given: the whole path, unquoted.
  std::ifstream in(path, std::ios::binary);
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error) || !in) {
    FailInput("", "cannot read scene file " + path.string(), "a readable scene file");
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) FailInput("", "read error in scene file " + path.string(), "a readable scene file");
  std::string bytes = text.str();
  const SceneImporter* importer = FindImporterForFile(path, bytes);
  if (importer == nullptr) {
    FailInput("", "cannot tell the format of scene file " + QuoteInput(path.string()) +
                      " from its name or its first bytes",
              "a file named " + KnownExtensions() + ", or holding one of those formats");
  }
  return importer->Import(
      ImportInput{std::move(bytes), path.filename().string(), std::filesystem::absolute(path).parent_path()});
}

Scene ImportSceneBytes(const std::string& bytes, const std::string& type,
                       const std::optional<std::filesystem::path>& baseDirectory) {
  const SceneImporter* importer = nullptr;
  if (type.empty()) {
    std::string_view head(bytes);
    head = head.substr(0, kSniffBytes);
    for (const SceneImporter* candidate : SceneImporters()) {
      if (candidate->Sniff(head)) {
        importer = candidate;
        break;
      }
    }
    if (importer == nullptr) {
      FailInput("", "cannot tell the format of the scene from its first bytes", "one of the types " + KnownTypes());
    }
  } else {
    importer = FindImporterByType(type);
    if (importer == nullptr) FailInput("", "unknown scene type " + QuoteInput(type), "one of " + KnownTypes());
  }
  return importer->Import(ImportInput{bytes, "the " + importer->Type() + " scene", baseDirectory});
}

}  // namespace tcfarm
