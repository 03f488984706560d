#include "worker/embree/tie_candidates.h"

#include "worker/shapes/shape_kind.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

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

// What the plane test takes from each kind: a curved one gives no faces, a flat one a face
// per primitive (a quad's one, a mesh's or terrain's triangles).
TEST(TieCandidatesTest, EachKindSaysWhetherItIsFlatAndGivesItsFaces) {
  const Scene scene = WithShapes(R"({"type": "sphere", "center": [0, 1, 0], "radius": 1},
      {"type": "quad", "corner": [1, 0, 0], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2]},
      {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2], [2, 1, 0]]},
      {"type": "terrain", "origin": [0, 0, 0], "size": [4, 4], "cells": [3, 2]})");
  const bool planar[] = {false, true, true, true};
  const size_t faces[] = {0, 1, 2, 12};
  for (size_t i = 0; i < scene.shapes.size(); ++i) {
    const Shape& shape = scene.shapes[i];
    EXPECT_EQ(KindOf(shape).Planar(), planar[i]) << i;
    size_t count = 0;
    KindOf(shape).ForEachFace(shape, [&](const Vec3&, const Vec3&, const Vec3&) { ++count; });
    EXPECT_EQ(count, faces[i]) << i;
  }
  std::vector<Vec3> quadFace;
  KindOf(scene.shapes[1]).ForEachFace(scene.shapes[1], [&](const Vec3& a, const Vec3& b, const Vec3& c) {
    quadFace = {a, b, c};
  });
  EXPECT_EQ(quadFace, (std::vector<Vec3>{{1, 0, 0}, {3, 0, 0}, {1, 0, 2}}));
}

// The definition SpheresMayMeet answers, pair by pair: the way it was computed before the
// sweep, kept here as the reference.
bool SpheresMayMeetPairwise(const Scene& scene) {
  std::vector<const Shape*> spheres;
  for (const Shape& shape : scene.shapes) {
    if (shape.type != Shape::Type::kSphere) continue;
    if (!shape.motion.IsTranslationOnly()) return true;
    spheres.push_back(&shape);
  }
  auto near = [](double a, double b) { return std::fabs(a - b) <= 1e-5 * std::max({1.0, std::fabs(a), std::fabs(b)}); };
  for (size_t a = 0; a < spheres.size(); ++a) {
    for (size_t b = a + 1; b < spheres.size(); ++b) {
      const Shape& s = *spheres[a];
      const Shape& t = *spheres[b];
      const Vec3 sc = s.motion.WorldFromObject(scene.render.firstFrame).Apply(s.center);
      const Vec3 tc = t.motion.WorldFromObject(scene.render.firstFrame).Apply(t.center);
      const bool sameCentre = near(sc.x, tc.x) && near(sc.y, tc.y) && near(sc.z, tc.z);
      if (near(s.radius, t.radius) && (s.Moves() || t.Moves() || sameCentre)) return true;
    }
  }
  return false;
}

// Values that sit on either side of the comparison grid (1e-5 of their size), at sizes
// below and far above 1, so that near misses and near hits both occur.
double GridEdgeValue(std::mt19937& random) {
  static const double kBases[] = {0.5, 1, 3, -2, 1000, -250000};
  static const double kNudges[] = {0, 0, 0, 0.4e-5, 0.9e-5, 1.1e-5, 3e-5, -0.9e-5, -1.1e-5};
  const double base = kBases[random() % std::size(kBases)];
  return base + kNudges[random() % std::size(kNudges)] * std::max(1.0, std::fabs(base));
}

std::string RandomSphere(std::mt19937& random, bool mayMove) {
  auto number = [](double v) {
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", v);
    return std::string(text);
  };
  std::string sphere = R"({"type": "sphere", "center": [)" + number(GridEdgeValue(random)) + ", " +
                       number(GridEdgeValue(random)) + ", " + number(GridEdgeValue(random)) +
                       R"(], "radius": )" + number(std::fabs(GridEdgeValue(random)));
  if (mayMove && random() % 8 == 0) sphere += R"(, "motion": {"polynomial": [[0, 0.25], [0], [0]]})";
  return sphere + "}";
}

TEST(TieCandidatesTest, SphereSweepAnswersAsEveryPairDoes) {
  std::mt19937 random(20240611);
  int meet = 0, apart = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const bool mayMove = trial % 2 == 0;
    std::string shapes = RandomSphere(random, mayMove);
    const int count = 2 + static_cast<int>(random() % 24);
    for (int i = 1; i < count; ++i) shapes += ", " + RandomSphere(random, mayMove);
    const Scene scene = WithShapes(shapes);
    const bool expected = SpheresMayMeetPairwise(scene);
    ASSERT_EQ(SpheresMayMeet(scene), expected) << shapes;
    (expected ? meet : apart) += 1;
  }
  // Both answers must have come up often, or the comparison proved little.
  EXPECT_GT(meet, 300);
  EXPECT_GT(apart, 300);
}

TEST(TieCandidatesTest, ManySpheresInALatticeAreApartAndADuplicateIsFound) {
  std::string shapes;
  for (int x = 0; x < 12; ++x) {
    for (int y = 0; y < 12; ++y) {
      for (int z = 0; z < 12; ++z) {
        if (!shapes.empty()) shapes += ", ";
        shapes += R"({"type": "sphere", "radius": 0.25, "center": [)" + std::to_string(x) + ", " +
                  std::to_string(y) + ", " + std::to_string(z) + "]}";
      }
    }
  }
  EXPECT_FALSE(SpheresMayMeet(WithShapes(shapes)));
  EXPECT_TRUE(SpheresMayMeet(WithShapes(shapes + R"(, {"type": "sphere", "radius": 0.25, "center": [7, 3, 5.000001]})")));
}

}  // namespace
}  // namespace tcfarm
