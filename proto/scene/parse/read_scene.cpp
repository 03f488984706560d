// Reading a scene document: its parts in order, an imported base, the render settings.
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/shapes/shape_format.h"

#include "proto/scene/import/import_options.h"

namespace tcfarm::scene_parse {

SceneReader::SceneReader(std::optional<std::filesystem::path> baseDirectory, Checkpoint checkpoint)
    : baseDirectory_(std::move(baseDirectory)), checkpoint_(std::move(checkpoint)) {}

Scene SceneReader::Read(const json& document) {
  Node root{document, ""};
  ExpectObject(root,
               {"import", "camera", "lights", "materials", "meshes", "transforms", "shapes", "background", "render"},
               "a scene object");
  // An imported file is the base the rest of the document adds to (proto/scene.md, "Importing").
  Scene scene = root.Has("import") ? ReadImport(root) : Scene{};
  const bool imported = root.Has("import");
  sharedMeshes_ = scene.meshes;
  if (!imported || root.Has("render")) {
    scene.render = ReadRender(Required(root, "render", "render settings {\"width\", \"height\", ...}"),
                              imported ? std::optional(scene.render) : std::nullopt);
  }
  range_ = FrameRange{scene.render.firstFrame, scene.render.LastFrame()};
  if (root.Has("transforms")) named_ = NamedTransforms(root.Member("transforms"), range_);
  scene.materials = ReadMaterials(root, std::move(scene.materials));
  if (!imported || root.Has("camera")) {
    scene.camera = ReadCamera(Required(root, "camera", "a camera {\"position\", \"look_at\", ...}"));
  }
  if (root.Has("lights")) Append(scene.lights, ReadLights(root.Member("lights")));
  if (root.Has("meshes")) AddSharedMeshes(scene, root.Member("meshes"));
  if (root.Has("shapes")) Append(scene.shapes, ReadShapes(root.Member("shapes")));
  if (root.Has("background")) scene.background = ReadColour(root.Member("background"));
  // What a kind leaves until the whole scene is known to be valid (terrain generating its
  // mesh) is done now: a rejected scene should cost no geometry.
  for (Shape& shape : scene.shapes) FormatOf(shape.type).Complete(shape, checkpoint_);
  return scene;
}

Scene SceneReader::ReadImport(const Node& root) {
  const Node node = root.Member("import");
  const std::string expected =
      "{\"file\": a glTF or OBJ file in the scene's folder, \"animation\", \"camera\", \"fps\", \"light_units\"}";
  ExpectObject(node, {"file", "animation", "camera", "fps", "light_units"}, expected);
  const Node file = Required(node, "file", expected);
  const std::string name = ReadString(file, "a glTF or OBJ file inside the scene folder");
  if (!baseDirectory_) {
    Fail(file.pointer, "file " + Quote(name) + " cannot be resolved: the scene was submitted without a folder",
         "the file uploaded with the scene (tcfarm submit uploads the files a scene names)");
  }
  const std::filesystem::path path = ResolveInsideFolder(*baseDirectory_, name, file.pointer, "imported file");
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
  // By extension only: a scene that sniffed as JSON could import itself.
  if (extension != ".gltf" && extension != ".glb" && extension != ".obj") {
    Fail(file.pointer, Quote(name) + " is not a glTF or OBJ file", "a .gltf, .glb or .obj file; tcfarm scenes do not nest");
  }
  const ImportOptions options = ReadImportOptions(root, node);
  try {
    return ImportScene(path, options);
  } catch (const SceneError& error) {
    throw SceneError(file.pointer, error.what());
  }
}

ImportOptions SceneReader::ReadImportOptions(const Node& root, const Node& node) const {
  ImportOptions options;
  if (node.Has("fps")) options.framesPerSecond = ReadFramesPerSecond(node.value.at("fps"), node.MemberPointer("fps"));
  if (node.Has("animation")) options.animation = ReadNameOrIndex(node.value.at("animation"), node.MemberPointer("animation"));
  if (node.Has("camera")) options.camera = ReadNameOrIndex(node.value.at("camera"), node.MemberPointer("camera"));
  if (node.Has("light_units")) {
    options.lightUnits = ReadLightUnits(node.value.at("light_units"), node.MemberPointer("light_units"));
  }
  if (root.Has("render") && root.value["render"].is_object()) {
    const Node render = root.Member("render");
    if (render.Has("width")) options.width = ReadImageSide(render.value.at("width"), render.MemberPointer("width"));
    if (render.Has("height")) options.height = ReadImageSide(render.value.at("height"), render.MemberPointer("height"));
    if (render.Has("samples_per_pixel")) {
      options.samplesPerPixel =
          ReadSamplesPerPixel(render.value.at("samples_per_pixel"), render.MemberPointer("samples_per_pixel"));
    }
  }
  return options;
}

RenderSettings SceneReader::ReadRender(const Node& node, const std::optional<RenderSettings>& base) {
  ExpectObject(node, {"width", "height", "frames", "samples_per_pixel", "max_depth", "shadows", "ambient"},
               "render settings");
  RenderSettings render = base.value_or(RenderSettings{});
  const std::string sideExpected = "an integer in [1, " + std::to_string(kMaxImageSide) + "]";
  for (const char* side : {"width", "height"}) {
    if (base && !node.Has(side)) continue;
    const Node value = Required(node, side, sideExpected);
    (std::string(side) == "width" ? render.width : render.height) = ReadImageSide(value.value, value.pointer);
  }
  if (node.Has("frames")) {
    Node frames = node.Member("frames");
    ExpectObject(frames, {"start", "count"}, "{\"start\": first frame, \"count\": number of frames}");
    if (frames.Has("start")) render.firstFrame = ReadInt(frames.Member("start"), 0, kMaxFirstFrame);
    if (frames.Has("count")) render.frameCount = ReadInt(frames.Member("count"), 1, kMaxFrameCount);
  }
  if (node.Has("samples_per_pixel")) {
    render.samplesPerPixel = ReadSamplesPerPixel(node.value.at("samples_per_pixel"), node.MemberPointer("samples_per_pixel"));
  }
  if (node.Has("max_depth")) render.maxDepth = ReadInt(node.Member("max_depth"), 0, kMaxBounceDepth);
  if (node.Has("shadows")) {
    const Node shadows = node.Member("shadows");
    if (!shadows.value.is_boolean()) FailType(shadows, "true (shadow rays traced) or false (none)");
    render.shadows = shadows.value.get<bool>();
  }
  if (node.Has("ambient")) render.ambient = ReadInRange(node.Member("ambient"), 0, 1, "an ambient share in [0, 1]");
  return render;
}

}  // namespace tcfarm::scene_parse
