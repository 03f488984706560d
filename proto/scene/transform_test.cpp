#include "proto/scene/transform.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>
#include <string>

#include "proto/scene/scene.h"

namespace tcfarm {
namespace {

using nlohmann::json;

void ExpectNear(const Vec3& a, const Vec3& b, double tolerance = 1e-12) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

TEST(TransformTest, QuarterTurnAboutYCarriesXOntoMinusZ) {
  Motion motion;
  motion.rotation = AnimatedRotation::Constant(Quaternion::FromAxisAngle({0, 1, 0}, 90));
  ExpectNear(motion.WorldFromObject(0).Apply({1, 0, 0}), {0, 0, -1});
}

TEST(TransformTest, QuaternionsOfAnyLengthTurnAlike) {
  Motion unit, scaled;
  unit.rotation = AnimatedRotation::Constant({std::sqrt(0.5), 0, std::sqrt(0.5), 0});
  scaled.rotation = AnimatedRotation::Constant({3, 0, 3, 0});
  ExpectNear(unit.WorldFromObject(0).Apply({1, 2, 3}), scaled.WorldFromObject(0).Apply({1, 2, 3}));
}

TEST(TransformTest, ThePivotStaysWhereItIs) {
  Motion motion;
  motion.pivot = {2, -1, 5};
  motion.rotation = AnimatedRotation::Spin({1, 1, 0}, 17);
  motion.scale = AnimatedVec3::Constant({2, 3, 0.5});
  for (int frame : {0, 3, 11}) ExpectNear(motion.WorldFromObject(frame).Apply({2, -1, 5}), {2, -1, 5}, 1e-12);
}

TEST(TransformTest, ScaleThenRotateThenTranslate) {
  Motion motion;
  motion.translation = AnimatedVec3::Constant({10, 0, 0});
  motion.rotation = AnimatedRotation::Constant(Quaternion::FromAxisAngle({0, 0, 1}, 90));
  motion.scale = AnimatedVec3::Constant({2, 1, 1});
  // (1,0,0) scaled to (2,0,0), turned to (0,2,0), moved to (10,2,0).
  ExpectNear(motion.WorldFromObject(0).Apply({1, 0, 0}), {10, 2, 0});
  EXPECT_NEAR(motion.WorldFromObject(0).MaxStretch(), 2, 1e-12);
}

TEST(TransformTest, TranslationAloneIsExactlyTheOldMotion) {
  Motion motion;
  motion.translation = AnimatedVec3::Polynomial({std::vector<double>{0.1, 0.3}, {0}, {0, 0, 0.01}});
  ASSERT_TRUE(motion.IsTranslationOnly());
  const Affine placed = motion.WorldFromObject(7);
  EXPECT_EQ(placed.offset, motion.translation.Evaluate(7));
  EXPECT_EQ(placed.Apply({1, 2, 3}), (Vec3{1 + placed.offset.x, 2 + placed.offset.y, 3 + placed.offset.z}));
}

TEST(TransformTest, SlerpMeetsItsKeysAndTakesTheShortWay) {
  const Quaternion a = Quaternion::FromAxisAngle({0, 1, 0}, 10);
  const Quaternion b = Quaternion::FromAxisAngle({0, 1, 0}, 350);  // -10 degrees, long way round as given
  AnimatedRotation rotation = AnimatedRotation::Keyframes({{0, a}, {10, b}});
  EXPECT_EQ(rotation.Evaluate(0), a);
  Motion motion;
  motion.rotation = rotation;
  // Halfway along the short arc is no turn at all.
  ExpectNear(motion.WorldFromObject(5).Apply({1, 0, 0}), {1, 0, 0}, 1e-12);
  Motion atB;
  atB.rotation = AnimatedRotation::Constant(b);
  ExpectNear(motion.WorldFromObject(10).Apply({1, 0, 0}), atB.WorldFromObject(0).Apply({1, 0, 0}));
}

TEST(TransformTest, HeldKeysKeepTheirBits) {
  const Quaternion held = Quaternion::FromAxisAngle({1, 2, 3}, 33);
  AnimatedRotation rotation = AnimatedRotation::Keyframes({{0, held}, {4, held}, {8, Quaternion{}}});
  for (double frame : {0.0, 1.0, 2.5, 4.0}) EXPECT_EQ(rotation.Evaluate(frame), held);
  EXPECT_TRUE(rotation.IsAnimated());
}

TEST(TransformTest, StepHoldsEachKeyUntilTheNext) {
  AnimatedVec3 steps = AnimatedVec3::Keyframes({{0, {0, 0, 0}}, {4, {1, 2, 3}}}, Interpolation::kStep);
  EXPECT_EQ(steps.Evaluate(3.99), (Vec3{0, 0, 0}));
  EXPECT_EQ(steps.Evaluate(4), (Vec3{1, 2, 3}));
  AnimatedRotation turns = AnimatedRotation::Keyframes(
      {{0, Quaternion{}}, {4, Quaternion::FromAxisAngle({0, 1, 0}, 90)}}, Interpolation::kStep);
  EXPECT_EQ(turns.Evaluate(2), Quaternion{});
}

TEST(TransformTest, CubicSplinesFollowHermiteWithTangentsPerFrame) {
  // From 0 to 1 over 4 frames, leaving with slope 1 per frame, arriving flat.
  AnimatedVec3 curve = AnimatedVec3::Keyframes(
      {{0, {0, 0, 0}, {}, {1, 0, 0}}, {4, {1, 0, 0}, {0, 0, 0}, {}}}, Interpolation::kCubicSpline);
  const double t = 0.25;  // frame 1
  const double expected = (t * t * t - 2 * t * t + t) * 4 * 1 + (-2 * t * t * t + 3 * t * t) * 1;
  EXPECT_NEAR(curve.Evaluate(1).x, expected, 1e-15);
  EXPECT_EQ(curve.Evaluate(4).x, 1);
  EXPECT_EQ(curve.Evaluate(0).x, 0);
  // Equal keys with a slope still move between them.
  EXPECT_TRUE(AnimatedVec3::Keyframes({{0, {}, {}, {0, 1, 0}}, {4, {}, {}, {}}}, Interpolation::kCubicSpline).IsAnimated());
  EXPECT_FALSE(AnimatedVec3::Keyframes({{0, {}}, {4, {}}}, Interpolation::kCubicSpline).IsAnimated());
}

TEST(TransformTest, ACubicSplineRotationStaysARotation) {
  AnimatedRotation rotation = AnimatedRotation::Keyframes(
      {{0, Quaternion{}, {0, 0, 0, 0}, {0, 0, 0.1, 0}}, {8, Quaternion::FromAxisAngle({0, 1, 0}, 120), {0, 0, 0, 0}, {0, 0, 0, 0}}},
      Interpolation::kCubicSpline);
  Motion motion;
  motion.rotation = rotation;
  for (double frame : {1.0, 3.5, 7.0}) {
    const Vec3 p = motion.WorldFromObject(frame).Apply({1, 0, 0});
    EXPECT_NEAR(p.x * p.x + p.y * p.y + p.z * p.z, 1, 1e-12) << frame;
  }
}

TEST(TransformTest, AChildIsCarriedByItsParents) {
  // A parent spinning about y at the origin carries a child 2 along x, itself turning and
  // moving up.
  auto parent = std::make_shared<Motion>();
  parent->rotation = AnimatedRotation::Spin({0, 1, 0}, 90);
  auto grand = std::make_shared<Motion>();
  grand->translation = AnimatedVec3::Constant({0, 0, 10});
  parent->parent = grand;
  Motion child;
  child.translation = AnimatedVec3::Polynomial({std::vector<double>{2}, {0, 1}, {0}});
  child.rotation = AnimatedRotation::Spin({1, 0, 0}, 45);
  child.parent = parent;
  EXPECT_TRUE(child.IsAnimated());
  EXPECT_FALSE(child.IsTranslationOnly());
  // Frame 1: the child's origin at (2, 1, 0) locally, turned 90 degrees about y: (0, 1, -2), then moved by 10 in z.
  ExpectNear(child.WorldFromObject(1).Apply({0, 0, 0}), {0, 1, 8});
  Motion still;
  still.parent = grand;
  EXPECT_FALSE(still.IsTranslationOnly());  // carried by a parent that is not the world
  ExpectNear(still.WorldFromObject(3).Apply({1, 1, 1}), {1, 1, 11});
}

std::string SceneWithMotion(const std::string& motion, const std::string& where = "shape") {
  const std::string shapeMotion = where == "shape" ? ", \"motion\": " + motion : "";
  const std::string cameraMotion = where == "camera" ? ", \"motion\": " + motion : "";
  const std::string lightMotion = where == "light" ? ", \"motion\": " + motion : "";
  return R"({"camera": {"position": [0, 0, 10], "look_at": [0, 0, 0])" + cameraMotion + R"(},
    "lights": [{"type": "point", "position": [3, 4, 5], "intensity": [50, 50, 50])" + lightMotion + R"(}],
    "shapes": [{"type": "quad", "corner": [-1, -1, 0], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0])" +
         shapeMotion + R"(}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 10}}})";
}

TEST(TransformSceneTest, ShapesTurnAndGrowAboutTheirPivot) {
  Scene scene = ParseScene(SceneWithMotion(
      R"({"rotation": {"axis": [0, 0, 1], "degrees_per_frame": 9}, "scale": {"keyframes": [
           {"frame": 0, "value": [1, 1, 1]}, {"frame": 9, "value": [2, 2, 2]}]}, "pivot": [0, 0, 0]})"));
  const Motion& motion = scene.shapes[0].motion;
  EXPECT_TRUE(scene.shapes[0].Moves());
  EXPECT_FALSE(motion.IsTranslationOnly());
  // At frame 9: 81 degrees about z, twice the size.
  Vec3 corner = motion.WorldFromObject(9).Apply({1, 0, 0});
  ExpectNear(corner, {2 * std::cos(81 * M_PI / 180), 2 * std::sin(81 * M_PI / 180), 0});
}

TEST(TransformSceneTest, RotationsAsQuaternionsAndKeyframes) {
  Scene scene = ParseScene(SceneWithMotion(
      R"({"rotation": {"keyframes": [{"frame": 0, "value": [0, 0, 0, 1]},
                                     {"frame": 9, "value": [0, 0.7071067811865476, 0, 0.7071067811865476]}]}})"));
  ExpectNear(scene.shapes[0].motion.WorldFromObject(9).Apply({1, 0, 0}), {0, 0, -1});
  Scene still = ParseScene(SceneWithMotion(R"({"rotation": [0, 0, 0, 1]})"));
  EXPECT_FALSE(still.shapes[0].Moves());
}

TEST(TransformSceneTest, CameraRigsAndLightsMoveToo) {
  Scene orbit = ParseScene(SceneWithMotion(R"({"rotation": {"axis": [0, 1, 0], "degrees_per_frame": 10}})", "camera"));
  EXPECT_TRUE(orbit.CameraMoves());
  ExpectNear(orbit.camera.At(9).position, {10 * std::sin(90 * M_PI / 180), 0, 10 * std::cos(90 * M_PI / 180)}, 1e-9);
  EXPECT_EQ(orbit.camera.At(9).lookAt, (Vec3{0, 0, 0}));
  Scene swing = ParseScene(SceneWithMotion(R"({"translation": {"polynomial": [[0, 1], [0], [0]]}})", "light"));
  EXPECT_TRUE(swing.AnyLightChanges());
  EXPECT_EQ(swing.lights[0].PositionAt(4), (Vec3{7, 4, 5}));
  EXPECT_FALSE(swing.lights[0].SameAt(1, 2));
}

TEST(TransformSceneTest, WrittenOutAndReadBackBitForBit) {
  const std::string text = SceneWithMotion(
      R"({"translation": [0.1, 0.2, 0.3], "rotation": {"keyframes": [{"frame": 0, "value": [0.1, 0.2, 0.3, 0.9]},
           {"frame": 7, "value": [0.3, -0.2, 0.1, 0.5]}]}, "scale": [1, 2, -0.5], "pivot": [0.25, 0, 1]})");
  Scene scene = ParseScene(text);
  std::string written = SerializeScene(scene);
  Scene reread = ParseScene(written);
  EXPECT_EQ(SerializeScene(reread), written);
  for (int frame : {0, 3, 7}) {
    EXPECT_EQ(reread.shapes[0].motion.WorldFromObject(frame), scene.shapes[0].motion.WorldFromObject(frame));
  }
  // Translation alone is written as it always was.
  Scene plain = ParseScene(SceneWithMotion(R"({"polynomial": [[0, 1], [0], [0]]})"));
  EXPECT_NE(SerializeScene(plain).find(R"("motion":{"polynomial")"), std::string::npos);
}

TEST(TransformSceneTest, InterpolationsTangentsAndParentsAreWrittenOutAndReadBack) {
  const std::string text = SceneWithMotion(R"({"translation": {"interpolation": "cubicspline", "keyframes": [
        {"frame": 0, "value": [0, 0, 0], "in_tangent": [0, 0, 0], "out_tangent": [0.5, 0, 0]},
        {"frame": 9, "value": [1, 1, 0], "in_tangent": [0, -0.2, 0], "out_tangent": [0, 0, 0]}]},
      "rotation": {"interpolation": "step", "keyframes": [{"frame": 0, "value": [0, 0, 0, 1]}, {"frame": 5, "value": [0, 1, 0, 0]}]},
      "parent": {"rotation": {"axis": [0, 1, 0], "degrees_per_frame": 10}, "parent": {"translation": [0, 0, -3]}}})");
  Scene scene = ParseScene(text);
  const Motion& motion = scene.shapes[0].motion;
  ASSERT_TRUE(motion.parent);
  ASSERT_TRUE(motion.parent->parent);
  EXPECT_EQ(motion.translation.interpolation(), Interpolation::kCubicSpline);
  EXPECT_EQ(motion.rotation.interpolation(), Interpolation::kStep);
  const std::string written = SerializeScene(scene);
  Scene reread = ParseScene(written);
  EXPECT_EQ(SerializeScene(reread), written);
  for (int frame : {0, 2, 5, 9}) {
    EXPECT_EQ(reread.shapes[0].motion.WorldFromObject(frame), motion.WorldFromObject(frame)) << frame;
  }
}

// A skeleton of two levels in "transforms", carrying two shapes: the same worlds as the
// chain written inline in each, and written back once.
std::string SceneWithNamedParents(const std::string& transforms, const std::string& firstParent = "\"knee\"") {
  return R"({"camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
    "transforms": )" + transforms + R"(,
    "shapes": [{"type": "sphere", "center": [0, 1, 0], "radius": 0.2,
                "motion": {"rotation": {"axis": [1, 0, 0], "degrees_per_frame": 4}, "parent": )" + firstParent + R"(}},
               {"type": "sphere", "center": [0, -1, 0], "radius": 0.2,
                "motion": {"translation": [0, 0.5, 0], "parent": )" + firstParent + R"(}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 10}}})";
}

const char kSkeleton[] = R"({"hip": {"translation": {"polynomial": [[0, 0.1], [0], [0]]}},
    "knee": {"rotation": {"axis": [0, 0, 1], "degrees_per_frame": 9}, "parent": "hip"}})";

TEST(TransformSceneTest, NamedParentsAreSharedAndWrittenOnce) {
  Scene scene = ParseScene(SceneWithNamedParents(kSkeleton));
  ASSERT_TRUE(scene.shapes[0].motion.parent);
  EXPECT_EQ(scene.shapes[0].motion.parent, scene.shapes[1].motion.parent);  // one knee, shared
  Scene inline_ = ParseScene(SceneWithNamedParents(
      "{}", R"({"rotation": {"axis": [0, 0, 1], "degrees_per_frame": 9},
                "parent": {"translation": {"polynomial": [[0, 0.1], [0], [0]]}}})"));
  for (int frame : {0, 3, 9}) {
    EXPECT_EQ(scene.shapes[0].motion.WorldFromObject(frame), inline_.shapes[0].motion.WorldFromObject(frame)) << frame;
  }
  // Written back: the shared knee once, in "transforms", named by both; the hip it alone
  // carries stays inline in it. A parent of one transform is written inline.
  const json written = json::parse(SerializeScene(scene));
  ASSERT_TRUE(written.contains("transforms"));
  EXPECT_EQ(written["transforms"].size(), 1u);
  const std::string name = written["shapes"][0]["motion"]["parent"].get<std::string>();
  EXPECT_EQ(written["shapes"][1]["motion"]["parent"], name);
  EXPECT_TRUE(written["transforms"][name]["parent"].is_object());
  EXPECT_FALSE(json::parse(SerializeScene(inline_)).contains("transforms"));
  Scene reread = ParseScene(written.dump());
  EXPECT_EQ(SerializeScene(reread), written.dump());
  for (int frame : {0, 3, 9}) {
    EXPECT_EQ(reread.shapes[1].motion.WorldFromObject(frame), scene.shapes[1].motion.WorldFromObject(frame));
  }
}

TEST(TransformSceneTest, BadNamedParentsAreRefusedWithTheirPointer) {
  const std::pair<std::string, std::string> cases[] = {
      {SceneWithNamedParents(kSkeleton, R"("ankle")"), "/shapes/0/motion/parent"},
      {SceneWithNamedParents(R"({"knee": {"rotation": [0, 0, 0, 1], "parent": "hip"},
                                 "hip": {"rotation": [0, 0, 0, 1], "parent": "knee"}})"),
       "/transforms/knee/parent"},  // read in name order: hip, then its parent knee
      {SceneWithNamedParents(R"({"knee": {"rotation": [0, 0, 0, 1]}, "spare": {"scale": [0, 1, 1]}})"),
       "/transforms/spare/scale"},
      {SceneWithNamedParents(R"({"knee": [1, 2, 3]})"), "/transforms/knee"},
      {SceneWithNamedParents(R"([])"), "/transforms"},
  };
  for (const auto& [text, pointer] : cases) {
    try {
      ParseScene(text);
      ADD_FAILURE() << text << " was accepted";
    } catch (const SceneError& error) {
      EXPECT_EQ(error.pointer(), pointer) << error.what();
    }
  }
  // 40 levels, each naming the one above, are deeper than a hierarchy may be; 20,000 are
  // refused as well, before they run the parser out of stack.
  for (int levels : {40, 20000}) {
    std::string chain = R"({"l0": {"translation": [0, 0, 1]})";
    for (int level = 1; level < levels; ++level) {
      chain += ", \"l" + std::to_string(level) + R"(": {"translation": [0, 0, 1], "parent": "l)" +
               std::to_string(level - 1) + "\"}";
    }
    chain += R"(, "knee": {"rotation": [0, 0, 0, 1], "parent": "l)" + std::to_string(levels - 1) + "\"}}";
    try {
      ParseScene(SceneWithNamedParents(chain));
      ADD_FAILURE() << levels << " levels were accepted";
    } catch (const SceneError& error) {
      EXPECT_NE(std::string(error.what()).find("deeper than 32 levels"), std::string::npos) << error.what();
    }
  }
}

TEST(TransformSceneTest, BadMotionIsRefusedWithItsPointer) {
  const std::pair<std::string, std::string> cases[] = {
      {R"({"rotation": [0, 0, 0, 0]})", "/shapes/0/motion/rotation"},
      {R"({"rotation": [0, 0, 1]})", "/shapes/0/motion/rotation"},
      {R"({"rotation": {"axis": [0, 0, 0], "degrees_per_frame": 3}})", "/shapes/0/motion/rotation/axis"},
      {R"({"rotation": {"axis": [0, 1, 0]}})", "/shapes/0/motion/rotation/degrees_per_frame"},
      {R"({"scale": [1, 0, 1]})", "/shapes/0/motion/scale"},
      {R"({"scale": {"polynomial": [[1, -0.25], [1], [1]]}})", "/shapes/0/motion/scale"},
      {R"({"translation": [0, 0, 0], "spin": 3})", "/shapes/0/motion/spin"},
      {R"({"rotation": {"keyframes": [{"frame": 2, "value": [0, 0, 0, 1]}, {"frame": 2, "value": [0, 1, 0, 0]}]}})",
       "/shapes/0/motion/rotation/keyframes/1/frame"},
      {R"("spin")", "/shapes/0/motion"},
      {R"({"translation": {"interpolation": "smooth", "keyframes": [{"frame": 0, "value": [0, 0, 0]}]}})",
       "/shapes/0/motion/translation/interpolation"},
      {R"({"translation": {"keyframes": [{"frame": 0, "value": [0, 0, 0], "in_tangent": [0, 0, 0]}]}})",
       "/shapes/0/motion/translation/keyframes/0/in_tangent"},
      {R"({"translation": {"polynomial": [[0], [0], [0]], "interpolation": "step"}})",
       "/shapes/0/motion/translation/interpolation"},
      {R"({"rotation": [0, 0, 0, 1], "parent": [1, 2, 3]})", "/shapes/0/motion/parent"},
  };
  for (const auto& [motion, pointer] : cases) {
    try {
      ParseScene(SceneWithMotion(motion));
      ADD_FAILURE() << motion << " was accepted";
    } catch (const SceneError& error) {
      EXPECT_EQ(error.pointer(), pointer) << motion << ": " << error.what();
    }
  }
}

}  // namespace
}  // namespace tcfarm
