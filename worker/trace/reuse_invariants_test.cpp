// What temporal reuse rests on, on the scenes most likely to break it: a pixel's bits do
// not depend on how it was traced (packet mates, pixel set, thread count, the frame's
// placement of the moving shapes), and a pixel copied up to its horizon equals a full
// trace of every frame it is copied into. Coplanar surfaces (a ray meets two of them at
// the same distance; real assets are full of them) and shapes that turn and grow.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

constexpr int kWidth = 96;
constexpr int kHeight = 72;
constexpr int kFrames = 12;

const char* kTwoLights = R"([{"type": "point", "position": [4, 6, 3], "intensity": [30, 30, 30]},
    {"type": "directional", "direction": [-1, -2, -1], "intensity": [0.3, 0.3, 0.3]}])";

std::string CoplanarScene(const std::string& shapes, const std::string& extraMaterials = "",
                          const std::string& lights = kTwoLights) {
  return R"({
    "camera": {"position": [0, 2, 8], "look_at": [0, 1, 0]},
    "lights": )" + lights + R"(,
    "materials": {"red": {"diffuse": [0.8, 0.1, 0.1], "specular": [0.3, 0.3, 0.3], "shininess": 32},
                  "blue": {"diffuse": [0.1, 0.2, 0.8]},
                  "floor": {"diffuse": [0.6, 0.6, 0.6]},
                  "mirror": {"diffuse": [0.05, 0.05, 0.05], "reflectivity": 0.9})" +
         extraMaterials + R"(},
    "shapes": [)" + shapes + R"(],
    "background": [0.1, 0.1, 0.2],
    "render": {"width": )" + std::to_string(kWidth) + R"(, "height": )" + std::to_string(kHeight) +
         R"(, "frames": {"start": 0, "count": )" + std::to_string(kFrames) +
         R"(}, "samples_per_pixel": 1, "max_depth": 5}
  })";
}

const char* kFloor =
    R"({"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0], "material": "floor"})";

struct Variant {
  const char* name;
  std::string json;
};

// A bar of four segments along x from `x0` at height 1, bound to two joints: the first
// holds its left half, the second (the elbow, at x0 + 1) bends the right half about z,
// with a pause (frames 4..7) where the pose does not change. Vertices at the elbow blend.
std::string SkinnedArm(double x0) {
  std::string vertices, joints, weights, triangles;
  auto add = [](std::string& list, const std::string& item) { list += (list.empty() ? "" : ", ") + item; };
  for (int ring = 0; ring < 5; ++ring) {
    const double x = x0 + 0.5 * ring;
    const double second = ring < 2 ? 0 : (ring == 2 ? 0.5 : 1);
    for (int corner = 0; corner < 4; ++corner) {
      const double y = corner < 2 ? 0.8 : 1.2, z = (corner == 0 || corner == 3) ? -0.2 : 0.2;
      add(vertices, "[" + std::to_string(x) + ", " + std::to_string(y) + ", " + std::to_string(z) + "]");
      add(joints, "[0, 1, 0, 0]");
      add(weights, "[" + std::to_string(1 - second) + ", " + std::to_string(second) + ", 0, 0]");
    }
  }
  auto index = [](int ring, int corner) { return std::to_string(4 * ring + corner % 4); };
  for (int ring = 0; ring < 4; ++ring) {
    for (int corner = 0; corner < 4; ++corner) {
      const std::string a = index(ring, corner), b = index(ring, corner + 1), c = index(ring + 1, corner + 1),
                        d = index(ring + 1, corner);
      add(triangles, "[" + a + ", " + b + ", " + c + "], [" + a + ", " + c + ", " + d + "]");
    }
  }
  add(triangles, "[0, 2, 1], [0, 3, 2], [16, 17, 18], [16, 18, 19]");
  const std::string elbow = std::to_string(x0 + 1);
  return R"({"type": "mesh", "material": "red", "vertices": [)" + vertices + R"(], "triangles": [)" + triangles +
         R"(], "skin": {"joints": [[0, 0, 0], {"translation": [)" + elbow + R"(, 1, 0], "rotation": {"keyframes": [
             {"frame": 0, "value": [0, 0, 0, 1]}, {"frame": 4, "value": [0, 0, 0.2588190, 0.9659258]},
             {"frame": 7, "value": [0, 0, 0.2588190, 0.9659258]}, {"frame": 11, "value": [0, 0, 0.5, 0.8660254]}]}}],
           "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], [1, 0, 0, -)" + elbow +
         R"(, 0, 1, 0, -1, 0, 0, 1, 0]],
           "vertex_joints": [)" + joints + R"(], "vertex_weights": [)" + weights + R"(]}})";
}

// A smooth octahedron whose top rises and sides swell by one morph target, its weight
// on a cubic spline, casting a shadow on the floor.
const char* kMorphingBlob = R"({"type": "mesh", "material": "blue",
    "vertices": [[-2, 1.6, 0.5], [-1.4, 1, 0.5], [-2, 1, 1.1], [-2.6, 1, 0.5], [-2, 1, -0.1], [-2, 0.4, 0.5]],
    "normals": [[0, 1, 0], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1], [0, -1, 0]],
    "triangles": [[0, 2, 1], [0, 3, 2], [0, 4, 3], [0, 1, 4], [5, 1, 2], [5, 2, 3], [5, 3, 4], [5, 4, 1]],
    "morph": {"targets": [{"positions": [[0, 0.5, 0], [0.2, 0, 0], [0, 0, 0.2], [-0.2, 0, 0], [0, 0, -0.2], [0, 0, 0]],
                           "normals": [[0, 0, 0], [0, 0.3, 0], [0, 0.3, 0], [0, 0.3, 0], [0, 0.3, 0], [0, 0, 0]]}],
              "weights": {"interpolation": "cubicspline", "keyframes": [
                  {"frame": 0, "value": [0], "in_tangent": [0], "out_tangent": [0.1]},
                  {"frame": 6, "value": [1], "in_tangent": [0], "out_tangent": [0]},
                  {"frame": 11, "value": [0.2], "in_tangent": [-0.1], "out_tangent": [0]}]}}})";

const char* kWall =
    R"({"type": "quad", "corner": [-6, 0, -3], "edge_u": [12, 0, 0], "edge_v": [0, 6, 0], "material": "blue"})";
const char* kMirror =
    R"({"type": "quad", "corner": [-6, 0, -3], "edge_u": [12, 0, 0], "edge_v": [0, 6, 0.5], "material": "mirror"})";

// The morphing blob on a node of its own that flies across the floor and rises: placed as a
// whole and deformed at once.
std::string FlyingMorphingBlob() {
  std::string blob = kMorphingBlob;
  const std::string material = R"("material": "blue",)";
  blob.insert(blob.find(material) + material.size(),
              R"( "motion": {"translation": {"keyframes": [{"frame": 0, "value": [0, 0, 0]},
                  {"frame": 11, "value": [2.5, 0.4, 0]}]}},)");
  return blob;
}

// Meshes that deform: a skinned arm bending before a still wall, a morphing blob and its
// shadow, a skinned arm seen in a mirror.
std::vector<Variant> DeformingVariants() {
  const std::string floor = kFloor;
  return {
      {"a skinned arm bending in front of a still wall", CoplanarScene(floor + ", " + kWall + ", " + SkinnedArm(-1))},
      {"a morphing blob casting a shadow", CoplanarScene(floor + ", " + kMorphingBlob)},
      {"a morphing blob casting a shadow as it flies", CoplanarScene(floor + ", " + FlyingMorphingBlob())},
      {"a skinned arm seen in a mirror", CoplanarScene(floor + ", " + kMirror + ", " + SkinnedArm(0.5))},
  };
}

std::vector<Variant> Variants() {
  const std::string floor = kFloor;
  std::vector<Variant> variants{
      {"moving quad on the floor",
       CoplanarScene(floor + R"(, {"type": "quad", "corner": [-3, 0, -1], "edge_u": [0, 0, 2],
           "edge_v": [2, 0, 0], "material": "red", "motion": {"polynomial": [[0, 0.4], [0], [0]]}})")},
      {"still quad on the floor beside a moving ball",
       CoplanarScene(floor + R"(, {"type": "quad", "corner": [-1.3, 0, -1.1], "edge_u": [0, 0, 2.3],
           "edge_v": [2.7, 0, 0], "material": "red"},
           {"type": "sphere", "center": [2, 0.5, 0], "radius": 0.5, "material": "blue",
            "motion": {"polynomial": [[0], [0, 0.1], [0]]}})")},
      {"two moving coplanar quads",
       CoplanarScene(floor + R"(, {"type": "quad", "corner": [-3, 0, -1], "edge_u": [0, 0, 2],
           "edge_v": [2, 0, 0], "material": "red", "motion": {"polynomial": [[0, 0.3], [0], [0]]}},
           {"type": "quad", "corner": [1, 0, -1.5], "edge_u": [0, 0, 2.5], "edge_v": [2.5, 0, 0],
            "material": "blue", "motion": {"polynomial": [[0, -0.3], [0], [0]]}})")},
      {"coplanar triangles of one mesh",
       CoplanarScene(R"({"type": "mesh", "material": "floor",
           "vertices": [[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4], [-3, 0, -3.3], [3.1, 0, -2.9], [0.2, 0, 3.7]],
           "triangles": [[0, 1, 2], [0, 2, 3], [4, 5, 6], [6, 5, 4]]},
           {"type": "sphere", "center": [-2, 0.6, 1], "radius": 0.6, "material": "red",
            "motion": {"polynomial": [[0, 0.3], [0], [0]]}})")},
      {"a spinning cube beside a growing ball",
       CoplanarScene(floor + R"(, {"type": "mesh", "material": "red",
           "vertices": [[-0.5, 0.5, -0.5], [0.5, 0.5, -0.5], [0.5, 1.5, -0.5], [-0.5, 1.5, -0.5],
                        [-0.5, 0.5, 0.5], [0.5, 0.5, 0.5], [0.5, 1.5, 0.5], [-0.5, 1.5, 0.5]],
           "triangles": [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                         [3, 6, 2], [3, 7, 6], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]],
           "motion": {"rotation": {"axis": [0.3, 1, 0.2], "degrees_per_frame": 7}, "pivot": [0, 1, 0]}},
           {"type": "sphere", "center": [2, 0.6, 0], "radius": 0.5, "material": "blue",
            "motion": {"scale": {"keyframes": [{"frame": 0, "value": [1, 1, 1]}, {"frame": 3, "value": [1, 1, 1]},
                                               {"frame": 11, "value": [1.6, 0.8, 1.6]}]},
                       "pivot": [2, 0.1, 0]}})")},
      {"a smooth octahedron turning over a smooth bowl",
       CoplanarScene(floor + R"(, {"type": "mesh", "material": "blue",
           "vertices": [[0, 1.6, 0], [0.6, 1, 0], [0, 1, 0.6], [-0.6, 1, 0], [0, 1, -0.6], [0, 0.4, 0]],
           "normals": [[0, 1, 0], [1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1], [0, -1, 0]],
           "triangles": [[0, 2, 1], [0, 3, 2], [0, 4, 3], [0, 1, 4], [5, 1, 2], [5, 2, 3], [5, 3, 4], [5, 4, 1]],
           "motion": {"rotation": {"axis": [0.2, 1, 0.4], "degrees_per_frame": 8}, "pivot": [0, 1, 0]}},
           {"type": "mesh", "material": "red",
            "vertices": [[1.5, 0.01, -1], [2.5, 0.01, -1], [2.5, 0.01, 0], [1.5, 0.01, 0], [2, 0.5, -0.5]],
            "normals": [[-0.5, 0.7, 0.5], [0.5, 0.7, 0.5], [0.5, 0.7, -0.5], [-0.5, 0.7, -0.5], [0, 1, 0]],
            "triangles": [[0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]]})")},
      {"a spot light's cone edge sweeping the floor",
       CoplanarScene(floor + R"(, {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5, "material": "red"})", "",
                     R"([{"type": "spot", "position": [0, 4, 1], "direction": {"keyframes": [{"frame": 0, "value": [-1, -2, 0]},
                         {"frame": 11, "value": [1, -2, -0.5]}]}, "intensity": [40, 40, 40],
                         "inner_cone_degrees": 10, "outer_cone_degrees": 18},
                        {"type": "directional", "direction": [-1, -2, -1], "intensity": [0.3, 0.3, 0.3]}])")},
      {"a ball rolling out of ranged lights' reach",
       CoplanarScene(floor + R"(, {"type": "sphere", "center": [-4, 0.5, 0], "radius": 0.5, "material": "red",
                                   "motion": {"polynomial": [[0, 0.5], [0], [0]]}})", "",
                     R"([{"type": "point", "position": [0, 3, 0], "intensity": [40, 40, 40], "range": 4},
                        {"type": "spot", "position": [-3, 4, 1], "direction": [0.3, -1, 0], "intensity": [40, 40, 40],
                         "range": 5, "outer_cone_degrees": 60}])")},
      {"a child stepped and splined on a spinning parent",
       CoplanarScene(floor + R"(, {"type": "mesh", "material": "red",
           "vertices": [[-0.3, 0.2, -0.3], [0.3, 0.2, -0.3], [0.3, 0.8, -0.3], [-0.3, 0.8, -0.3],
                        [-0.3, 0.2, 0.3], [0.3, 0.2, 0.3], [0.3, 0.8, 0.3], [-0.3, 0.8, 0.3]],
           "triangles": [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                         [3, 6, 2], [3, 7, 6], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]],
           "motion": {"translation": {"interpolation": "cubicspline", "keyframes": [
                        {"frame": 0, "value": [1.5, 0, 0], "in_tangent": [0, 0, 0], "out_tangent": [0, 0.1, 0]},
                        {"frame": 11, "value": [1.5, 0.4, 0], "in_tangent": [0, 0, 0], "out_tangent": [0, 0, 0]}]},
                      "rotation": {"interpolation": "step", "keyframes": [{"frame": 0, "value": [0, 0, 0, 1]},
                        {"frame": 6, "value": [0, 0.3826834, 0, 0.9238795]}]},
                      "pivot": [0, 0.5, 0],
                      "parent": {"rotation": {"axis": [0, 1, 0], "degrees_per_frame": 6}}}})")},
      {"a box that stops, waits and moves on, turning",
       CoplanarScene(floor + R"(, {"type": "mesh", "material": "red",
           "vertices": [[-0.3, 0.2, -0.3], [0.3, 0.2, -0.3], [0.3, 0.8, -0.3], [-0.3, 0.8, -0.3],
                        [-0.3, 0.2, 0.3], [0.3, 0.2, 0.3], [0.3, 0.8, 0.3], [-0.3, 0.8, 0.3]],
           "triangles": [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                         [3, 6, 2], [3, 7, 6], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5]],
           "motion": {"translation": {"keyframes": [{"frame": 0, "value": [-2, 0, 0]}, {"frame": 4, "value": [0, 0, 0]},
                                                    {"frame": 7, "value": [0, 0, 0]}, {"frame": 11, "value": [1, 0.5, 0]}]},
                      "rotation": {"keyframes": [{"frame": 0, "value": [0, 0, 0, 1]},
                                                 {"frame": 4, "value": [0, 0.3826834, 0, 0.9238795]},
                                                 {"frame": 7, "value": [0, 0.3826834, 0, 0.9238795]},
                                                 {"frame": 11, "value": [0, 0, 0, 1]}]},
                      "pivot": [0, 0.5, 0]}},
           {"type": "sphere", "center": [2, 0.5, 1], "radius": 0.5, "material": "blue",
            "motion": {"translation": {"keyframes": [{"frame": 0, "value": [0, 0, 0]}, {"frame": 5, "value": [0, 0, 0]},
                                                     {"frame": 11, "value": [-1, 0, 0]}]}}})")},
      {"a tie seen in a mirror",
       CoplanarScene(floor + R"(, {"type": "quad", "corner": [-3, 0, -1], "edge_u": [0, 0, 2],
           "edge_v": [2, 0, 0], "material": "red", "motion": {"polynomial": [[0, 0.4], [0], [0]]}},
           {"type": "quad", "corner": [-6, 0, -3], "edge_u": [12, 0, 0], "edge_v": [0, 6, 0.5],
            "material": "mirror"},
           {"type": "quad", "corner": [-6, 0, -3.0001], "edge_u": [12, 0, 0], "edge_v": [0, 6, 0.5],
            "material": "blue"})")},
  };
  for (Variant& deforming : DeformingVariants()) variants.push_back(std::move(deforming));
  return variants;
}

std::vector<float> TraceFull(Tracer& tracer, int frame) {
  std::vector<float> rgb(static_cast<size_t>(kWidth) * kHeight * 3);
  tracer.TraceFrame(frame, rgb.data());
  return rgb;
}

bool SamePixel(const float* a, const float* b) { return std::memcmp(a, b, 3 * sizeof(float)) == 0; }

// Any pixel set, in any order, on any thread count, gives the full frame's bits.
TEST(ReuseInvariantsTest, EveryPixelSetGivesTheFullFramesBits) {
  EmbreeDevice device;
  std::mt19937 random(7);
  for (const Variant& variant : Variants()) {
    Scene scene = ParseScene(variant.json);
    TracingThreads fullPool(2);
    Tracer reference(device, scene, fullPool);
    for (int frame : {0, 5, 11}) {
      std::vector<float> full = TraceFull(reference, frame);
      for (unsigned threads : {1u, 3u}) {
        TracingThreads pool(threads);
        Tracer tracer(device, scene, pool);
        for (int trial = 0; trial < 3; ++trial) {
          std::vector<uint32_t> pixels(full.size() / 3);
          std::iota(pixels.begin(), pixels.end(), 0u);
          std::shuffle(pixels.begin(), pixels.end(), random);
          pixels.resize(1 + random() % (trial == 0 ? 40 : pixels.size()));
          std::vector<float> rgb(pixels.size() * 3);
          tracer.TracePixels(frame, pixels.data(), pixels.size(), rgb.data());
          size_t differing = 0;
          for (size_t i = 0; i < pixels.size(); ++i) {
            differing += !SamePixel(&rgb[3 * i], &full[3 * pixels[i]]);
          }
          EXPECT_EQ(differing, 0u) << variant.name << ": frame " << frame << ", " << pixels.size()
                                   << " pixels on " << threads << " threads";
        }
      }
    }
  }
}

// exact's promise at the tracer: a pixel traced at frame a with horizon h has the same bits
// in every frame a .. h-1 as a full trace of that frame gives it.
TEST(ReuseInvariantsTest, CopiesUpToTheHorizonEqualFullTraces) {
  EmbreeDevice device;
  for (const Variant& variant : Variants()) {
    Scene scene = ParseScene(variant.json);
    TracingThreads pool(2);
    Tracer tracer(device, scene, pool);
    std::vector<std::vector<float>> frames;
    for (int frame = 0; frame < kFrames; ++frame) frames.push_back(TraceFull(tracer, frame));
    const size_t pixelCount = static_cast<size_t>(kWidth) * kHeight;
    std::vector<uint32_t> pixels(pixelCount);
    std::iota(pixels.begin(), pixels.end(), 0u);
    std::vector<float> rgb(pixelCount * 3);
    std::vector<int32_t> horizons(pixelCount);
    // From the first frame, and from inside the pauses of the variants that pause.
    for (int start : {0, 5}) {
      const int window = kFrames - 1 - start;
      tracer.TracePixels(start, pixels.data(), pixelCount, rgb.data(), window, horizons.data());
      size_t wrong = 0, copies = 0;
      for (size_t p = 0; p < pixelCount; ++p) {
        for (int frame = start + 1; frame < std::min(horizons[p], kFrames); ++frame, ++copies) {
          wrong += !SamePixel(&rgb[3 * p], &frames[frame][3 * p]);
        }
      }
      EXPECT_EQ(wrong, 0u) << variant.name << ", from frame " << start << ": " << wrong << " of " << copies
                           << " copies differ";
      EXPECT_GT(copies, pixelCount) << variant.name << ": horizons should let still pixels be copied";
    }
  }
}

// A deforming mesh is posed by refitting a tree built from its rest pose: whatever frames
// a worker posed before, in whatever order, a frame traces to the same bits. And a pause
// in the animation poses nothing new.
TEST(ReuseInvariantsTest, DeformingMeshesTraceTheSameBitsInAnyFrameOrder) {
  EmbreeDevice device;
  for (const Variant& variant : DeformingVariants()) {
    Scene scene = ParseScene(variant.json);
    TracingThreads pool(2);
    Tracer forward(device, scene, pool), backward(device, scene, pool);
    std::vector<std::vector<float>> frames;
    for (int frame = 0; frame < kFrames; ++frame) frames.push_back(TraceFull(forward, frame));
    size_t differing = 0, changed = 0;
    for (int frame = kFrames - 1; frame >= 0; --frame) {
      const std::vector<float> again = TraceFull(backward, frame);
      for (size_t p = 0; p < again.size() / 3; ++p) {
        differing += !SamePixel(&again[3 * p], &frames[frame][3 * p]);
        if (frame > 0) changed += !SamePixel(&frames[frame][3 * p], &frames[frame - 1][3 * p]);
      }
    }
    EXPECT_EQ(differing, 0u) << variant.name;
    EXPECT_GT(changed, 0u) << variant.name << ": the mesh should visibly deform";
    const SceneGeometry::DeformationWork work = forward.DeformationCounts();
    EXPECT_GT(work.posesComputed, 0u) << variant.name;
    EXPECT_GT(work.verticesDeformed, 0u) << variant.name;
  }
}

TEST(ReuseInvariantsTest, APauseInASkinPosesNothingNew) {
  EmbreeDevice device;
  Scene scene = ParseScene(CoplanarScene(std::string(kFloor) + ", " + SkinnedArm(-1)));
  TracingThreads pool(2);
  Tracer tracer(device, scene, pool);
  for (int frame = 0; frame < kFrames; ++frame) TraceFull(tracer, frame);
  // Frames 4..7 hold one pose: 12 frames, 9 poses.
  EXPECT_EQ(tracer.DeformationCounts().posesComputed, 9u);
  EXPECT_EQ(tracer.DeformationCounts().posesShared, 3u);
}

}  // namespace
}  // namespace tcfarm
