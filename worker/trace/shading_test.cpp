// Shading beyond the paper's spheres: smooth meshes, spot lights, ranged lights, emission,
// orthographic cameras, each against its closed form.
#include <gtest/gtest.h>

#include <algorithm>
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

// A point light with a range, straight above a floor seen from above through an
// orthographic camera: glTF's clamp(1 - (d / range)^4, 0, 1) / d^2 along a row, nothing and
// no shadow ray beyond the range, and the pure inverse square without one.
TEST(ShadingTest, RangedLightsFadeToNothingAtTheirRange) {
  auto scene = [](const std::string& range) {
    return ParseScene(R"({"camera": {"position": [0, 10, 0], "look_at": [0, 0, 0], "up": [0, 0, -1],
                                     "projection": "orthographic", "ortho_height": 12.5},
      "lights": [{"type": "point", "position": [0, 2, 0], "intensity": [16, 16, 16])" + range + R"(}],
      "materials": {"white": {"diffuse": [1, 1, 1]}},
      "shapes": [{"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0], "material": "white"}],
      "render": {"width": 25, "height": 25}})");
  };
  // The middle row's pixels are half a unit apart: pixel 12 + k sees the floor k / 2 off
  // the light's foot, at d^2 = (k / 2)^2 + 2^2 from it, under a cosine of 2 / d.
  auto lit = [](int k, double range) {
    const double d2 = k * k / 4.0 + 4, d = std::sqrt(d2);
    const double share = range > 0 ? std::clamp(1 - d2 * d2 / std::pow(range, 4), 0.0, 1.0) : 1;
    return 0.05 + 16 * (2 / d) * share / d2;
  };
  auto pixel = [](const std::vector<float>& rgb, int k) { return rgb[3 * (12 * 25 + 12 + k)]; };
  EmbreeDevice device;
  TracingThreads threads(2);
  Scene ranged = scene(R"(, "range": 4)"), unranged = scene("");
  Tracer rangedTracer(device, ranged, threads), unrangedTracer(device, unranged, threads);
  std::vector<float> rgb(25 * 25 * 3), pure(25 * 25 * 3);
  rangedTracer.TraceFrame(0, rgb.data());
  unrangedTracer.TraceFrame(0, pure.data());
  for (int k : {0, 2, 4, 6}) {
    EXPECT_NEAR(pixel(rgb, k), lit(k, 4), 1e-5) << "k = " << k;
    EXPECT_NEAR(pixel(pure, k), lit(k, 0), 1e-5) << "k = " << k;
  }
  // d^2 = 20 > 16: beyond the range, the ambient term alone, while without one it is lit.
  EXPECT_NEAR(pixel(rgb, 8), 0.05f, 1e-6f);
  EXPECT_GT(pixel(pure, 8), 0.1f);
  EXPECT_LT(rangedTracer.Counts().shadow * 3, unrangedTracer.Counts().shadow) << "shadow rays beyond the range";
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
