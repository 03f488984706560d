// Reading a scene document: its parts in order, an imported base, the render settings.
#include "proto/scene/parse/scene_reader.h"
#include "proto/scene/shapes/shape_format.h"

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
  const std::string expected = "{\"file\": a glTF or OBJ file in the scene's folder, \"animation\", \"camera\", \"fps\"}";
  ExpectObject(node, {"file", "animation", "camera", "fps"}, expected);
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
  if (node.Has("fps")) options.framesPerSecond = ReadInRange(node.Member("fps"), kMinFramesPerSecond, kMaxFramesPerSecond, "frames per second");
  for (const char* key : {"animation", "camera"}) {
    if (!node.Has(key)) continue;
    const Node choice = node.Member(key);
    if (!choice.value.is_string() && !IsIntegral(choice.value)) FailType(choice, "a name or an index");
    (std::string(key) == "animation" ? options.animation : options.camera) =
        choice.value.is_string() ? choice.value.get<std::string>() : std::to_string(choice.value.get<int64_t>());
  }
  if (root.Has("render") && root.value["render"].is_object()) {
    const Node render = root.Member("render");
    if (render.Has("width")) options.width = ReadInt(render.Member("width"), 1, kMaxImageSide);
    if (render.Has("height")) options.height = ReadInt(render.Member("height"), 1, kMaxImageSide);
    if (render.Has("samples_per_pixel")) {
      options.samplesPerPixel = ReadInt(render.Member("samples_per_pixel"), 1, kMaxSamplesPerPixel);
    }
  }
  return options;
}

RenderSettings SceneReader::ReadRender(const Node& node, const std::optional<RenderSettings>& base) {
  ExpectObject(node, {"width", "height", "frames", "samples_per_pixel", "max_depth"}, "render settings");
  RenderSettings render = base.value_or(RenderSettings{});
  const std::string sideExpected = "an integer in [1, " + std::to_string(kMaxImageSide) + "]";
  if (!base || node.Has("width")) render.width = ReadInt(Required(node, "width", sideExpected), 1, kMaxImageSide);
  if (!base || node.Has("height")) render.height = ReadInt(Required(node, "height", sideExpected), 1, kMaxImageSide);
  if (node.Has("frames")) {
    Node frames = node.Member("frames");
    ExpectObject(frames, {"start", "count"}, "{\"start\": first frame, \"count\": number of frames}");
    if (frames.Has("start")) render.firstFrame = ReadInt(frames.Member("start"), 0, kMaxFirstFrame);
    if (frames.Has("count")) render.frameCount = ReadInt(frames.Member("count"), 1, kMaxFrameCount);
  }
  if (node.Has("samples_per_pixel")) {
    render.samplesPerPixel = ReadInt(node.Member("samples_per_pixel"), 1, kMaxSamplesPerPixel);
  }
  if (node.Has("max_depth")) render.maxDepth = ReadInt(node.Member("max_depth"), 0, kMaxBounceDepth);
  return render;
}

}  // namespace tcfarm::scene_parse
