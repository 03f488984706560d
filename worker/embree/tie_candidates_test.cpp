#include "embree/tie_candidates.h"

#include <gtest/gtest.h>

#include <string>

namespace tcfarm {
namespace {

Scene WithShapes(const std::string& shapes) {
  return ParseScene(R"({"camera": {"position": [0, 2, 8], "look_at": [0, 1, 0]},
    "shapes": [)" + shapes + R"(], "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 10}}})");
}

const std::string kFloor = R"({"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0]})";

TEST(TieCandidatesTest, ThePapersScenesNeedNoTieRule) {
  for (const char* name : {"paper_a_one_sphere", "paper_b_twelve_spheres", "paper_c_terrain_flyover"}) {
    EXPECT_FALSE(SceneMayTie(LoadSceneFile(std::string("tests/scenes/") + name + ".json"))) << name;
  }
}

TEST(TieCandidatesTest, SurfacesThatMayCoincideOverAnAreaNeedIt) {
  // A still quad on the floor, seen from either side.
  EXPECT_TRUE(SceneMayTie(WithShapes(kFloor + R"(, {"type": "quad", "corner": [-1, 0, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2]})")));
  // Any planar shape that moves may come to lie in another's plane.
  EXPECT_TRUE(SceneMayTie(WithShapes(kFloor + R"(, {"type": "quad", "corner": [-1, 1, -1], "edge_u": [2, 0, 0],
      "edge_v": [0, 1, 2], "motion": {"polynomial": [[0, 0.1], [0], [0]]}})")));
  // A face doubled inside one mesh.
  EXPECT_TRUE(SceneMayTie(WithShapes(R"({"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
      "triangles": [[0, 1, 2], [2, 1, 0]]})")));
  // Equal spheres in one place, or equal spheres one of which moves.
  EXPECT_TRUE(SceneMayTie(WithShapes(R"({"type": "sphere", "center": [0, 1, 0], "radius": 1},
      {"type": "sphere", "center": [0, 1, 0], "radius": 1})")));
  EXPECT_TRUE(SceneMayTie(WithShapes(R"({"type": "sphere", "center": [0, 1, 0], "radius": 1},
      {"type": "sphere", "center": [3, 1, 0], "radius": 1, "motion": {"polynomial": [[0, -0.5], [0], [0]]}})")));
  // A still quad held by a constant transform in the floor's plane.
  // (A quad in the plane z = 0, turned a quarter about x into y = 0.)
  EXPECT_TRUE(SceneMayTie(WithShapes(kFloor + R"(, {"type": "quad", "corner": [-1, 0, 0], "edge_u": [2, 0, 0],
      "edge_v": [0, 2, 0], "motion": {"rotation": [0.7071067811865476, 0, 0, 0.7071067811865476]}})")));
}

TEST(TieCandidatesTest, SurfacesApartNeedNone) {
  EXPECT_FALSE(SceneMayTie(WithShapes(kFloor + R"(, {"type": "quad", "corner": [-1, 0.001, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2]})")));
  EXPECT_FALSE(SceneMayTie(WithShapes(kFloor + R"(, {"type": "sphere", "center": [0, 1, 0], "radius": 1,
      "motion": {"polynomial": [[0], [0, 0.1], [0]]}})")));
  EXPECT_FALSE(SceneMayTie(WithShapes(R"({"type": "sphere", "center": [0, 1, 0], "radius": 1},
      {"type": "sphere", "center": [3, 1, 0], "radius": 0.5, "motion": {"polynomial": [[0, -0.5], [0], [0]]}})")));
}

}  // namespace
}  // namespace tcfarm
