// A glTF 2.0 file (.gltf with external or data-URI buffers, or .glb) as a scene: its node
// hierarchy as shared parent motions, one mesh shape per (node, primitive), PBR materials
// mapped onto the Whitted model, its cameras and KHR_lights_punctual lights, and one
// animation's channels as keyframes. proto/scene.md documents the mapping.
//
// The file is read by tinygltf (Debian's libtinygltf: maintained, a header plus a library,
// it reads .gltf with external and data-URI buffers and .glb). It parses; everything the
// scene model relies on (ranges, finiteness, key order, the graph being a forest) is
// checked here, so that bad input is refused with the glTF pointer of the bad value.
//
// The reading is in gltf/, by role (gltf/gltf_reader.h).
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "proto/scene/import/gltf/gltf_reader.h"
#include "proto/scene/import/importers.h"

namespace tcfarm {
namespace {

class GltfImporter : public SceneImporter {
 public:
  std::string Type() const override { return "gltf"; }
  std::vector<std::string> Extensions() const override { return {".gltf", ".glb"}; }

  // GLB's magic, or a JSON object naming "asset" (required in glTF, unknown to tcfarm JSON).
  // The key must be the top object's own: tcfarm JSON may use "asset" as a material's name.
  bool Sniff(std::string_view head) const override {
    if (head.substr(0, 4) == "glTF") return true;
    if (head.substr(0, 3) == "\xEF\xBB\xBF") head.remove_prefix(3);
    size_t first = head.find_first_not_of(" \t\r\n");
    if (first == std::string_view::npos || head[first] != '{') return false;
    int depth = 0;
    for (size_t i = first; i < head.size(); ++i) {
      char c = head[i];
      if (c == '{' || c == '[') {
        ++depth;
      } else if (c == '}' || c == ']') {
        if (--depth == 0) return false;
      } else if (c == '"') {
        size_t end = i + 1;
        while (end < head.size() && head[end] != '"') end += head[end] == '\\' ? 2 : 1;
        if (end >= head.size()) return false;
        std::string_view text = head.substr(i + 1, end - i - 1);
        size_t next = head.find_first_not_of(" \t\r\n", end + 1);
        if (depth == 1 && text == "asset" && next != std::string_view::npos && head[next] == ':') return true;
        i = end;
      }
    }
    return false;
  }

  void CheckAlone(const ImportInput& input) const override { gltf::GltfReader(input).CheckAlone(); }

  Scene Import(const ImportInput& input) const override {
    Scene scene = gltf::GltfReader(input).Read();
    // Workers receive the scene as tcfarm JSON: what the parser would refuse (a camera's up
    // along its view at some frame, an animated scale through zero) is refused now.
    // The scene itself is returned, not the one read back, so that nodes keep sharing
    // their parents' motions.
    try {
      ParseScene(SerializeScene(scene));
    } catch (const SceneError& error) {
      FailInput("", input.displayName + ": the imported scene breaks a rule of the scene format: " + error.what(),
                "a glTF file whose scene the format can hold");
    }
    return scene;
  }
};

}  // namespace

std::unique_ptr<SceneImporter> MakeGltfImporter() { return std::make_unique<GltfImporter>(); }

// For tests: a strip or fan as triangles.
std::vector<std::array<uint32_t, 3>> GltfTriangles(const std::vector<uint32_t>& indices, int mode) {
  return gltf::GltfReader::Triangles(indices, mode);
}

}  // namespace tcfarm
