#include "proto/scene/deformation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "proto/scene/scene.h"
#include "tests/support/cpp/skinned_tube.h"

namespace tcfarm {
namespace {

// Two vertices on a bar bound to two joints: the first held by joint 0 (still), the second
// by joint 1, which turns 90 degrees about z from frame 0 to frame 10 about the point
// (1, 0, 0); a third vertex blends the two halves.
std::string BarScene(const std::string& skinExtra = "",
                     const std::string& weights = "[[1, 0, 0, 0], [0, 1, 0, 0], [0.5, 0.5, 0, 0]]") {
  return R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "shapes": [{"type": "mesh", "vertices": [[0, 0, 0], [2, 0, 0], [1, 1, 0]], "triangles": [[0, 1, 2]],
      "skin": {"joints": [[0, 0, 0], {"translation": [1, 0, 0], "rotation": {"keyframes": [
                 {"frame": 0, "value": [0, 0, 0, 1]}, {"frame": 10, "value": [0, 0, 0.7071067811865476, 0.7071067811865476]}]}}],
               "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], [1, 0, 0, -1, 0, 1, 0, 0, 0, 0, 1, 0]],
               "vertex_joints": [[0, 1, 0, 0], [0, 1, 0, 0], [0, 1, 0, 0]],
               "vertex_weights": )" + weights + skinExtra + R"(}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 11}}})";
}

TEST(DeformationTest, SkinsByTheBlendedJointMatrices) {
  Scene scene = ParseScene(BarScene());
  ASSERT_TRUE(scene.shapes[0].Deforms());
  const Deformation& deformation = *scene.shapes[0].deformation;
  DeformedVertices rest = Deform(scene.shapes[0].Mesh(), deformation, 0);
  EXPECT_NEAR(rest.positions[1].x, 2, 1e-12);
  DeformedVertices bent = Deform(scene.shapes[0].Mesh(), deformation, 10);
  // Joint 1 turned 90 degrees about (1, 0, 0): (2, 0, 0) goes to (1, 1, 0).
  EXPECT_NEAR(bent.positions[1].x, 1, 1e-12);
  EXPECT_NEAR(bent.positions[1].y, 1, 1e-12);
  EXPECT_EQ(bent.positions[0].x, 0);  // held by the still joint: not moved at all
  // Half of each: (1, 1, 0) under joint 0 stays, under joint 1 goes to (0, 0, 0).
  EXPECT_NEAR(bent.positions[2].x, 0.5, 1e-12);
  EXPECT_NEAR(bent.positions[2].y, 0.5, 1e-12);
}

TEST(DeformationTest, MorphsByTheWeightsOfTheFrame) {
  Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "shapes": [{"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]],
                "normals": [[0, 0, 1], [0, 0, 1], [0, 0, 1]],
                "morph": {"targets": [{"positions": [[0, 0, 1], [0, 0, 0], [0, 0, 0]], "normals": [[1, 0, 0], [0, 0, 0], [0, 0, 0]]},
                                      {"positions": [[0, 0, 0], [0, 2, 0], [0, 0, 0]]}],
                          "weights": {"interpolation": "step", "keyframes": [{"frame": 0, "value": [0, 0]},
                                                                            {"frame": 5, "value": [0.5, 1]}]}}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 10}}})");
  const Shape& shape = scene.shapes[0];
  ASSERT_TRUE(shape.Deforms());
  DeformedVertices before = Deform(shape.Mesh(), *shape.deformation, 4);
  EXPECT_EQ(before.positions, shape.Mesh().vertices);  // zero weights leave every bit
  DeformedVertices after = Deform(shape.Mesh(), *shape.deformation, 5);
  EXPECT_EQ(after.positions[0].z, 0.5);
  EXPECT_EQ(after.positions[1].y, 2);
  EXPECT_EQ(after.normals[0].x, 0.5);
  EXPECT_TRUE(shape.deformation->SameAt(5, 9));
  EXPECT_FALSE(shape.deformation->SameAt(4, 5));
}

TEST(DeformationTest, JsonRoundTripKeepsEveryBit) {
  Scene scene = ParseScene(BarScene());
  const std::string text = SerializeScene(scene);
  EXPECT_EQ(SerializeScene(ParseScene(text)), text);
  Scene again = ParseScene(text);
  for (int frame : {0, 3, 7, 10}) {
    EXPECT_EQ(Deform(again.shapes[0].Mesh(), *again.shapes[0].deformation, frame).positions,
              Deform(scene.shapes[0].Mesh(), *scene.shapes[0].deformation, frame).positions);
  }
}

TEST(DeformationTest, RebasingMovesSkinnedVerticesWithTheWorld) {
  Scene scene = ParseScene(BarScene());
  Scene moved = scene;
  TranslateScene(moved, {10, -3, 2});
  for (int frame : {0, 10}) {
    DeformedVertices a = Deform(scene.shapes[0].Mesh(), *scene.shapes[0].deformation, frame);
    DeformedVertices b = Deform(moved.shapes[0].Mesh(), *moved.shapes[0].deformation, frame);
    for (size_t v = 0; v < a.positions.size(); ++v) {
      EXPECT_NEAR(b.positions[v].x, a.positions[v].x + 10, 1e-12);
      EXPECT_NEAR(b.positions[v].y, a.positions[v].y - 3, 1e-12);
      EXPECT_NEAR(b.positions[v].z, a.positions[v].z + 2, 1e-12);
    }
  }
}

// A square tube along x from 0 to 4 (41 rings, 320 triangles), every vertex on one
// joint, which slides it down y from frame 1 on.
std::string LongTube() {
  const test::TubeJson tube = test::SquareTube(40, 0, 0.1, -0.1, 0.1, -0.1, 0.1, test::OnJointZero);
  return R"({"camera": {"position": [2, 0, 6], "look_at": [2, 0, 0]},
    "shapes": [{"type": "mesh", "vertices": [)" + tube.vertices + R"(], "triangles": [)" + tube.triangles + R"(],
      "skin": {"joints": [{"translation": {"keyframes": [{"frame": 0, "value": [0, 0, 0]}, {"frame": 1, "value": [0, 0, 0]},
                                                          {"frame": 9, "value": [0, -0.4, 0]}]}}],
               "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]],
               "vertex_joints": [)" + tube.joints + R"(], "vertex_weights": [)" + tube.weights + R"(]}}],
    "render": {"width": 32, "height": 24, "frames": {"start": 0, "count": 10}}})";
}

// A part is cut across its length into pieces, and every triangle it moves lies within
// one piece: the pieces' bounds hold the part with a tube's thickness around it, where
// the part's own sphere reaches half its length.
TEST(DeformationTest, APartIsCutIntoPiecesThatEachHoldWholeTriangles) {
  const Scene scene = ParseScene(LongTube());
  const TriangleMesh& mesh = scene.shapes[0].Mesh();
  const DeformationParts parts = SplitIntoParts(mesh, *scene.shapes[0].deformation);
  ASSERT_EQ(parts.groups.size(), 1u);
  const DeformationParts::Group& tube = parts.groups[0];
  EXPECT_EQ(tube.reach.size(), mesh.vertices.size());
  ASSERT_EQ(tube.pieces.size(), 4u);
  for (const std::vector<uint32_t>& piece : tube.pieces) {
    ASSERT_TRUE(std::is_sorted(piece.begin(), piece.end()));
    double lo = INFINITY, hi = -INFINITY;
    for (uint32_t v : piece) lo = std::min(lo, mesh.vertices[v].x), hi = std::max(hi, mesh.vertices[v].x);
    EXPECT_LE(hi - lo, 1.0 + 1e-9) << "a piece from x " << lo << " to " << hi;
  }
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const bool held = std::any_of(tube.pieces.begin(), tube.pieces.end(), [&](const std::vector<uint32_t>& piece) {
      return std::all_of(mesh.triangles[t].begin(), mesh.triangles[t].end(),
                         [&](uint32_t v) { return std::binary_search(piece.begin(), piece.end(), v); });
    });
    EXPECT_TRUE(held) << "triangle " << t << " is in no piece whole";
  }
}

TEST(DeformationTest, AStillSkinIsBakedIntoARigidMesh) {
  Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "shapes": [{"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]],
      "skin": {"joints": [{"translation": [0, 3, 0]}], "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]],
               "vertex_joints": [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]],
               "vertex_weights": [[1, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]]}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 4}}})");
  EXPECT_FALSE(scene.shapes[0].Moves());
  PlaceStillShapes(scene);
  EXPECT_EQ(scene.shapes[0].deformation, nullptr);
  EXPECT_EQ(scene.shapes[0].mesh.vertices[2].y, 4);
}

void ExpectRefused(const std::string& json, const std::string& pointer, const std::string& words) {
  try {
    ParseScene(json);
    ADD_FAILURE() << "accepted a scene with " << words;
  } catch (const SceneError& error) {
    EXPECT_EQ(error.pointer(), pointer) << error.what();
    EXPECT_NE(std::string(error.what()).find(words), std::string::npos) << error.what();
  }
}

TEST(DeformationTest, BadSkinsAndMorphsAreRefusedWithTheirPointer) {
  ExpectRefused(BarScene("", "[[1, 0, 0, 0], [0, 1, 0, 0], [0.3, 0.3, 0, 0]]"), "/shapes/0/skin/vertex_weights/2",
                "summing to 0.6");
  ExpectRefused(BarScene("", "[[1, 0, 0, 0], [0, 1, 0, 0]]"), "/shapes/0/skin/vertex_weights", "8 weights");
  ExpectRefused(BarScene(R"(, "offset": [1, 2])"), "/shapes/0/skin/offset", "");
  std::string outOfRange = BarScene();
  const std::string joints = "[[0, 1, 0, 0], [0, 1, 0, 0], [0, 1, 0, 0]]";
  outOfRange.replace(outOfRange.find(joints), joints.size(), "[[0, 1, 0, 0], [0, 7, 0, 0], [0, 1, 0, 0]]");
  ExpectRefused(outOfRange, "/shapes/0/skin/vertex_joints/1", "joint index 7");
  ExpectRefused(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "shapes": [{"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]],
                "morph": {"targets": [{"positions": [[0, 0, 1], [0, 0, 0]]}], "weights": [1]}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 2}}})",
                "/shapes/0/morph/targets/0/positions", "2 position deltas");
  ExpectRefused(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "shapes": [{"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]],
                "morph": {"targets": [{"positions": [[0, 0, 1], [0, 0, 0], [0, 0, 0]]}], "weights": [1, 2]}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 2}}})",
                "/shapes/0/morph/weights", "1 weights");
}

}  // namespace
}  // namespace tcfarm
