// Shading beyond the paper's spheres: smooth meshes, spot lights, emission, orthographic
// cameras, each against its closed form.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

std::vector<float> Render(const Scene& scene, int frame = 0) {
  EmbreeDevice device;
  TracingThreads threads(2);
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  tracer.TraceFrame(frame, rgb.data());
  return rgb;
}

// A smooth mesh shades with its interpolated vertex normals: two triangles facing the
// camera whose vertices all lean the same way light like a plane leaning that way.
TEST(ShadingTest, SmoothMeshesShadeWithTheirVertexNormals) {
  const double lean = std::sqrt(0.5);
  auto scene = [&](bool smooth) {
    std::string normals = smooth ? R"(, "normals": [[0, )" + std::to_string(lean) + ", " + std::to_string(lean) +
                                       R"(], [0, 0.7071067811865476, 0.7071067811865476], [0, 0.7071067811865476, 0.7071067811865476],
                                       [0, 0.7071067811865476, 0.7071067811865476]])"
                                 : "";
    return ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
      "lights": [{"type": "directional", "direction": [0, -1, 0], "intensity": [1, 1, 1]}],
      "materials": {"white": {"diffuse": [1, 1, 1]}},
      "shapes": [{"type": "mesh", "material": "white", "vertices": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]],
                  "triangles": [[0, 1, 2], [0, 2, 3]])" + normals + R"(}],
      "render": {"width": 9, "height": 9}})");
  };
  const size_t centre = 3 * (4 * 9 + 4);
  std::vector<float> flat = Render(scene(false), 0), smooth = Render(scene(true), 0);
  // Flat: the light grazes the plane (cosine 0), only the ambient term is left.
  EXPECT_NEAR(flat[centre], 0.05f, 1e-6f);
  // Smooth: the normals lean 45 degrees toward the light.
  EXPECT_NEAR(smooth[centre], 0.05f + std::sqrt(0.5f), 1e-5f);
}

// A spot light straight down onto a floor, seen from above: full light under it, a softer
// ring between the cones, nothing beyond the outer cone, and no shadow ray cast there.
TEST(ShadingTest, SpotLightsLightTheirConeOnly) {
  auto scene = [](const std::string& light) {
    return ParseScene(R"({"camera": {"position": [0, 10, 0.001], "look_at": [0, 0, 0], "fov_degrees": 60},
      "lights": [)" + light + R"(], "materials": {"white": {"diffuse": [1, 1, 1]}},
      "shapes": [{"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0], "material": "white"}],
      "render": {"width": 41, "height": 41}})");
  };
  const std::string spot = R"({"type": "spot", "position": [0, 4, 0], "direction": [0, -1, 0], "intensity": [16, 16, 16],
                               "inner_cone_degrees": 20, "outer_cone_degrees": 30})";
  EmbreeDevice device;
  TracingThreads threads(2);
  Scene spotScene = scene(spot);
  Tracer tracer(device, spotScene, threads);
  std::vector<float> rgb(41 * 41 * 3);
  tracer.TraceFrame(0, rgb.data());
  const size_t centre = 3 * (20 * 41 + 20), corner = 3 * (1 * 41 + 1);
  EXPECT_NEAR(rgb[centre], 0.05f + 16.0f / 16.0f, 1e-3f);  // intensity / 4^2, cosine 1
  EXPECT_NEAR(rgb[corner], 0.05f, 1e-6f);                    // outside the cone: ambient alone
  const uint64_t spotShadowRays = tracer.Counts().shadow;
  Scene pointScene = scene(R"({"type": "point", "position": [0, 4, 0], "intensity": [16, 16, 16]})");
  Tracer pointTracer(device, pointScene, threads);
  pointTracer.TraceFrame(0, rgb.data());
  EXPECT_LT(spotShadowRays * 4, pointTracer.Counts().shadow) << "shadow rays outside the cone";
}

// A surface shows its emission on top of what lights it, even in the dark.
TEST(ShadingTest, EmissionShowsWithoutLight) {
  Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "materials": {"lamp": {"diffuse": [0.5, 0.5, 0.5], "emission": [2, 1, 0.25]}},
    "shapes": [{"type": "quad", "corner": [-4, -4, 0], "edge_u": [8, 0, 0], "edge_v": [0, 8, 0], "material": "lamp"}],
    "render": {"width": 5, "height": 5}})");
  const std::vector<float> rgb = Render(scene);
  const float* centre = &rgb[3 * 12];
  EXPECT_NEAR(centre[0], 0.025f + 2, 1e-6f);  // ambient 0.05 x diffuse 0.5, plus emission
  EXPECT_NEAR(centre[1], 0.025f + 1, 1e-6f);
  EXPECT_NEAR(centre[2], 0.025f + 0.25f, 1e-6f);
}

// An orthographic camera's image is the same size at any distance; a perspective one's shrinks.
TEST(ShadingTest, OrthographicCamerasKeepSizesAtAnyDistance) {
  auto coveredShare = [](double distance, bool orthographic) {
    const std::string projection = orthographic ? R"(, "projection": "orthographic", "ortho_height": 4)" : "";
    Scene scene = ParseScene(R"({"camera": {"position": [0, 0, )" + std::to_string(distance) +
                             R"(], "look_at": [0, 0, 0])" + projection + R"(},
      "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}], "background": [0, 0, 0],
      "render": {"width": 40, "height": 40}})");
    const std::vector<float> rgb = Render(scene);
    size_t covered = 0;
    for (size_t i = 0; i < rgb.size(); i += 3) covered += rgb[i] > 0;
    return static_cast<double>(covered) / (rgb.size() / 3);
  };
  // A unit sphere in a 4-wide view covers pi / 16 of it.
  EXPECT_NEAR(coveredShare(5, true), M_PI / 16, 0.02);
  EXPECT_NEAR(coveredShare(50, true), M_PI / 16, 0.02);
  EXPECT_GT(coveredShare(5, false), 4 * coveredShare(50, false));
}

}  // namespace
}  // namespace tcfarm
