// The import seam: the one place where a file format becomes the scene model (Scene).
//
// Each format is a SceneImporter; tcfarm JSON, OBJ and glTF 2.0 are peers. A file is
// given to the importer its extension names, or else to the first whose Sniff accepts its
// first bytes. Whatever the format, the result is a Scene as ParseScene would give it:
// validated, self-contained (meshes inline), and written back by SerializeScene as tcfarm
// JSON, the form in which scenes travel to workers.
//
// Adding a format: a class implementing SceneImporter in its own file here, its factory
// declared in importers.h and listed in SceneImporters() (scene_import.cpp), the file added
// to tcfarm_scene in proto/CMakeLists.txt, and its mapping documented in proto/scene.md.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "proto/scene/scene.h"

namespace tcfarm {

// What a file may leave to the caller. The render size and samples apply to every format
// (ImportScene sets them on the scene an importer gives); the rest only to formats that
// carry animations and cameras of their own (glTF).
enum class LightUnits { kPhotometric, kRadiometric };
// Watts (per steradian or square metre) per unit of a glTF light's intensity.
inline double WattsPerLightUnit(LightUnits units) { return units == LightUnits::kPhotometric ? 1.0 / 683 : 1.0; }
// "photometric" and "radiometric", as options and scenes name them; nullopt for another.
std::optional<LightUnits> LightUnitsNamed(const std::string& name);
const char* NameOf(LightUnits units);

struct ImportOptions {
  double framesPerSecond = 24;  // frame f samples time f / framesPerSecond
  std::string animation;        // its name or index; empty: the first
  std::string camera;           // a camera's (or its node's) name, or the camera's index; empty: the first camera node
  int width = 0, height = 0;    // 0: the file's own, else 640 x 480
  int samplesPerPixel = 0;      // 0: the file's own, else 1
  // How glTF light intensities (candela, lux) become radiometric ones (proto/scene.md,
  // "glTF lights"): as the tools that write glTF convert them (683 lm/W), or as they are.
  LightUnits lightUnits = LightUnits::kPhotometric;
  // The last frame the caller will render; -1: none said. A glTF file's frames run to its
  // animation's end; asked past it, they extend to this one, holding the last key.
  int lastFrame = -1;
};

struct ImportInput {
  std::string bytes;        // the whole file
  std::string displayName;  // how messages name it (the file name, or the type for bytes)
  // Where relative references (mesh files, material libraries, buffers, textures) resolve;
  // none for data that arrives over the network, which must then be self-contained.
  std::optional<std::filesystem::path> baseDirectory;
  ImportOptions options;
};

class SceneImporter {
 public:
  virtual ~SceneImporter() = default;
  // The name callers give ImportSceneBytes: "tcfarm-json", "obj", "gltf".
  virtual std::string Type() const = 0;
  // File name extensions, lower case with their dot (".json").
  virtual std::vector<std::string> Extensions() const = 0;
  // True when `head`, the first bytes of a file, look like this format. Only consulted
  // when the extension names no importer, in SceneImporters() order.
  virtual bool Sniff(std::string_view head) const = 0;
  // Throws SceneError naming the JSON pointer (or "" and the file and line) of bad input.
  virtual Scene Import(const ImportInput& input) const = 0;
  // What the file alone shows, without the files it names (POST /api/v1/scenes/check before
  // they are uploaded). Throws SceneError as Import does. By default nothing: OBJ's lines
  // are checked only as the import reads them.
  virtual void CheckAlone(const ImportInput& input) const { (void)input; }
};

// Every importer, in the order their Sniff is tried.
const std::vector<const SceneImporter*>& SceneImporters();
// nullptr when no importer has that type.
const SceneImporter* FindImporterByType(const std::string& type);
// By extension, else by content; nullptr when neither tells.
const SceneImporter* FindImporterForFile(const std::filesystem::path& path, std::string_view head);

// Reads a scene file of any supported format; references resolve in its folder.
Scene ImportScene(const std::filesystem::path& path, const ImportOptions& options = {});
// The file named fileName (for its extension and messages) with these bytes, checked as
// far as it can be without the files it names (SceneImporter::CheckAlone). Throws
// SceneError, also when neither the name nor the bytes tell the format.
void CheckSceneFileAlone(const std::string& bytes, const std::string& fileName);
// Imports bytes of the given type (an importer's Type(); "" to sniff the content).
// Without a base directory, references to other files are rejected.
Scene ImportSceneBytes(const std::string& bytes, const std::string& type,
                       const std::optional<std::filesystem::path>& baseDirectory = std::nullopt,
                       const ImportOptions& options = {});

}  // namespace tcfarm
