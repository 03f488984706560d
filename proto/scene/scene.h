// The scene contract: what an animated scene is, once parsed and validated.
//
// A scene file is JSON (proto/scene.schema.json describes it). ParseScene turns it into
// the plain structs below or throws SceneError naming the JSON pointer of the bad value.
// Everything downstream (worker, coordinator) trusts a Scene: all numbers are finite,
// all references resolved, every mesh either inline or a shared mesh of Scene::meshes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "proto/scene/animated_vec3.h"
#include "proto/scene/deformation.h"
#include "proto/scene/material.h"
#include "proto/scene/transform.h"

namespace tcfarm {

// Where the camera is at one frame, after its rig's motion.
struct CameraPose {
  Vec3 position, lookAt, up;
  bool operator==(const CameraPose& o) const {
    return position == o.position && lookAt == o.lookAt && up == o.up;
  }
};

struct Camera {
  AnimatedVec3 position;
  AnimatedVec3 lookAt;
  Vec3 up{0, 1, 0};
  double verticalFovDegrees = 45;
  // Orthographic cameras look along parallel rays over an image plane `orthographicHeight`
  // world units high (glTF's ymag * 2); the field of view is then unused.
  bool orthographic = false;
  double orthographicHeight = 2;
  // The rig carrying position, look-at point and up vector (none by default): a camera
  // can orbit, pan and roll as a transform of its own.
  Motion rig;

  CameraPose At(double frame) const;
  bool Moves() const { return position.IsAnimated() || lookAt.IsAnimated() || rig.IsAnimated(); }
};

// Every kind of light, each named once, in Light::Type's order: X(Stem) gives the type
// Light::Type::k<Stem>, the scene format's <Stem>LightFormat() (proto/scene/lights/<stem>.cpp:
// reading, writing, moving it) and the worker's <Stem>Shading (worker/trace/lights.h: what
// shading asks of it). A kind missing either part fails to compile or link.
#define TCFARM_LIGHT_KINDS(X) X(Point) X(Directional) X(Spot)

struct Light {
#define TCFARM_LIGHT_TYPE(Stem) k##Stem,
  enum class Type { TCFARM_LIGHT_KINDS(TCFARM_LIGHT_TYPE) };
#undef TCFARM_LIGHT_TYPE
  // How many kinds there are: Light::Type runs from 0 to kTypeCount - 1.
#define TCFARM_COUNT_LIGHT_TYPE(Stem) +1
  static constexpr size_t kTypeCount = 0 TCFARM_LIGHT_KINDS(TCFARM_COUNT_LIGHT_TYPE);
#undef TCFARM_COUNT_LIGHT_TYPE
  Type type = Type::kPoint;
  AnimatedVec3 position;   // point and spot lights
  AnimatedVec3 direction;  // directional and spot lights: the direction light travels
  // Spot lights: full intensity within innerConeDegrees of the axis, none beyond
  // outerConeDegrees, a smooth fall in between (glTF's KHR_lights_punctual cone).
  double innerConeDegrees = 0, outerConeDegrees = 45;
  AnimatedVec3 intensity;  // linear RGB radiant intensity (point) or irradiance (directional)
  Motion motion;           // carries position and direction (none by default)
  // Point and spot lights: beyond this distance they light nothing, fading smoothly as
  // glTF's KHR_lights_punctual recommends; 0 for no limit (pure inverse square).
  double range = 0;

  // Whether its kind places it (point, spot) and aims it (directional, spot).
  bool HasPosition() const;
  bool HasDirection() const;

  Vec3 PositionAt(double frame) const;
  Vec3 DirectionAt(double frame) const;
  bool Changes() const {
    return position.IsAnimated() || direction.IsAnimated() || intensity.IsAnimated() || motion.IsAnimated();
  }
  // Whether the light at frames a and b is the same, bit for bit.
  bool SameAt(double a, double b) const;
};

struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  // Optional per-vertex attributes, each either empty or one per vertex (the parser checks).
  // Shading normals, not necessarily unit length; a zero normal means "use the geometric one".
  std::vector<Vec3> normals;
  // Texture coordinates (u, v), as OBJ's vt and glTF's TEXCOORD_0 give them.
  std::vector<std::array<double, 2>> uvs;
  // A second set (glTF's TEXCOORD_1), which a material's texture may name.
  std::vector<std::array<double, 2>> uvs1;
  // Tangents (x, y, z, w): the direction of increasing u, w = +-1 the bitangent's sign
  // (glTF's TANGENT), for normal maps. Empty: shading derives them from the triangles.
  std::vector<std::array<double, 4>> tangents;
  // Linear RGB per vertex (glTF's COLOR_0), multiplying the material's diffuse colour
  // (and its texture) as glTF multiplies the base colour.
  std::vector<Vec3> colors;
};

// Every kind of shape, each named once, in Shape::Type's order: X(Stem) gives the type
// Shape::Type::k<Stem>, the scene format's <Stem>Format() (proto/scene/shapes/<stem>.cpp:
// reading, writing, moving it) and the worker's <Stem>Kind() (worker/shapes/: tracing it).
// A kind missing either part fails to link.
#define TCFARM_SHAPE_KINDS(X) X(Sphere) X(Quad) X(Mesh) X(Terrain)

struct Shape {
#define TCFARM_SHAPE_TYPE(Stem) k##Stem,
  enum class Type { TCFARM_SHAPE_KINDS(TCFARM_SHAPE_TYPE) };
#undef TCFARM_SHAPE_TYPE
  // How many kinds there are: Shape::Type runs from 0 to kTypeCount - 1.
#define TCFARM_COUNT_SHAPE_TYPE(Stem) +1
  static constexpr size_t kTypeCount = 0 TCFARM_SHAPE_KINDS(TCFARM_COUNT_SHAPE_TYPE);
#undef TCFARM_COUNT_SHAPE_TYPE
  Type type = Type::kSphere;
  std::string name;      // optional, for messages
  int material = 0;      // index into Scene::materials
  // The object's motion: the geometry below is its rest pose, placed at each frame by
  // motion.WorldFromObject(frame). None (identity at every frame) when it never moves.
  Motion motion;

  // kSphere
  Vec3 center;
  double radius = 1;
  // kQuad: corner, corner + edgeU, corner + edgeU + edgeV, corner + edgeV
  Vec3 corner, edgeU, edgeV;
  // kMesh, and kTerrain after generation (the parser generates terrain meshes): the
  // shape's own triangles, empty when it places a shared mesh instead.
  TriangleMesh mesh;
  // kMesh placing a mesh of Scene::meshes (one mesh, many placements: a forest of one
  // tree): its name there, and the mesh itself, held by the scene's table as well.
  std::string meshRef;
  std::shared_ptr<const TriangleMesh> sharedMesh;
  // kMesh: morph targets and/or a skin that move its vertices (deformation.h); none for a
  // rigid mesh. A skinned shape's motion is the identity: its joints place it.
  std::shared_ptr<const Deformation> deformation;
  // kTerrain parameters, kept so the scene can be written back
  struct Terrain {
    Vec3 origin;               // the minimum x/z corner at height 0
    double sizeX = 1, sizeZ = 1;
    double height = 1;         // peak-to-valley amplitude
    int cellsX = 100, cellsZ = 100;  // 2 triangles per cell
    uint64_t seed = 1;
  } terrain;

  bool Moves() const { return motion.IsAnimated() || Deforms(); }
  // Whether its vertices move relative to one another over the frames.
  bool Deforms() const { return deformation && deformation->IsAnimated(); }
  bool SharesMesh() const { return sharedMesh != nullptr; }
  // The triangles the shape places, its own or the shared ones: what every consumer reads.
  const TriangleMesh& Mesh() const { return sharedMesh ? *sharedMesh : mesh; }
};

struct RenderSettings {
  int width = 640;
  int height = 480;
  int firstFrame = 0;
  int frameCount = 1;
  int samplesPerPixel = 1;
  int maxDepth = 5;  // reflection/refraction bounces after the primary hit
  // Lighting switches for comparisons with renderers that lack them (a rasterizer without
  // shadow maps or image-based light): shadow rays off, every light reaching every surface
  // that faces it; the ambient term's share of a surface's colour (0.05 by default).
  bool shadows = true;
  double ambient = kDefaultAmbient;
  static constexpr double kDefaultAmbient = 0.05;
  int LastFrame() const { return firstFrame + frameCount - 1; }
};

// One thing an importer added, left out or could not honour. `code` is a stable snake_case
// name (counted per code in the coordinator's metrics), `pointer` the JSON pointer into
// `file` it concerns (empty for the whole file), `message` what happened, for a person.
struct ImportWarning {
  std::string code;
  std::string file;
  std::string pointer;
  std::string message;
  // "<file> at <pointer>: <message>", as a log line reads it.
  std::string Line() const { return file + (pointer.empty() ? "" : " at " + pointer) + ": " + message; }
  bool operator==(const ImportWarning& o) const {
    return code == o.code && file == o.file && pointer == o.pointer && message == o.message;
  }
};

struct Scene {
  Camera camera;
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<Shape> shapes;
  // Meshes placed by several shapes (Shape::meshRef), by name: written and sent once.
  // Immutable once parsed, so copies of a scene share them.
  std::map<std::string, std::shared_ptr<const TriangleMesh>> meshes;
  Vec3 background{0, 0, 0};
  RenderSettings render;
  // What an importer added, left out or could not honour (a default camera, an extension it
  // does not implement), for whoever asked for the import to show its user (a submission's
  // job record lists them). Not written out.
  std::vector<ImportWarning> importWarnings;

  bool CameraMoves() const;
  bool AnyLightChanges() const;
  bool AnyShapeMoves() const;
  bool AnyMaterialReflects() const;
  bool AnyMaterialRefracts() const;
};

// The same world moved by `offset`: camera, lights that have a position, and shapes (a
// shape's motion is relative to its place, so it stays as it is).
void TranslateScene(Scene& scene, const Vec3& offset);

// Moves the world so that the camera stands at the origin at the first rendered frame.
// Tracing works in float: near the viewer, where rounding shows, coordinates then keep
// the digits that a scene far from the origin spends on its distance from it. Images
// are the same up to that rounding; the trace of every frame sees the same moved world.
void RebaseOnCamera(Scene& scene);

// Builds every shape that never moves where its constant transform puts it (vertices,
// quad corner and edges, sphere centre and radius under a uniform scale), leaving it
// with no motion, so a tracer holds it in its still geometry. A sphere scaled unevenly
// keeps its transform. A still shape placing a shared mesh gets its own placed copy: the
// static geometry holds world-space triangles, and an instance would trace other bits
// than the same mesh written inline. Images are the same up to rounding.
void PlaceStillShapes(Scene& scene);

// What a tracer is given, here as on every worker, so all trace the same bits:
// RebaseOnCamera, then PlaceStillShapes.
void PrepareForTracing(Scene& scene);

// Bad scene input. pointer() is the RFC 6901 JSON pointer of the offending value
// ("" for the whole document), what() reads "scene<pointer>: <problem>; expected <...>".
class SceneError : public std::runtime_error {
 public:
  SceneError(std::string pointer, const std::string& message);
  const std::string& pointer() const { return pointer_; }

 private:
  std::string pointer_;
};

// Called now and then during long work on a scene (generating terrain): it may throw to
// give the work up (a worker told to stop). Empty: never called.
using Checkpoint = std::function<void()>;

// Parses scene JSON text. baseDirectory resolves mesh "file" references (OBJ); a
// reference that escapes it is rejected. With no base directory, file references are
// rejected (scenes that arrive over the network must be self-contained).
Scene ParseScene(const std::string& jsonText,
                 const std::optional<std::filesystem::path>& baseDirectory = std::nullopt,
                 const Checkpoint& checkpoint = {});
// Reads and parses a scene JSON file; mesh files resolve relative to its folder.
// ImportScene (scene/import/scene_import.h) reads a scene file of any supported format.
Scene LoadSceneFile(const std::filesystem::path& path);

// Writes a scene back to self-contained JSON (meshes inline or in the shared table, once,
// terrain as parameters); a scene without shared meshes writes no "meshes" key.
// ParseScene(SerializeScene(s)) == s. Stable output: the same scene gives the same bytes,
// so a hash of it identifies the scene.
std::string SerializeScene(const Scene& scene);

// The deterministic heightfield mesh of a terrain shape (Shape::terrain parameters).
// `checkpoint` is called once a row of cells.
TriangleMesh GenerateTerrain(const Shape::Terrain& terrain, const Checkpoint& checkpoint = {});

}  // namespace tcfarm
