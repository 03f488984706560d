#include "proto/scene/import/scene_import.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <fstream>
#include <memory>
#include <system_error>

#include "proto/scene/import/import_budget.h"
#include "proto/scene/import/importers.h"
#include "proto/scene/import/messages.h"
#include "proto/scene/scene_limits.h"

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

// The caller's render size and samples win over the file's, within the scene format's
// limits (proto/scene.md, "Render").
Scene ApplyOptions(Scene scene, const ImportOptions& options) {
  using scene_limits::kMaxImageSide;
  using scene_limits::kMaxSamplesPerPixel;
  if (options.width != 0 || options.height != 0) {
    if (options.width < 1 || options.width > kMaxImageSide || options.height < 1 || options.height > kMaxImageSide) {
      FailInput("/render", "a render size of " + std::to_string(options.width) + " x " + std::to_string(options.height),
                "a width and a height from 1 to " + std::to_string(kMaxImageSide));
    }
    scene.render.width = options.width;
    scene.render.height = options.height;
  }
  if (options.samplesPerPixel != 0) {
    if (options.samplesPerPixel < 1 || options.samplesPerPixel > kMaxSamplesPerPixel) {
      FailInput("/render/samples_per_pixel", std::to_string(options.samplesPerPixel) + " samples per pixel",
                "1 to " + std::to_string(kMaxSamplesPerPixel));
    }
    scene.render.samplesPerPixel = options.samplesPerPixel;
  }
  return scene;
}

}  // namespace

std::optional<LightUnits> LightUnitsNamed(const std::string& name) {
  if (name == "photometric") return LightUnits::kPhotometric;
  if (name == "radiometric") return LightUnits::kRadiometric;
  return std::nullopt;
}

const char* NameOf(LightUnits units) { return units == LightUnits::kPhotometric ? "photometric" : "radiometric"; }

// The registry is this one list, not self-registration: static initialisers in a static
// library are dropped by the linker unless something references their object file.
const std::vector<const SceneImporter*>& SceneImporters() {
  static const std::vector<std::unique_ptr<SceneImporter>> owned = [] {
    std::vector<std::unique_ptr<SceneImporter>> importers;
    // glTF first: a .gltf is JSON too, and its Sniff claims only objects holding "asset".
    importers.push_back(MakeGltfImporter());
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

namespace {

// FindImporterForFile's, or refused saying the formats it knows.
const SceneImporter& RequireImporterForFile(const std::filesystem::path& path, std::string_view head) {
  const SceneImporter* importer = FindImporterForFile(path, head);
  if (importer == nullptr) {
    FailInput("", "cannot tell the format of scene file " + QuoteInput(path.string()) +
                      " from its name or its first bytes",
              "a file named " + KnownExtensions() + ", or holding one of those formats");
  }
  return *importer;
}

}  // namespace

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

Scene ImportScene(const std::filesystem::path& path, const ImportOptions& options) {
  // The message LoadSceneFile has always given: the whole path, unquoted.
  std::ifstream in(path, std::ios::binary);
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error) || !in) {
    FailInput("", "cannot read scene file " + path.string(), "a readable scene file");
  }
  // Read once into a string of the file's size: a stream's buffer and a copy of it would
  // hold a large scene file twice.
  const std::uintmax_t size = std::filesystem::file_size(path, error);
  if (error) FailInput("", "read error in scene file " + path.string(), "a readable scene file");
  ChargeImportMemory(size);
  std::string bytes(static_cast<size_t>(size), '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (in.gcount() != static_cast<std::streamsize>(bytes.size())) {
    FailInput("", "read error in scene file " + path.string(), "a readable scene file");
  }
  const SceneImporter* importer = &RequireImporterForFile(path, bytes);
  return ApplyOptions(importer->Import(ImportInput{std::move(bytes), path.filename().string(),
                                                   std::filesystem::absolute(path).parent_path(), options}),
                      options);
}

void CheckSceneFileAlone(const std::string& bytes, const std::string& fileName) {
  ChargeImportMemory(bytes.size());  // the importer's copy
  RequireImporterForFile(fileName, bytes).CheckAlone(ImportInput{bytes, fileName, std::nullopt, {}});
}

Scene ImportSceneBytes(const std::string& bytes, const std::string& type,
                       const std::optional<std::filesystem::path>& baseDirectory, const ImportOptions& options) {
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
  ChargeImportMemory(bytes.size());  // the importer's copy
  return ApplyOptions(importer->Import(ImportInput{bytes, "the " + importer->Type() + " scene", baseDirectory, options}),
                      options);
}

}  // namespace tcfarm
