// The yardstick the benchmarks hold the tracer to: a scene traced by a bare Embree loop,
// without anything the tracer adds for exactness (face normals computed in double, the tie
// rule, horizons, ray counts). The same shapes as the same Embree primitives
// (ShapeKind::NewGeometry), placed per frame as the tracer places them (still shapes in one
// scene; each moving shape in its own scene, instanced at its motion's matrix), the same
// camera rays, primary packets as wide as the tracer's (embree/ray_packets.h), one shadow
// packet per light, with Embree's own normals, on the same threads: Phong, or for a glTF
// material glTF's BRDF (gltf_brdf.h) over PbrMaterial::Surface at the hit's interpolated
// texture coordinates and vertex colours (textures read as the tracer reads them; no normal
// maps, no alpha masks or blending: every surface is solid). Placed frames are kept, as the
// tracer's frame cache keeps them. Mirrors and refraction are not traced: a scene with them
// is measured only with maxDepth 0, where the tracer traces none either.
#pragma once

#include <embree3/rtcore.h>

#include <array>
#include <map>
#include <memory>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/camera.h"
#include "worker/trace/float3.h"
#include "worker/trace/lights.h"
#include "worker/trace/materials.h"
#include "worker/util/tracing_threads.h"

namespace tcfarm {

class BareEmbreeLoop {
 public:
  // Embree's defaults (medium-quality trees, fast traversal), or with the tracer's flags:
  // high-quality trees for the scenes of shapes, traversed robustly where shapes share
  // edges (scene_geometry.h).
  enum class Flags { kEmbreeDefaults, kTracers };

  // The scene must outlive the loop.
  BareEmbreeLoop(RTCDevice device, const Scene& scene, Flags flags = Flags::kEmbreeDefaults);
  ~BareEmbreeLoop();
  BareEmbreeLoop(const BareEmbreeLoop&) = delete;
  BareEmbreeLoop& operator=(const BareEmbreeLoop&) = delete;

  // Whether the loop traces every ray the scene asks for (no mirrors, no refraction, or
  // none traced: maxDepth 0) and shades every material (Phong's and glTF's models).
  static bool Covers(const Scene& scene);
  // Every pixel of `frame`, row by row, as 3 floats of linear RGB.
  void TraceFrame(int frame, TracingThreads& threads, float* rgb);

 private:
  // A frame's traceable scene, and for each instance its shape (-1: the still shapes) and
  // the matrix carrying its object-space normals to the world (row-major).
  struct Placed {
    RTCScene scene = nullptr;
    std::vector<int> shapeOfInstance;
    std::vector<std::array<float, 9>> normalToWorld;
  };
  const Placed& Place(int frame);
  // What every chunk of a frame shares.
  struct FrameParts {
    const Placed& placed;
    PerspectiveCamera camera;
    std::vector<ShadingLight> lights;
    Float3 background;
    uint32_t width;
    int spp;
  };
  template <int Width>
  void TracePixels(const FrameParts& parts, size_t begin, size_t end, float* rgb) const;
  // robust: the tracer's flags hold robust traversal for this scene's shapes.
  RTCScene NewShapesScene(bool robust) const;
  // What a glTF material reads of a mesh at a hit, in float (shapes sharing a mesh share it).
  struct PbrMesh {
    const std::vector<std::array<uint32_t, 3>>* triangles = nullptr;
    std::vector<std::array<float, 2>> uvs, uvs1;
    std::vector<Float3> colors;
  };
  void MakePbrMeshes();
  // The BRDF's inputs at a hit on `shape` (triangle `primitive`, barycentric u, v).
  PbrSurface SurfaceAt(int shape, unsigned primitive, float u, float v) const;

  RTCDevice device_;
  const Scene& scene_;
  Flags flags_;
  int packetWidth_;
  bool robust_;  // the tracer's flags, on a scene with shared edges
  RTCScene still_ = nullptr;            // the still shapes, null when there are none
  std::vector<int> stillShapeOfGeometry_;
  std::vector<std::pair<int, RTCScene>> movers_;  // shape, its own scene
  std::map<int, Placed> placed_;
  std::vector<std::unique_ptr<TextureImage>> textures_;  // the images glTF materials read
  std::vector<ShadingMaterial> materials_;
  std::vector<std::shared_ptr<const PbrMesh>> pbrMeshes_;  // per shape; null unless its material is glTF's
};

}  // namespace tcfarm
