// The scene contract: what an animated scene is, once parsed and validated.
//
// A scene file is JSON (proto/scene.schema.json describes it). ParseScene turns it into
// the plain structs below or throws SceneError naming the JSON pointer of the bad value.
// Everything downstream (worker, coordinator) trusts a Scene: all numbers are finite,
// all references resolved, all meshes inline.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tcfarm {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  bool operator==(const Vec3& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator!=(const Vec3& o) const { return !(*this == o); }
};

// A vec3-valued function of frame time, as in the paper's section 5: either a constant,
// a polynomial per axis in the frame number, or keyframes interpolated linearly (and
// held constant before the first and after the last key).
class AnimatedVec3 {
 public:
  struct Keyframe {
    double frame;
    Vec3 value;
  };

  AnimatedVec3() = default;
  static AnimatedVec3 Constant(Vec3 value);
  // coefficients[axis][k] multiplies frame^k.
  static AnimatedVec3 Polynomial(std::array<std::vector<double>, 3> coefficients);
  // Keys must be sorted by frame with no two on the same frame (the parser checks).
  static AnimatedVec3 Keyframes(std::vector<Keyframe> keys);

  Vec3 Evaluate(double frame) const;
  // True when Evaluate can return different values for different frames.
  bool IsAnimated() const;
  // True when Evaluate(a) == Evaluate(b) bit for bit (exact, not approximate).
  bool SameAt(double a, double b) const { return Evaluate(a) == Evaluate(b); }

  enum class Kind { kConstant, kPolynomial, kKeyframes };
  Kind kind() const { return kind_; }
  const std::array<std::vector<double>, 3>& coefficients() const { return coefficients_; }
  const std::vector<Keyframe>& keys() const { return keys_; }
  const Vec3& constant() const { return constant_; }

 private:
  Kind kind_ = Kind::kConstant;
  Vec3 constant_;
  std::array<std::vector<double>, 3> coefficients_;
  std::vector<Keyframe> keys_;
};

struct Camera {
  AnimatedVec3 position;
  AnimatedVec3 lookAt;
  Vec3 up{0, 1, 0};
  double verticalFovDegrees = 45;
};

struct Light {
  enum class Type { kPoint, kDirectional };
  Type type = Type::kPoint;
  AnimatedVec3 position;   // point lights
  AnimatedVec3 direction;  // directional lights: the direction light travels
  AnimatedVec3 intensity;  // linear RGB radiant intensity (point) or irradiance (directional)
};

struct Material {
  std::string name;
  Vec3 diffuse{0.8, 0.8, 0.8};
  Vec3 specular{0, 0, 0};
  double shininess = 32;      // Phong exponent
  double reflectivity = 0;    // 0..1, mirror reflection weight
  double transparency = 0;    // 0..1, refraction weight
  double indexOfRefraction = 1.5;

  bool Reflects() const { return reflectivity > 0; }
  bool Refracts() const { return transparency > 0; }
};

struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  // Optional per-vertex attributes, each either empty or one per vertex (the parser checks);
  // imported files bring them, and the tracer does not read them yet.
  // Shading normals, not necessarily unit length; a zero normal means "use the geometric one".
  std::vector<Vec3> normals;
  // Texture coordinates (u, v), as OBJ's vt and glTF's TEXCOORD_0 give them.
  std::vector<std::array<double, 2>> uvs;
};

struct Shape {
  enum class Type { kSphere, kQuad, kMesh, kTerrain };
  Type type = Type::kSphere;
  std::string name;      // optional, for messages
  int material = 0;      // index into Scene::materials
  AnimatedVec3 translation;  // the object's motion; constant zero when it never moves

  // kSphere
  Vec3 center;
  double radius = 1;
  // kQuad: corner, corner + edgeU, corner + edgeU + edgeV, corner + edgeV
  Vec3 corner, edgeU, edgeV;
  // kMesh, and kTerrain after generation (the parser generates terrain meshes)
  TriangleMesh mesh;
  // kTerrain parameters, kept so the scene can be written back
  struct Terrain {
    Vec3 origin;               // the minimum x/z corner at height 0
    double sizeX = 1, sizeZ = 1;
    double height = 1;         // peak-to-valley amplitude
    int cellsX = 100, cellsZ = 100;  // 2 triangles per cell
    uint64_t seed = 1;
  } terrain;

  bool Moves() const { return translation.IsAnimated(); }
};

struct RenderSettings {
  int width = 640;
  int height = 480;
  int firstFrame = 0;
  int frameCount = 1;
  int samplesPerPixel = 1;
  int maxDepth = 5;  // reflection/refraction bounces after the primary hit
  int LastFrame() const { return firstFrame + frameCount - 1; }
};

struct Scene {
  Camera camera;
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<Shape> shapes;
  Vec3 background{0, 0, 0};
  RenderSettings render;

  bool CameraMoves() const;
  bool AnyLightChanges() const;
  bool AnyShapeMoves() const;
  bool AnyMaterialReflects() const;
  bool AnyMaterialRefracts() const;
};

// The same world moved by `offset`: camera, point lights and shapes (a shape's motion is
// relative to its place, so it stays as it is).
void TranslateScene(Scene& scene, const Vec3& offset);

// Moves the world so that the camera stands at the origin at the first rendered frame.
// Tracing works in float: near the viewer, where rounding shows, coordinates then keep
// the digits that a scene far from the origin spends on its distance from it. Images
// are the same up to that rounding; the trace of every frame sees the same moved world.
void RebaseOnCamera(Scene& scene);

// Keeps a single job within a worker's memory (Embree BVH plus mesh: ~100 bytes/triangle);
// every importer charges its triangles against it.
constexpr size_t kMaxSceneTriangles = 20'000'000;

// Bad scene input. pointer() is the RFC 6901 JSON pointer of the offending value
// ("" for the whole document), what() reads "scene<pointer>: <problem>; expected <...>".
class SceneError : public std::runtime_error {
 public:
  SceneError(std::string pointer, const std::string& message);
  const std::string& pointer() const { return pointer_; }

 private:
  std::string pointer_;
};

// Parses scene JSON text. baseDirectory resolves mesh "file" references (OBJ); a
// reference that escapes it is rejected. With no base directory, file references are
// rejected (scenes that arrive over the network must be self-contained).
Scene ParseScene(const std::string& jsonText,
                 const std::optional<std::filesystem::path>& baseDirectory = std::nullopt);
// Reads and parses a scene JSON file; mesh files resolve relative to its folder.
// ImportScene (scene/import/scene_import.h) reads a scene file of any supported format.
Scene LoadSceneFile(const std::filesystem::path& path);

// Writes a scene back to self-contained JSON (meshes inline, terrain as parameters).
// ParseScene(SerializeScene(s)) == s. Stable output: the same scene gives the same bytes,
// so a hash of it identifies the scene.
std::string SerializeScene(const Scene& scene);

// The deterministic heightfield mesh of a terrain shape (Shape::terrain parameters).
TriangleMesh GenerateTerrain(const Shape::Terrain& terrain);

}  // namespace tcfarm
