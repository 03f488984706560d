// The bare Embree loop, the benchmarks' yardstick, shades as the tracer does where both
// trace the same rays: here a glTF material, whose BRDF it must share for the yardstick to
// do comparable work.
#include "worker/trace/bare_embree_loop.h"

#include <gtest/gtest.h>

#include <vector>

#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

// A quad facing the camera under a slanting light, its material glTF's (a rough
// dielectric, tinted by its vertex colours).
Scene GltfQuad() {
  Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "lights": [{"type": "directional", "direction": [-0.3, -0.4, -1], "intensity": [2, 2, 2]}],
    "materials": {"quad": {"diffuse": [1, 1, 1]}},
    "shapes": [{"type": "mesh", "material": "quad", "vertices": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]],
                "triangles": [[0, 1, 2], [0, 2, 3]]}],
    "render": {"width": 9, "height": 9}})");
  MetallicRoughness pbr;
  pbr.baseColor = {0.9, 0.5, 0.2};
  pbr.metallic = 0.3;
  pbr.roughness = 0.5;
  pbr.doubleSided = true;
  scene.materials[static_cast<size_t>(scene.shapes[0].material)].model = pbr;
  scene.shapes[0].mesh.colors.assign(4, Vec3{0.5, 1, 1});
  return scene;
}

TEST(BareEmbreeLoopTest, ShadesGltfMaterialsWithTheTracersBrdf) {
  const Scene scene = GltfQuad();
  ASSERT_TRUE(BareEmbreeLoop::Covers(scene));
  EmbreeDevice device;
  TracingThreads threads(2);
  const size_t values = static_cast<size_t>(scene.render.width) * scene.render.height * 3;
  std::vector<float> traced(values), bare(values);
  Tracer(device, scene, threads).TraceFrame(0, traced.data());
  BareEmbreeLoop(device.get(), scene).TraceFrame(0, threads, bare.data());
  const size_t centre = 3 * (4 * 9 + 4);
  for (int channel = 0; channel < 3; ++channel) {
    EXPECT_NEAR(bare[centre + channel], traced[centre + channel], 1e-4f * traced[centre + channel]) << channel;
  }
  // Lit, and tinted by the vertex colours: red halved against the base colour's.
  EXPECT_GT(traced[centre + 1], traced[centre]);
}

// Mirrors and refraction are out of its reach, unless the scene traces none (maxDepth 0).
TEST(BareEmbreeLoopTest, CoversMirrorsOnlyWhenNoneAreTraced) {
  Scene scene = GltfQuad();
  scene.materials[static_cast<size_t>(scene.shapes[0].material)].As<MetallicRoughness>().roughness = 0.1;
  EXPECT_FALSE(BareEmbreeLoop::Covers(scene));
  scene.render.maxDepth = 0;
  EXPECT_TRUE(BareEmbreeLoop::Covers(scene));
}

}  // namespace
}  // namespace tcfarm
