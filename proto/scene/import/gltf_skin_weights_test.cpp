// What real exporters write that glTF forbids, accepted and said: skin weights that do
// not sum to 1, influences of weight 0 naming joints the skin lacks, and frames asked for
// past the animation's end.
#include <gtest/gtest.h>

#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/scene/deformation.h"
#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene_limits.h"
#include "tests/support/cpp/gltf_builder.h"
#include "tests/support/cpp/scene_test_support.h"

namespace tcfarm {
namespace {

using nlohmann::json;

// The strip's default weights: the bottom row on the hip, the middle half and half, the
// top on the knee (SkinnedStrip).
const std::vector<double> kStripWeights = {1, 0, 0, 0, 1, 0, 0, 0, 0.5, 0.5, 0, 0,
                                           0.5, 0.5, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0};

std::optional<ImportWarning> WarningOf(const Scene& scene, const std::string& code) {
  std::optional<ImportWarning> found;
  for (const ImportWarning& warning : scene.importWarnings) {
    if (warning.code != code) continue;
    EXPECT_FALSE(found) << "a second " << code << " warning: " << warning.Line();
    found = warning;
  }
  return found;
}

std::vector<Vec3> DeformedVertices(const Shape& shape, double frame) {
  return Deform(shape.Mesh(), *shape.deformation, frame).positions;
}

// Both shapes' vertices, deformed, have the same bits at every frame asked.
void ExpectSameDeformation(const Shape& a, const Shape& b, const std::vector<double>& frames) {
  for (double frame : frames) {
    const std::vector<Vec3> left = DeformedVertices(a, frame), right = DeformedVertices(b, frame);
    ASSERT_EQ(left.size(), right.size());
    for (size_t v = 0; v < left.size(); ++v) {
      EXPECT_EQ(std::memcmp(&left[v], &right[v], sizeof(Vec3)), 0) << "vertex " << v << " frame " << frame;
    }
  }
}

TEST(GltfSkinWeightsTest, SumsCloseToOneAreDividedWithoutAWord) {
  // Vertex 2's weights sum to 1.01: rounding, divided by their sum, not worth a warning.
  std::vector<double> weights = kStripWeights;
  weights[9] = 0.51;
  SkinnedStrip near(weights);
  const Scene scene = near.gltf.Import();
  const Skin& skin = scene.shapes[0].deformation->skin;
  EXPECT_EQ(skin.vertexWeights[8], 0.5 / (0.5 + static_cast<double>(0.51f)));
  EXPECT_DOUBLE_EQ(skin.vertexWeights[8] + skin.vertexWeights[9], 1.0);
  EXPECT_EQ(skin.vertexWeights[12], 0.5);  // a sum of exactly 1 keeps its bits
  EXPECT_FALSE(WarningOf(scene, "weights_renormalised"));

  // Normalized unsigned bytes: 128 + 127 of 255 is 1.
  SkinnedStrip bytes;
  json& attributes = bytes.gltf.doc()["meshes"][0]["primitives"][0]["attributes"];
  attributes["WEIGHTS_0"] = bytes.gltf.Integers(
      {255, 0, 0, 0, 255, 0, 0, 0, 128, 127, 0, 0, 128, 127, 0, 0, 0, 255, 0, 0, 0, 255, 0, 0}, 5121, "VEC4", true);
  const Scene fromBytes = bytes.gltf.Import();
  EXPECT_DOUBLE_EQ(fromBytes.shapes[0].deformation->skin.vertexWeights[8], 128.0 / 255);
  EXPECT_FALSE(WarningOf(fromBytes, "weights_renormalised"));
  bytes.gltf.doc()["accessors"][attributes["WEIGHTS_0"].get<int>()].erase("normalized");
  const std::string what = ErrorOf([&] { bytes.gltf.Import(); });
  EXPECT_NE(what.find("/normalized: the gltf scene: integer weights that are not normalized"), std::string::npos)
      << what;
}

TEST(GltfSkinWeightsTest, OldExportersSumsAreDividedOutAndSaidOncePerPrimitive) {
  // Sums old exporters write: 0.685 (vertex 0), 0.237 (vertex 4), 0.898 (vertex 5).
  std::vector<double> weights = kStripWeights;
  weights[0] = 0.685;
  weights[17] = 0.237;
  weights[21] = 0.898;
  SkinnedStrip under(weights);
  const Scene scene = under.gltf.Import();
  const Skin& skin = scene.shapes[0].deformation->skin;
  // One joint each: divided by its own weight, exactly 1, so they render as weights of 1.
  EXPECT_EQ(skin.vertexWeights[0], 1.0);
  EXPECT_EQ(skin.vertexWeights[17], 1.0);
  SkinnedStrip whole;
  ExpectSameDeformation(scene.shapes[0], whole.gltf.Import().shapes[0], {0, 7.5, 24});

  std::optional<ImportWarning> warning = WarningOf(scene, "weights_renormalised");
  ASSERT_TRUE(warning);
  EXPECT_EQ(warning->pointer, "/accessors/" + std::to_string(under.weights));
  EXPECT_EQ(warning->message,
            "3 of 6 vertices have weights that do not sum to 1 (vertex 4's sum to 0.237, the furthest); each "
            "vertex's weights are divided by their sum");
}

TEST(GltfSkinWeightsTest, ASplitSumIsDividedBitForBit) {
  // Vertex 2 leans 0.4 on the hip and 0.285 on the knee: 0.685 in all.
  std::vector<double> weights = kStripWeights;
  weights[8] = 0.4;
  weights[9] = 0.285;
  SkinnedStrip split(weights);
  const Scene scene = split.gltf.Import();
  const Skin& skin = scene.shapes[0].deformation->skin;
  const double sum = static_cast<double>(0.4f) + static_cast<double>(0.285f);
  EXPECT_EQ(skin.vertexWeights[8], static_cast<double>(0.4f) / sum);
  EXPECT_EQ(skin.vertexWeights[9], static_cast<double>(0.285f) / sum);
  ASSERT_TRUE(WarningOf(scene, "weights_renormalised"));
  EXPECT_NE(WarningOf(scene, "weights_renormalised")->message.find("1 of 6 vertices"), std::string::npos);
}

TEST(GltfSkinWeightsTest, AllZeroOrNegativeWeightsAreRefused) {
  std::vector<double> weights = kStripWeights;
  weights[12] = weights[13] = 0;
  SkinnedStrip zero(weights);
  std::string what = ErrorOf([&] { zero.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(zero.weights) +
                      ": the gltf scene: vertex 3's weights are all 0; expected a positive weight on every vertex"),
            std::string::npos)
      << what;

  weights = kStripWeights;
  weights[8] = 1.5;
  weights[9] = -0.5;
  SkinnedStrip negative(weights);
  what = ErrorOf([&] { negative.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(negative.weights) +
                      ": the gltf scene: vertex 2 has the weight -0.5; expected weights >= 0"),
            std::string::npos)
      << what;
}

TEST(GltfSkinWeightsTest, JointPastTheSkinIsDroppedWhenItsWeightIsZero) {
  // Vertex 4 (on the knee alone) names joints 7 and 9 with weight 0, vertex 5 joint 3.
  SkinnedStrip strip;
  json& attributes = strip.gltf.doc()["meshes"][0]["primitives"][0]["attributes"];
  attributes["JOINTS_0"] = strip.joints = strip.gltf.Integers(
      std::vector<int>{0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 7, 9, 0, 1, 3, 0}, 5121, "VEC4");
  const Scene scene = strip.gltf.Import();
  const Skin& skin = scene.shapes[0].deformation->skin;
  EXPECT_EQ(skin.joints.size(), 2u);
  EXPECT_EQ(skin.vertexJoints[4 * 4 + 2], 0u);
  SkinnedStrip plain;
  ExpectSameDeformation(scene.shapes[0], plain.gltf.Import().shapes[0], {0, 7.5, 24});
  std::optional<ImportWarning> warning = WarningOf(scene, "joint_index_ignored");
  ASSERT_TRUE(warning);
  EXPECT_EQ(warning->pointer, "/accessors/" + std::to_string(strip.joints));
  EXPECT_EQ(warning->message,
            "3 influences of weight 0 name joints past the 2 of skin 0 (the first at vertex 4); they are ignored");

  // With a weight, the same index is refused.
  SkinnedStrip weighted;
  json& weightedAttributes = weighted.gltf.doc()["meshes"][0]["primitives"][0]["attributes"];
  weightedAttributes["JOINTS_0"] = weighted.joints = weighted.gltf.Integers(
      std::vector<int>{0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 7, 0, 0, 0, 1, 0, 0}, 5121, "VEC4");
  const std::string what = ErrorOf([&] { weighted.gltf.Import(); });
  EXPECT_NE(what.find("scene/accessors/" + std::to_string(weighted.joints) +
                      ": the gltf scene: vertex 4 names joint 7 (weight 1.0) of skin 0, which has 2"),
            std::string::npos)
      << what;
}

ImportOptions ToFrame(int lastFrame) {
  ImportOptions options;
  options.lastFrame = lastFrame;
  return options;
}

TEST(GltfSkinWeightsTest, FramesPastTheAnimationHoldItsLastKey) {
  SkinnedStrip strip;  // the knee turns over frames 0 to 24
  const Scene own = strip.gltf.Import(ToFrame(24));
  EXPECT_EQ(own.render.frameCount, 25);
  EXPECT_FALSE(WarningOf(own, "frames_past_animation"));

  const Scene longer = strip.gltf.Import(ToFrame(40));
  EXPECT_EQ(longer.render.firstFrame, 0);
  EXPECT_EQ(longer.render.frameCount, 41);
  std::optional<ImportWarning> warning = WarningOf(longer, "frames_past_animation");
  ASSERT_TRUE(warning);
  EXPECT_EQ(warning->pointer, "/animations/0");
  EXPECT_EQ(warning->message, "frames 25-40 hold the last key (the animation ends at frame 24)");
  // Frame 40 is frame 24 again, and the scene reads back with its longer range.
  const std::vector<Vec3> last = DeformedVertices(longer.shapes[0], 24), past = DeformedVertices(longer.shapes[0], 40);
  ASSERT_EQ(last.size(), past.size());
  for (size_t v = 0; v < last.size(); ++v) EXPECT_EQ(std::memcmp(&last[v], &past[v], sizeof(Vec3)), 0);
  EXPECT_EQ(ParseScene(SerializeScene(longer)).render.frameCount, 41);

  EXPECT_EQ(WarningOf(strip.gltf.Import(ToFrame(25)), "frames_past_animation")->message,
            "frame 25 holds the last key (the animation ends at frame 24)");
  const std::string what = ErrorOf([&] { strip.gltf.Import(ToFrame(scene_limits::kMaxFrameCount)); });
  EXPECT_NE(what.find("frames up to 100000 asked for; expected at most 100000 frames"), std::string::npos) << what;
}

TEST(GltfSkinWeightsTest, AStillFileAskedForFramesShowsItsOneFrame) {
  GltfBuilder still;
  still.Node({{"mesh", still.Mesh({0, 0, 0, 1, 0, 0, 0, 1, 0})}}, true);
  const Scene scene = still.Import(ToFrame(3));
  EXPECT_EQ(scene.render.frameCount, 4);
  std::optional<ImportWarning> warning = WarningOf(scene, "frames_past_animation");
  ASSERT_TRUE(warning);
  EXPECT_EQ(warning->pointer, "");
  EXPECT_EQ(warning->message, "the file has no animation: frames 1-3 show it as frame 0 does");
}

}  // namespace
}  // namespace tcfarm
