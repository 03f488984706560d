// Shapes that turn, grow and move: a shape placed by its motion at frame f looks like the
// same shape built in place at f (positions, normals, shading), within the rounding of
// the float instance matrix that places it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

constexpr int kWidth = 120;
constexpr int kHeight = 90;

std::vector<float> Render(const Scene& scene, int frame, uint64_t* frameBuilds = nullptr) {
  EmbreeDevice device;
  TracingThreads pool(2);
  Tracer tracer(device, scene, pool);
  std::vector<float> rgb(static_cast<size_t>(kWidth) * kHeight * 3);
  tracer.TraceFrame(frame, rgb.data());
  if (frameBuilds) *frameBuilds = tracer.FrameBuilds();
  return rgb;
}

// Pixels differing by more than a tolerance: edges may flip between two hits a rounding
// apart; the body of a shape, its shading and its shadow may not.
double ShareDiffering(const std::vector<float>& a, const std::vector<float>& b) {
  size_t differing = 0;
  for (size_t i = 0; i < a.size(); i += 3) {
    float gap = std::max({std::fabs(a[i] - b[i]), std::fabs(a[i + 1] - b[i + 1]), std::fabs(a[i + 2] - b[i + 2])});
    differing += gap > 1e-3f;
  }
  return static_cast<double>(differing) / (a.size() / 3);
}

Scene MovingScene() {
  return ParseScene(R"({
    "camera": {"position": [0, 2.5, 7], "look_at": [0, 0.8, 0]},
    "lights": [{"type": "point", "position": [3, 6, 4], "intensity": [60, 60, 60]},
               {"type": "directional", "direction": [-1, -2, -1], "intensity": [0.3, 0.3, 0.3]}],
    "materials": {"red": {"diffuse": [0.8, 0.1, 0.1], "specular": [0.4, 0.4, 0.4], "shininess": 20},
                  "blue": {"diffuse": [0.1, 0.2, 0.8], "specular": [0.5, 0.5, 0.5]},
                  "floor": {"diffuse": [0.6, 0.6, 0.6]}},
    "shapes": [
      {"type": "quad", "corner": [-10, 0, -10], "edge_u": [0, 0, 20], "edge_v": [20, 0, 0], "material": "floor"},
      {"type": "mesh", "material": "red",
       "vertices": [[-0.5, 0.5, -0.5], [0.5, 0.5, -0.5], [0.5, 1.5, -0.5], [-0.5, 1.5, -0.5],
                    [-0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [0.5, 1.5, 0.5], [-0.5, 1.5, 0.5]],
       "triangles": [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                     [3, 6, 2], [3, 7, 6], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]],
       "motion": {"translation": {"polynomial": [[-1, 0.1], [0], [0]]},
                  "rotation": {"axis": [0.3, 1, 0.2], "degrees_per_frame": 11},
                  "scale": {"polynomial": [[1, 0.05], [1], [1, -0.03]]}, "pivot": [0, 1, 0]}},
      {"type": "sphere", "center": [1.8, 0.7, 0], "radius": 0.5, "material": "blue",
       "motion": {"rotation": {"axis": [1, 0, 0], "degrees_per_frame": 20},
                  "scale": {"polynomial": [[1, 0.1], [1, 0.1], [1, 0.1]]}, "pivot": [1.8, 0.2, 0]}}],
    "background": [0.1, 0.1, 0.2],
    "render": {"width": 120, "height": 90, "frames": {"start": 0, "count": 12}}
  })");
}

// The same world at `frame` with every moving shape built where its motion puts it.
Scene PlacedAt(Scene scene, int frame) {
  for (Shape& shape : scene.shapes) {
    if (!shape.Moves()) continue;
    const Affine worldFromObject = shape.motion.WorldFromObject(frame);
    if (shape.type == Shape::Type::kSphere) {
      shape.center = worldFromObject.Apply(shape.center);
      shape.radius *= worldFromObject.MaxStretch();  // uniform scale here: still a sphere
    } else {
      for (Vec3& v : shape.mesh.vertices) v = worldFromObject.Apply(v);
    }
    shape.motion = Motion{};
  }
  return scene;
}

TEST(MotionTest, TurnedAndScaledShapesLookLikeCopiesBuiltInPlace) {
  const Scene scene = MovingScene();
  for (int frame : {0, 4, 11}) {
    double share = ShareDiffering(Render(scene, frame), Render(PlacedAt(scene, frame), frame));
    EXPECT_LT(share, 0.002) << "frame " << frame << ": " << share * 100 << " % of pixels differ";
  }
}

TEST(MotionTest, TheImageFollowsTheMotion) {
  // A shape that turns changes the picture from frame to frame; one that does not, does not.
  const Scene scene = MovingScene();
  EXPECT_GT(ShareDiffering(Render(scene, 0), Render(scene, 6)), 0.01);
  Scene still = scene;
  for (Shape& shape : still.shapes) shape.motion = Motion{};
  EXPECT_EQ(ShareDiffering(Render(still, 0), Render(still, 6)), 0.0);
}

TEST(MotionTest, ShapesHeldAtATransformAreBuiltInPlace) {
  // Every shape of the scene at its frame-4 transform, held there.
  Scene held = MovingScene();
  for (Shape& shape : held.shapes) {
    if (!shape.Moves()) continue;
    const Affine at4 = shape.motion.WorldFromObject(4);
    shape.motion.translation = AnimatedVec3::Constant(shape.motion.translation.Evaluate(4));
    shape.motion.rotation = AnimatedRotation::Constant(shape.motion.rotation.Evaluate(4));
    shape.motion.scale = AnimatedVec3::Constant(shape.motion.scale.Evaluate(4));
    ASSERT_EQ(shape.motion.WorldFromObject(0), at4);
    ASSERT_FALSE(shape.Moves());
  }
  uint64_t instancedBuilds = 0, placedBuilds = 0;
  std::vector<float> instanced = Render(held, 0, &instancedBuilds);
  Scene placed = held;
  PlaceStillShapes(placed);
  for (const Shape& shape : placed.shapes) EXPECT_TRUE(shape.motion.IsNone());
  EXPECT_LT(ShareDiffering(instanced, Render(placed, 0, &placedBuilds)), 0.002);
  EXPECT_EQ(placedBuilds, 0u);  // nothing placed per frame once built in place
  EXPECT_EQ(instancedBuilds, 1u);
  EXPECT_LT(ShareDiffering(instanced, Render(PlacedAt(MovingScene(), 4), 4)), 0.002);

  // A ball squashed unevenly is no sphere: it keeps its transform, and still renders.
  Scene squashed = held;
  squashed.shapes[2].motion.scale = AnimatedVec3::Constant({1.5, 0.6, 1.5});
  PlaceStillShapes(squashed);
  EXPECT_FALSE(squashed.shapes[2].motion.IsNone());
  EXPECT_TRUE(squashed.shapes[1].motion.IsNone());
  EXPECT_GT(ShareDiffering(Render(squashed, 0), instanced), 0.001);
}

// A smooth ball (normals written per vertex) and a mirrored ball of glass before a wall:
// what a held node's transform does to normals and to the winding that says which side is
// outside.
Scene SmoothAndMirroredBalls(const std::string& smoothMotion, const std::string& glassMotion) {
  std::string vertices, normals, triangles;
  constexpr int kRings = 10, kSegments = 16;
  for (int ring = 0; ring <= kRings; ++ring) {
    const double theta = M_PI * ring / kRings;
    for (int segment = 0; segment < kSegments; ++segment) {
      const double phi = 2 * M_PI * segment / kSegments;
      const double x = std::sin(theta) * std::cos(phi), y = std::cos(theta), z = std::sin(theta) * std::sin(phi);
      const std::string v = "[" + std::to_string(x) + ", " + std::to_string(y) + ", " + std::to_string(z) + "]";
      vertices += (vertices.empty() ? "" : ", ") + v;
      normals += (normals.empty() ? "" : ", ") + v;
      if (ring == kRings) continue;
      const int a = ring * kSegments + segment, b = ring * kSegments + (segment + 1) % kSegments;
      triangles += (triangles.empty() ? "" : ", ") + ("[" + std::to_string(a) + ", " + std::to_string(b) + ", " +
                                                     std::to_string(b + kSegments) + "], [" + std::to_string(a) +
                                                     ", " + std::to_string(b + kSegments) + ", " +
                                                     std::to_string(a + kSegments) + "]");
    }
  }
  const std::string ball = R"("vertices": [)" + vertices + R"(], "normals": [)" + normals + R"(], "triangles": [)" +
                           triangles + "]";
  return ParseScene(R"({
    "camera": {"position": [0, 1, 7], "look_at": [0, 1, 0]},
    "lights": [{"type": "point", "position": [2, 6, 5], "intensity": [60, 60, 60]}],
    "materials": {"clay": {"diffuse": [0.8, 0.5, 0.3], "specular": [0.5, 0.5, 0.5], "shininess": 30},
                  "glass": {"diffuse": [0.05, 0.05, 0.05], "transparency": 0.9, "ior": 1.5},
                  "wall": {"diffuse": [0.2, 0.6, 0.3]}},
    "shapes": [
      {"type": "quad", "corner": [-6, -2, -3], "edge_u": [12, 0, 0], "edge_v": [0, 8, 0], "material": "wall"},
      {"type": "mesh", "material": "clay", )" + ball + R"(, "motion": )" + smoothMotion + R"(},
      {"type": "mesh", "material": "glass", )" + ball + R"(, "motion": )" + glassMotion + R"(}],
    "render": {"width": 120, "height": 90, "max_depth": 4}
  })");
}

TEST(MotionTest, NormalsAndOutsidesOfShapesBuiltInPlaceFollowTheirTransform) {
  // Held at a turn and a scale, and at a mirror: built in place, as shapes that move are
  // carried by their instance. (Under an uneven scale the two differ a little in the
  // smooth shading: built in place, each vertex's normal is made unit before the hit
  // interpolates them.)
  const Scene held = SmoothAndMirroredBalls(
      R"({"translation": [-1.4, 1, 0], "rotation": {"axis": [0, 0, 1], "degrees_per_frame": 0, "degrees": 80},
          "scale": [0.8, 0.8, 0.8]})",
      R"({"translation": [1.4, 1, 1], "scale": [-1.1, 1.1, 1.1]})");
  Scene placed = held;
  PlaceStillShapes(placed);
  for (const Shape& shape : placed.shapes) ASSERT_TRUE(shape.motion.IsNone());
  const std::vector<float> carried = Render(held, 0), built = Render(placed, 0);
  EXPECT_LT(ShareDiffering(carried, built), 0.002);
  // The ball's smooth shading shows: its normals are not its faces'.
  Scene flat = placed;
  flat.shapes[1].mesh.normals.clear();
  EXPECT_GT(ShareDiffering(Render(flat, 0), built), 0.01);
}

}  // namespace
}  // namespace tcfarm
