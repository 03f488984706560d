// Shapes placing one shared mesh (Scene::meshes) render the very bits of the same scene
// with the mesh written inline in every shape: still and moving placements, turned and
// scaled, smooth normals, textures through uvs, coplanar copies settled by shape order,
// and the validity horizons of `exact`.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "tests/support/cpp/checker_png_for_tests.h"
#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr int kWidth = 96;
constexpr int kHeight = 72;
constexpr int kFrames = 6;

// A smooth, textured box: normals leaning outward from its centre, uvs over each face.
json BoxMesh() {
  json vertices = json::array(), normals = json::array(), uvs = json::array();
  for (int i = 0; i < 8; ++i) {
    const double x = i & 1 ? 0.5 : -0.5, y = i & 2 ? 1.0 : 0.0, z = i & 4 ? 0.5 : -0.5;
    vertices.push_back({x, y, z});
    normals.push_back({x, y - 0.5, z});
    uvs.push_back({i & 1 ? 1.0 : 0.0, i & 2 ? 0.0 : 1.0});
  }
  json triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                    {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  return {{"vertices", vertices}, {"triangles", triangles}, {"normals", normals}, {"uvs", uvs}};
}

json Placement(const std::string& material, json motion) {
  json shape = {{"type", "mesh"}, {"mesh_ref", "box"}, {"material", material}};
  if (!motion.is_null()) shape["motion"] = std::move(motion);
  return shape;
}

// Still boxes (one in place, one turned and scaled, one an exact copy of another: their
// faces tie), moving ones (translated; turned, scaled and mirrored), over a floor.
json SharedScene(const fs::path& texture) {
  json shapes = json::array();
  shapes.push_back({{"type", "quad"}, {"corner", {-10, 0, -10}}, {"edge_u", {0, 0, 20}}, {"edge_v", {20, 0, 0}}});
  shapes.push_back(Placement("printed", nullptr));
  shapes.push_back(Placement("red", {{"translation", {-2, 0, -1}}, {"rotation", {0, 0.38, 0, 0.92}},
                                     {"scale", {1.2, 0.7, 1}}}));
  shapes.push_back(Placement("printed", {{"translation", {-2, 0, -1}}, {"rotation", {0, 0.38, 0, 0.92}},
                                         {"scale", {1.2, 0.7, 1}}}));
  shapes.push_back(Placement("red", {{"translation", {{"polynomial", {{1.5, 0.1}, {0}, {0}}}}}}));
  shapes.push_back(Placement("printed", {{"translation", {{"polynomial", {{1.5, 0.1}, {0}, {0}}}}}}));
  shapes.push_back(Placement("printed", {{"translation", {0.5, 0.2, 1.5}},
                                         {"rotation", {{"axis", {0.3, 1, 0.2}}, {"degrees_per_frame", 13}}},
                                         {"scale", {{"polynomial", {{-0.8, 0.05}, {0.9}, {1, -0.04}}}}},
                                         {"pivot", {0, 0.5, 0}}}));
  json texel = {{"image", texture.filename().string()}, {"filter", "nearest"}};
  return {{"camera", {{"position", {0.3, 3, 6}}, {"look_at", {0, 0.5, 0}}}},
          {"lights", {{{"type", "point"}, {"position", {3, 6, 4}}, {"intensity", {60, 60, 60}}}}},
          {"materials", {{"red", {{"diffuse", {0.8, 0.1, 0.1}}, {"specular", {0.4, 0.4, 0.4}}}},
                         {"printed", {{"diffuse", {1, 1, 1}}, {"diffuse_texture", texel}, {"reflectivity", 0.3}}}}},
          {"meshes", {{"box", BoxMesh()}}},
          {"shapes", shapes},
          {"render", {{"width", kWidth}, {"height", kHeight}, {"frames", {{"start", 0}, {"count", kFrames}}}}}};
}

// The same scene with the shared mesh written into every shape that places it.
json Inlined(json scene) {
  for (json& shape : scene["shapes"]) {
    if (!shape.contains("mesh_ref")) continue;
    const json mesh = scene["meshes"][shape["mesh_ref"].get<std::string>()];
    shape.erase("mesh_ref");
    shape.update(mesh);
  }
  scene.erase("meshes");
  return scene;
}

struct Rendered {
  std::vector<float> rgb;
  std::vector<int32_t> horizons;
};

// Every pixel of a frame traced with horizons over the rest of the animation.
Rendered Render(const json& text, const fs::path& folder, int frame) {
  Scene scene = ParseScene(text.dump(), folder);
  PrepareForTracing(scene);
  EmbreeDevice device;
  TracingThreads pool(2);
  Tracer tracer(device, scene, pool);
  std::vector<uint32_t> pixels(kWidth * kHeight);
  for (uint32_t i = 0; i < pixels.size(); ++i) pixels[i] = i;
  Rendered out{std::vector<float>(pixels.size() * 3), std::vector<int32_t>(pixels.size())};
  tracer.TracePixels(frame, pixels.data(), pixels.size(), out.rgb.data(), kFrames, out.horizons.data());
  return out;
}

class SharedMeshTracingTest : public testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_shared_mesh_test_" + std::to_string(::getpid()));
    fs::create_directories(folder_);
    WriteCheckerPng(folder_ / "checker.png");
  }
  void TearDown() override { fs::remove_all(folder_); }
  fs::path folder_;
};

TEST_F(SharedMeshTracingTest, RendersTheBitsOfInlineCopies) {
  const json shared = SharedScene(folder_ / "checker.png");
  for (int frame = 0; frame < kFrames; frame += 2) {
    const Rendered a = Render(shared, folder_, frame);
    const Rendered b = Render(Inlined(shared), folder_, frame);
    ASSERT_EQ(0, std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float))) << "frame " << frame;
    ASSERT_EQ(a.horizons, b.horizons) << "frame " << frame;
  }
}

TEST_F(SharedMeshTracingTest, SceneShowsTheMeshAndItsMovers) {
  // Guards the comparison above against a scene that shows nothing worth comparing.
  const Rendered frame0 = Render(SharedScene(folder_ / "checker.png"), folder_, 0);
  const Rendered frame4 = Render(SharedScene(folder_ / "checker.png"), folder_, 4);
  EXPECT_NE(0, std::memcmp(frame0.rgb.data(), frame4.rgb.data(), frame0.rgb.size() * sizeof(float)));
  size_t red = 0;
  for (size_t i = 0; i < frame0.rgb.size(); i += 3) red += frame0.rgb[i] > 2 * frame0.rgb[i + 1] + 0.05f;
  EXPECT_GT(red, 50u);
}

TEST_F(SharedMeshTracingTest, MovingPlacementsShareOneObjectTree) {
  Scene scene = ParseScene(SharedScene(folder_ / "checker.png").dump(), folder_);
  PrepareForTracing(scene);
  size_t stillShared = 0, movingShared = 0;
  for (const Shape& shape : scene.shapes) {
    if (shape.SharesMesh()) (shape.Moves() ? movingShared : stillShared)++;
  }
  // Still placements are built in place; the box placed at the identity stays shared.
  EXPECT_EQ(1u, stillShared);
  EXPECT_EQ(3u, movingShared);
}

}  // namespace
}  // namespace tcfarm
