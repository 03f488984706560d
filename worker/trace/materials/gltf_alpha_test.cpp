// glTF's alpha modes and one-sided materials in every traversal: a masked surface is not
// there for camera or shadow rays, a blended one covers alpha of what is behind it and lets
// 1 - alpha of a light through, and a one-sided one is seen from its front only.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "worker/tracing.h"

namespace tcfarm {
namespace {

constexpr int kSide = 9;
constexpr size_t kCentre = 3 * (4 * kSide + 4);

std::vector<float> Render(const std::string& json) {
  const Scene scene = ParseScene(json);
  EmbreeDevice device;
  TracingThreads threads(1);
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(kSide * kSide * 3);
  tracer.TraceFrame(0, rgb.data());
  return rgb;
}

// Two triangles at z = z0 facing +z (towards the camera) or -z, with material `material`.
std::string Panel(const std::string& material, double z, bool facingCamera, double size = 1) {
  const std::string s = std::to_string(size), zs = std::to_string(z);
  const std::string triangles = facingCamera ? "[[0, 1, 2], [0, 2, 3]]" : "[[0, 2, 1], [0, 3, 2]]";
  return R"({"type": "mesh", "material": ")" + material + R"(", "vertices": [[-)" + s + ", -" + s + ", " + zs + "], [" +
         s + ", -" + s + ", " + zs + "], [" + s + ", " + s + ", " + zs + "], [-" + s + ", " + s + ", " + zs +
         R"(]], "triangles": )" + triangles + "}";
}

std::string SceneWith(const std::string& materials, const std::string& shapes, const std::string& lights = "") {
  return R"({"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]}, "background": [0, 0, 1],
    "lights": [)" + lights + R"(], "materials": {)" + materials + R"(}, "shapes": [)" + shapes + R"(],
    "render": {"width": 9, "height": 9, "ambient": 0}})";
}

TEST(GltfAlphaTest, AOneSidedSurfaceIsSeenFromItsFrontOnly) {
  const std::string red = R"("red": {"pbr": {"base_color": [1, 0, 0], "unlit": true}})";
  const std::string twoSided = R"("red": {"pbr": {"base_color": [1, 0, 0], "unlit": true, "double_sided": true}})";
  EXPECT_FLOAT_EQ(Render(SceneWith(red, Panel("red", 0, true)))[kCentre], 1.0f);
  EXPECT_FLOAT_EQ(Render(SceneWith(red, Panel("red", 0, false)))[kCentre + 2], 1.0f);  // the background's blue
  EXPECT_FLOAT_EQ(Render(SceneWith(twoSided, Panel("red", 0, false)))[kCentre], 1.0f);
}

TEST(GltfAlphaTest, AMaskedSurfaceIsThereWhereItsAlphaReachesTheCutoff) {
  auto masked = [](double alpha) {
    return R"("red": {"pbr": {"base_color": [1, 0, 0], "unlit": true, "double_sided": true, "alpha_mode": "mask",
                        "alpha": )" + std::to_string(alpha) + "}}";
  };
  EXPECT_FLOAT_EQ(Render(SceneWith(masked(0.6), Panel("red", 0, true)))[kCentre], 1.0f);
  EXPECT_FLOAT_EQ(Render(SceneWith(masked(0.4), Panel("red", 0, true)))[kCentre + 2], 1.0f);
}

TEST(GltfAlphaTest, AMaskedSurfaceCastsNoShadowWhereItIsCut) {
  // A white floor at z = 0 lit head-on by a light at z = 3; a large panel at z = 1 between.
  const std::string materials =
      R"("floor": {"pbr": {"base_color": [1, 1, 1], "metallic": 0, "roughness": 1, "double_sided": true}},
         "cut": {"pbr": {"base_color": [1, 1, 1], "alpha_mode": "mask", "alpha": 0.2, "double_sided": true}},
         "kept": {"pbr": {"base_color": [1, 1, 1], "alpha_mode": "mask", "alpha": 0.8, "double_sided": false}})";
  const std::string light = R"({"type": "directional", "direction": [0, 0, -1], "intensity": [3, 3, 3]})";
  const float open = Render(SceneWith(materials, Panel("floor", 0, true, 3), light))[kCentre];
  const float cut = Render(SceneWith(materials, Panel("floor", 0, true, 3) + ", " + Panel("cut", 1, false, 3), light))[kCentre];
  EXPECT_GT(open, 0.5f);
  EXPECT_EQ(cut, open);
  // A kept one-sided panel seen from behind is not seen, but it still casts its shadow.
  const std::vector<float> kept = Render(SceneWith(materials, Panel("floor", 0, true, 3) + ", " + Panel("kept", 1, false, 3), light));
  EXPECT_EQ(kept[kCentre], 0.0f);
}

TEST(GltfAlphaTest, ABlendedSurfaceCoversAlphaOfWhatIsBehindAndPassesTheRestOfALight) {
  const std::string materials =
      R"("green": {"pbr": {"base_color": [0, 1, 0], "unlit": true, "double_sided": true}},
         "glass": {"pbr": {"base_color": [1, 0, 0], "unlit": true, "alpha_mode": "blend", "alpha": 0.25, "double_sided": true}})";
  const std::vector<float> seen = Render(SceneWith(materials, Panel("green", 0, true) + ", " + Panel("glass", 1, true)));
  EXPECT_NEAR(seen[kCentre], 0.25f, 1e-6f);      // red over
  EXPECT_NEAR(seen[kCentre + 1], 0.75f, 1e-6f);  // green through
  // Its shadow: 1 - alpha of the light reaches the floor behind it.
  const std::string lit =
      R"("floor": {"pbr": {"base_color": [1, 1, 1], "metallic": 0, "roughness": 1, "double_sided": true}},
         "veil": {"pbr": {"base_color": [1, 1, 1], "alpha_mode": "blend", "alpha": 0.25, "double_sided": true}})";
  const std::string light = R"({"type": "directional", "direction": [0, 0, -1], "intensity": [3, 3, 3]})";
  const std::string floor = Panel("floor", 0, true, 3);
  // Seen past the veil (3/4 of the floor's light shows) and lit through it (3/4 arrives).
  const float open = Render(SceneWith(lit, floor, light))[kCentre];
  const std::vector<float> veiled = Render(SceneWith(lit, floor + ", " + Panel("veil", 1, true, 3), light));
  const float veilItself = Render(SceneWith(lit, Panel("veil", 1, true, 3), light))[kCentre];
  EXPECT_NEAR(veiled[kCentre], veilItself + 0.75f * 0.75f * open, 1e-5f);
}

}  // namespace
}  // namespace tcfarm
