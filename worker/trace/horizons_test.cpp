// Validity horizons against brute force: a pixel traced at frame a with horizon h must be
// bit-identical in every frame a+1 .. h-1. Every scene here is rendered in full at every
// frame and each promise is checked pixel by pixel.
#include <gtest/gtest.h>

#include <cstring>
#include <algorithm>
#include <numeric>
#include <random>
#include <set>
#include <string>

#include "worker/embree/scene_geometry.h"
#include "worker/trace/horizons.h"
#include "tests/support/cpp/scaled_scene.h"
#include "tests/support/cpp/skinned_tube.h"
#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

struct Sequence {
  std::vector<std::vector<float>> frames;
};

Sequence RenderAll(Tracer& tracer, const Scene& scene) {
  Sequence sequence;
  size_t floats = static_cast<size_t>(scene.render.width) * scene.render.height * 3;
  for (int f = scene.render.firstFrame; f <= scene.render.LastFrame(); ++f) {
    sequence.frames.emplace_back(floats);
    tracer.TraceFrame(f, sequence.frames.back().data());
  }
  return sequence;
}

struct HorizonCheck {
  size_t broken = 0;     // promises that brute force contradicts
  size_t unbounded = 0;  // pixels valid through the whole window
  size_t needless = 0;   // pixels due again at a+1 that are unchanged there
  size_t changed = 0;    // pixels that differ at a+1
  size_t pixels = 0;
};

bool SamePixel(const std::vector<float>& frame, const std::vector<float>& rgb, size_t p) {
  return std::memcmp(&frame[3 * p], &rgb[3 * p], 3 * sizeof(float)) == 0;
}

// Traces frame `a` with horizons over the rest of the sequence and checks each promise.
HorizonCheck Check(const Scene& scene, int a) {
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  Sequence all = RenderAll(tracer, scene);
  int first = scene.render.firstFrame, last = scene.render.LastFrame();
  size_t count = static_cast<size_t>(scene.render.width) * scene.render.height;
  std::vector<uint32_t> pixels(count);
  std::iota(pixels.begin(), pixels.end(), 0u);
  std::vector<float> rgb(count * 3);
  std::vector<int32_t> horizons(count);
  int window = last - a;
  tracer.TracePixels(a, pixels.data(), count, rgb.data(), window, horizons.data());
  HorizonCheck check;
  check.pixels = count;
  for (size_t p = 0; p < count; ++p) {
    EXPECT_GE(horizons[p], a + 1);
    EXPECT_LE(horizons[p], a + window + 1);
    check.unbounded += horizons[p] == a + window + 1;
    if (a < last) {
      bool same = SamePixel(all.frames[a + 1 - first], rgb, p);
      check.changed += !same;
      check.needless += same && horizons[p] == a + 1;
    }
    for (int f = a + 1; f < horizons[p] && f <= last; ++f) {
      if (!SamePixel(all.frames[f - first], rgb, p)) {
        ++check.broken;
        break;
      }
    }
  }
  return check;
}

Scene Small(const std::string& json) { return ParseScene(json); }

// Check() at each of `frames`: no promise broken, and at least `minChanged` pixels that
// change at the next frame (the scene does move there). Each frame's check, for a test's
// own figures.
std::vector<HorizonCheck> CheckFrames(const Scene& scene, std::initializer_list<int> frames, size_t minChanged) {
  std::vector<HorizonCheck> checks;
  for (int a : frames) {
    checks.push_back(Check(scene, a));
    EXPECT_EQ(checks.back().broken, 0u) << "frame " << a;
    EXPECT_GT(checks.back().changed, minChanged) << "frame " << a;
  }
  return checks;
}

const char* const kPaperAnimations[] = {"tests/scenes/paper_a_one_sphere.json",
                                        "tests/scenes/paper_b_twelve_spheres.json"};

// A paper animation, smaller and shorter.
Scene PaperAnimation(const char* file, int width, int height, int frames) {
  Scene scene = LoadSceneFile(file);
  scene.render.width = width;
  scene.render.height = height;
  scene.render.frameCount = frames;
  return scene;
}

const char* kBackdropAndLight = R"(
    "lights": [{"type": "point", "position": [4, 6, 8], "intensity": [120, 120, 120]}],
    "materials": {"wall": {"diffuse": [0.7, 0.7, 0.65]},
                  "ball": {"diffuse": [0.8, 0.2, 0.2], "specular": [0.4, 0.4, 0.4]},
                  "mirror": {"diffuse": [0.1, 0.1, 0.1], "reflectivity": 0.7},
                  "glass": {"diffuse": [0.05, 0.05, 0.05], "transparency": 0.8, "ior": 1.4}},
    "background": [0.1, 0.1, 0.2],)";

TEST(HorizonsTest, MovingBallWithShadowMirrorAndGlassKeepsEveryPromise) {
  Scene scene = Small(std::string(R"({
    "camera": {"position": [0, 0.5, 9], "look_at": [0, 0, 0]},)") + kBackdropAndLight + R"(
    "shapes": [
      {"type": "quad", "corner": [-8, -2, -4], "edge_u": [16, 0, 0], "edge_v": [0, 0, 10], "material": "wall"},
      {"type": "quad", "corner": [-8, -2, -4], "edge_u": [16, 0, 0], "edge_v": [0, 10, 0], "material": "wall"},
      {"type": "sphere", "center": [-2, -1, 0], "radius": 0.9, "material": "mirror"},
      {"type": "sphere", "center": [2, -1, 1], "radius": 0.8, "material": "glass"},
      {"type": "sphere", "center": [0, 0, 0], "radius": 0.4, "material": "ball",
       "motion": {"polynomial": [[-3, 0.35], [1, -0.05], [0, 0.02]]}}
    ],
    "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 16}, "max_depth": 3}
  })");
  for (int a : {0, 7}) {
    HorizonCheck check = Check(scene, a);
    EXPECT_EQ(check.broken, 0u) << "frame " << a;
    EXPECT_GT(check.unbounded, check.pixels / 3) << "frame " << a;  // not trivially a+1
  }
}

// The paper's pathological case: a thin object crosses the screen between two frames that
// are otherwise equal. Horizons see it coming.
TEST(HorizonsTest, ThinFastObjectCrossingBetweenEqualFrames) {
  Scene scene = Small(std::string(R"({
    "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},)") + kBackdropAndLight + R"(
    "shapes": [
      {"type": "quad", "corner": [-8, -6, -4], "edge_u": [16, 0, 0], "edge_v": [0, 12, 0], "material": "wall"},
      {"type": "sphere", "center": [0, 0, 0], "radius": 0.08, "material": "ball",
       "motion": {"keyframes": [{"frame": 0, "value": [-30, 0, 0]}, {"frame": 1, "value": [-30, 0, 0]},
                                {"frame": 5, "value": [30, 0, 0]}, {"frame": 6, "value": [30, 0, 0]}]}}
    ],
    "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 8}}
  })");
  HorizonCheck check = Check(scene, 0);
  EXPECT_EQ(check.broken, 0u);
}

TEST(HorizonsTest, FlickeringLightCapsLitPixels) {
  Scene scene = Small(R"({
    "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [3, 4, 8],
                "intensity": {"keyframes": [{"frame": 0, "value": [100, 100, 100]}, {"frame": 3, "value": [100, 100, 100]},
                                            {"frame": 4, "value": [20, 20, 20]}]}}],
    "shapes": [{"type": "quad", "corner": [-3, -3, 0], "edge_u": [6, 0, 0], "edge_v": [0, 6, 0]}],
    "background": [0.2, 0.3, 0.4],
    "render": {"width": 32, "height": 24, "frames": {"start": 0, "count": 8}}
  })");
  HorizonCheck check = Check(scene, 0);
  EXPECT_EQ(check.broken, 0u);
  EXPECT_GT(check.unbounded, 0u);  // the background never changes
}

// A ball the camera cannot see (behind it, between the light and the wall) casts a large
// shadow that drifts: only the shadow's edges change from frame to frame. Pixels deep in
// the shadow stay blocked and must not be traced again at every frame.
TEST(HorizonsTest, PixelsInADriftingShadowStayValidWhileTheyStayInShadow) {
  Scene scene = Small(R"({
    "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [0, 0, 20], "intensity": [300, 300, 300]}],
    "shapes": [
      {"type": "quad", "corner": [-8, -8, 0], "edge_u": [16, 0, 0], "edge_v": [0, 16, 0]},
      {"type": "sphere", "center": [0, 0, 12], "radius": 1,
       "motion": {"polynomial": [[-0.5, 0.1], [0], [0]]}}
    ],
    "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 10}}
  })");
  for (const HorizonCheck& check : CheckFrames(scene, {0, 4}, 20)) {  // the shadow's edges move
    EXPECT_LE(check.needless, check.changed / 10);
  }
}

// Materials, background and the floor (the shapes' first) of the two tests below.
const char* kBallsOnAFloor = R"("materials": {"floor": {"diffuse": [0.6, 0.6, 0.6]},
                  "ball": {"diffuse": [0.8, 0.2, 0.2], "specular": [0.4, 0.4, 0.4]},
                  "blue": {"diffuse": [0.2, 0.3, 0.8]}},
    "background": [0.1, 0.1, 0.2],
    "shapes": [
      {"type": "quad", "corner": [-10, -1, -10], "edge_u": [0, 0, 20], "edge_v": [20, 0, 0], "material": "floor"})";

// Both lights are behind the spheres, so the camera sees mostly their unlit sides, which
// show a flat ambient colour (HorizonOracle::UnlitSphereHolds). Such a pixel keeps it only
// while its ray meets the same sphere first, nearer than at the traced frame, on a side
// every light is behind: one sphere sunk into the floor and coming nearer with a still
// ball inside it, one resting on the floor, one moving away, one crossing in front.
TEST(HorizonsTest, UnlitSidesOfMovingSpheresKeepTheirColourOnlyWhileTheyStayUnlit) {
  Scene scene = Small(R"({
    "camera": {"position": [0, 1, 9], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [0, 3, -10], "intensity": [150, 150, 150]},
               {"type": "directional", "direction": [0.1, -0.2, 1], "intensity": [0.4, 0.4, 0.4]}],
    )" + std::string(kBallsOnAFloor) + R"(,
      {"type": "sphere", "center": [-0.5, -0.5, 0], "radius": 1.2, "material": "ball",
       "motion": {"polynomial": [[0, 0.12], [0], [0, 0.15]]}},
      {"type": "sphere", "center": [-0.2, -0.4, 0.3], "radius": 0.3, "material": "blue"},
      {"type": "sphere", "center": [2.5, 0, -1], "radius": 1, "material": "ball",
       "motion": {"polynomial": [[0, -0.05], [0], [0, 0.1]]}},
      {"type": "sphere", "center": [-3, 0.5, -1], "radius": 0.8, "material": "blue",
       "motion": {"polynomial": [[0], [0], [0, -0.2]]}},
      {"type": "sphere", "center": [-4, 0, 3], "radius": 0.3, "material": "blue",
       "motion": {"polynomial": [[0, 0.7], [0], [0]]}}
    ],
    "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 12}}
  })");
  for (const HorizonCheck& check : CheckFrames(scene, {0, 5}, 50)) {
    EXPECT_LE(check.needless, check.changed / 2);  // 74 and 62; 318 and 291 without the rule
  }
}

// The same rule where the light faces the spheres but other moving spheres block it: a
// ball floating between the light and two moving spheres casts its shadow on them, then
// drifts off, so the shadowed sides come into the light part by part.
TEST(HorizonsTest, ShadowedSidesOfMovingSpheresKeepTheirColourOnlyWhileTheyStayShadowed) {
  Scene scene = Small(R"({
    "camera": {"position": [0, 1, 9], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [0.5, 1.5, 12], "intensity": [300, 300, 300]}],
    )" + std::string(kBallsOnAFloor) + R"(,
      {"type": "sphere", "center": [0, 0, 0], "radius": 1.2, "material": "ball",
       "motion": {"polynomial": [[0, 0.03], [0], [0, 0.1]]}},
      {"type": "sphere", "center": [-2.2, 0, -0.5], "radius": 0.9, "material": "ball",
       "motion": {"polynomial": [[0, -0.04], [0, 0.02], [0, -0.1]]}},
      {"type": "sphere", "center": [0.3, 1.2, 10], "radius": 0.4, "material": "blue",
       "motion": {"polynomial": [[-0.2, 0.06], [0], [0]]}}
    ],
    "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 12}}
  })");
  for (const HorizonCheck& check : CheckFrames(scene, {0, 4}, 50)) {
    // 98 and 64; 230 and 266 when a shadowed side is traced again at every frame.
    EXPECT_LT(check.needless, check.unbounded / 16);
  }
}

// Every frame of an `exact` sequence assembled as the coordinator does (a segment's first
// frame in full, then each frame only the pixels due there, the rest copied). Returns the
// pixels that differ from brute force, and the pixels traced.
struct ExactRun {
  size_t differing = 0, traced = 0, pixels = 0;
};

ExactRun RunExactSequence(const Scene& scene) {
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  Sequence brute = RenderAll(tracer, scene);
  const int first = scene.render.firstFrame, last = scene.render.LastFrame();
  const size_t count = static_cast<size_t>(scene.render.width) * scene.render.height;
  std::vector<int32_t> due(count, first);
  std::vector<float> assembled(count * 3);
  ExactRun run;
  run.pixels = count * scene.render.frameCount;
  for (int frame = first; frame <= last; ++frame) {
    std::vector<uint32_t> pixels;
    for (size_t p = 0; p < count; ++p) {
      if (due[p] == frame) pixels.push_back(static_cast<uint32_t>(p));
    }
    std::vector<float> rgb(pixels.size() * 3);
    std::vector<int32_t> horizons(pixels.size());
    tracer.TracePixels(frame, pixels.data(), pixels.size(), rgb.data(), last - frame, horizons.data());
    for (size_t i = 0; i < pixels.size(); ++i) {
      std::memcpy(&assembled[3 * pixels[i]], &rgb[3 * i], 3 * sizeof(float));
      due[pixels[i]] = frame < last ? horizons[i] : frame + 1;
    }
    run.traced += pixels.size();
    for (size_t p = 0; p < count; ++p) run.differing += !SamePixel(brute.frames[frame - first], assembled, p);
  }
  return run;
}

TEST(HorizonsTest, ExactSequencesOfThePaperAnimationsEqualBruteForce) {
  for (const char* file : kPaperAnimations) {
    ExactRun run = RunExactSequence(PaperAnimation(file, 160, 120, 30));
    EXPECT_EQ(run.differing, 0u) << file;
    EXPECT_LT(run.traced, run.pixels / 3) << file;
  }
}

// Proxy padding, sure-blocked margins and ray offsets all scale with the coordinates: the
// same animation in millimetres or in tens of kilometres keeps every promise, and still
// saves as much.
TEST(HorizonsTest, ExactSequencesAtExtremeScalesEqualBruteForce) {
  const Scene scene = PaperAnimation(kPaperAnimations[1], 96, 72, 16);
  const ExactRun unit = RunExactSequence(scene);
  for (double scale : {1e-3, 1e4}) {
    ExactRun run = RunExactSequence(test::ScaleScene(scene, scale));
    EXPECT_EQ(run.differing, 0u) << "scale " << scale;
    EXPECT_LT(run.traced, unit.traced * 11 / 10) << "scale " << scale;
  }
}

TEST(HorizonsTest, MovingCameraMakesEveryHorizonTheNextFrame) {
  Scene scene = Small(R"({
    "camera": {"position": {"polynomial": [[0, 0.1], [0], [10]]}, "look_at": [0, 0, 0]},
    "shapes": [{"type": "quad", "corner": [-3, -3, 0], "edge_u": [6, 0, 0], "edge_v": [0, 6, 0]}],
    "render": {"width": 16, "height": 12, "frames": {"start": 0, "count": 4}}
  })");
  HorizonCheck check = Check(scene, 0);
  EXPECT_EQ(check.broken, 0u);
  EXPECT_EQ(check.unbounded, 0u);
}

TEST(HorizonsTest, StaticSceneIsValidThroughTheWindow) {
  Scene scene = Small(std::string(R"({
    "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},)") + kBackdropAndLight + R"(
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "mirror"}],
    "render": {"width": 16, "height": 12, "frames": {"start": 0, "count": 5}}
  })");
  HorizonCheck check = Check(scene, 0);
  EXPECT_EQ(check.unbounded, check.pixels);
}

// Tasks split pixel sets arbitrarily: a pixel's horizon, like its colour, must not depend
// on which pixels are traced with it, in what order, or on how many threads.
TEST(HorizonsTest, HorizonsDoNotDependOnTheOtherPixelsOfTheTask) {
  Scene scene = LoadSceneFile("tests/scenes/paper_b_twelve_spheres.json");
  scene.render.width = 64;
  scene.render.height = 48;
  const int frame = 3, window = 20;
  const size_t count = 64 * 48;
  EmbreeDevice device;
  std::vector<uint32_t> all(count);
  std::iota(all.begin(), all.end(), 0u);
  std::vector<float> rgb(count * 3);
  std::vector<int32_t> reference(count);
  {
    TracingThreads pool(1);
    Tracer tracer(device, scene, pool);
    tracer.TracePixels(frame, all.data(), count, rgb.data(), window, reference.data());
  }
  std::mt19937 random(7);
  TracingThreads pool(3);
  Tracer tracer(device, scene, pool);
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<uint32_t> subset = all;
    std::shuffle(subset.begin(), subset.end(), random);
    subset.resize(1 + random() % count);
    std::vector<int32_t> horizons(subset.size());
    std::vector<float> subsetRgb(subset.size() * 3);
    tracer.TracePixels(frame, subset.data(), subset.size(), subsetRgb.data(), window, horizons.data());
    for (size_t i = 0; i < subset.size(); ++i) {
      ASSERT_EQ(horizons[i], reference[subset[i]]) << "pixel " << subset[i];
    }
  }
}

TEST(HorizonsTest, PaperAnimationsKeepEveryPromise) {
  for (const char* file : kPaperAnimations) {
    HorizonCheck check = Check(PaperAnimation(file, 80, 60, 12), 0);
    EXPECT_EQ(check.broken, 0u) << file;
    EXPECT_GT(check.unbounded, check.pixels / 2) << file;
  }
}

}  // namespace
}  // namespace tcfarm

namespace tcfarm {
namespace {

// A bar bound to two joints: triangles 0..7 (its first ring segment) weigh only on joint
// 0, which never moves; triangles 24..31 only on joint 1, which turns from frame 3 on.
Scene TwoJointBar() {
  const test::TubeJson tube = test::SquareTube(4, 0, 0.5, 0, 0.4, -0.2, 0.2, [](int ring) {
    const double second = ring < 2 ? 0 : (ring == 2 ? 0.5 : 1);
    return std::make_pair(std::string("[0, 1, 0, 0]"),
                          "[" + std::to_string(1 - second) + ", " + std::to_string(second) + ", 0, 0]");
  });
  Scene scene = ParseScene(R"({"camera": {"position": [1, 0.2, 6], "look_at": [1, 0.2, 0]},
    "shapes": [{"type": "mesh", "vertices": [)" + tube.vertices + R"(], "triangles": [)" + tube.triangles + R"(],
      "skin": {"joints": [[0, 0, 0], {"translation": [1, 0, 0], "rotation": {"keyframes": [
                 {"frame": 0, "value": [0, 0, 0, 1]}, {"frame": 2, "value": [0, 0, 0, 1]},
                 {"frame": 9, "value": [0, 0, 0.5, 0.8660254]}]}}],
               "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], [1, 0, 0, -1, 0, 1, 0, 0, 0, 0, 1, 0]],
               "vertex_joints": [)" + tube.joints + R"(], "vertex_weights": [)" + tube.weights + R"(]}}],
    "render": {"width": 32, "height": 24, "frames": {"start": 0, "count": 10}}})");
  PrepareForTracing(scene);
  return scene;
}

// The parts of a skin that hold still are still: a surface on them is valid through the
// window; one on the turning part changes when its joint starts to turn, not before.
TEST(HorizonsTest, APartOfASkinThatHoldsStillIsStill) {
  const Scene scene = TwoJointBar();
  EmbreeDevice device;
  SceneGeometry geometry(device, scene);
  HorizonOracle oracle(scene, 0, 9, [&](size_t shape) { return geometry.Deforming(shape); });
  EXPECT_EQ(oracle.SurfaceChange(0, 0), oracle.Unbounded());
  EXPECT_EQ(oracle.SurfaceChange(0, 7), oracle.Unbounded());
  EXPECT_EQ(oracle.SurfaceChange(0, 24), 3);
  EXPECT_EQ(oracle.SurfaceChange(0, 31), 3);
  // Traced at frame 3, when the joint turns every frame: the next frame.
  HorizonOracle later(scene, 3, 6, [&](size_t shape) { return geometry.Deforming(shape); });
  EXPECT_EQ(later.SurfaceChange(0, 24), 4);
  EXPECT_EQ(later.SurfaceChange(0, 0), later.Unbounded());
  // A ray down through the still end meets nothing that moves; one through the turning
  // end does, once it turns (the scene is rebased: the camera at the origin).
  const Float3 camera{1, 0.2f, 6};
  EXPECT_EQ(oracle.FirstMeeting({Float3{0.1f, 3, 0} - camera, {0, -1, 0}, 10}), oracle.Unbounded());
  EXPECT_EQ(oracle.FirstMeeting({Float3{1.9f, 3, 0} - camera, {0, -1, 0}, 10}), 3);
}


// The parts of a skin are bounded each by its own vertices: a ray beside the bar, which
// a sphere around the whole bar would reach, meets none of its parts' bounds, while one
// through the turning end still does.
TEST(HorizonsTest, EachPartOfASkinIsBoundedByItsOwnVertices) {
  const Scene scene = TwoJointBar();
  EmbreeDevice device;
  SceneGeometry geometry(device, scene);
  HorizonOracle oracle(scene, 0, 9, [&](size_t shape) { return geometry.Deforming(shape); });
  const Float3 camera{1, 0.2f, 6};
  // Down in front of the blended ring: the sphere around both turning parts (radius
  // 0.83 about x 1.24 at frame 3) holds it, neither part's own sphere (radius about 0.59)
  // does at any frame.
  EXPECT_EQ(oracle.FirstMeeting({Float3{0.65f, 3, 0.55f} - camera, {0, -1, 0}, 10}), oracle.Unbounded());
  EXPECT_EQ(oracle.FirstMeeting({Float3{1.9f, 3, 0} - camera, {0, -1, 0}, 10}), 3);
}

// A square tube along x from 0 to 4 (320 triangles) on one joint, sliding down from frame
// 1 on, over a floor, under a light: its one part comes in four pieces a unit long.
Scene SlidingTube() {
  const test::TubeJson tube = test::SquareTube(40, 0, 0.1, 0.9, 1.1, -0.1, 0.1, test::OnJointZero);
  Scene scene = Small(std::string(R"({"camera": {"position": [2, 1.5, 6], "look_at": [2, 0.5, 0]},)") +
                      kBackdropAndLight + R"(
    "shapes": [{"type": "quad", "corner": [-4, 0, -3], "edge_u": [12, 0, 0], "edge_v": [0, 0, 6], "material": "wall"},
      {"type": "mesh", "material": "ball", "vertices": [)" + tube.vertices + R"(], "triangles": [)" + tube.triangles + R"(],
      "skin": {"joints": [{"translation": {"keyframes": [{"frame": 0, "value": [0, 0, 0]}, {"frame": 1, "value": [0, 0, 0]},
                                                          {"frame": 9, "value": [0, -0.4, 0]}]}}],
               "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]],
               "vertex_joints": [)" + tube.joints + R"(], "vertex_weights": [)" + tube.weights + R"(]}}],
    "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 10}}})");
  PrepareForTracing(scene);
  return scene;
}

// A part is met where one of its pieces is, not wherever its own sphere reaches: a ray
// down beside the tube, inside the sphere around the whole tube (radius about 2), meets
// none of its pieces at any frame, while one down through it meets it when it first
// moves. Every promise holds against brute force. Of the 3,072 pixels, 270 to 370 are
// due needlessly at each frame (mostly the tube's own flat top, whose shading a slide
// leaves as it is); 1,050 to 1,160 were with the tube's sphere alone.
TEST(HorizonsTest, APartIsMetWhereItsPiecesAreNotWhereverItsSphereReaches) {
  const Scene scene = SlidingTube();
  EmbreeDevice device;
  SceneGeometry geometry(device, scene);
  HorizonOracle oracle(scene, 0, 9, [&](size_t shape) { return geometry.Deforming(shape); });
  const Float3 camera{2, 1.5f, 6};  // the prepared scene is the world less the camera
  EXPECT_EQ(oracle.FirstMeeting({Float3{2, 3, 0.9f} - camera, {0, -1, 0}, 2.5f}), oracle.Unbounded());
  EXPECT_EQ(oracle.FirstMeeting({Float3{2, 3, 0} - camera, {0, -1, 0}, 2.5f}), 2);
  for (int a : {0, 1, 3, 4, 5}) {
    const HorizonCheck check = Check(scene, a);
    EXPECT_EQ(check.broken, 0u) << "frame " << a;
    EXPECT_LT(check.needless, 500u) << "frame " << a;
  }
}

// A long skinned slab sliding along its length under a light, and a camera that sees only
// the floor in its shadow: the shadow rays stay blocked, by the slab's later triangles.
Scene SlabOverItsShadow() {
  const test::TubeJson tube = test::SquareTube(40, -4, 0.2, 1.9, 2.1, -0.6, 0.6, test::OnJointZero);
  Scene scene = Small(R"({"camera": {"position": [0, 1, 1], "look_at": [0, 0, 0.2], "fov_degrees": 10},
    "lights": [{"type": "point", "position": [0, 10, 0], "intensity": [120, 120, 120]}],
    "materials": {"floor": {"diffuse": [0.7, 0.7, 0.65]}},
    "shapes": [{"type": "quad", "corner": [-8, 0, -8], "edge_u": [16, 0, 0], "edge_v": [0, 0, 16], "material": "floor"},
      {"type": "mesh", "vertices": [)" + tube.vertices + R"(], "triangles": [)" + tube.triangles + R"(],
      "skin": {"joints": [{"translation": {"keyframes": [{"frame": 0, "value": [0, 0, 0]}, {"frame": 9, "value": [0.9, 0, 0]}]}}],
               "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]],
               "vertex_joints": [)" + tube.joints + R"(], "vertex_weights": [)" + tube.weights + R"(]}}],
    "render": {"width": 32, "height": 24, "frames": {"start": 0, "count": 10}}})");
  PrepareForTracing(scene);
  return scene;
}

// The slab's shadow rays are followed frame by frame over the frames the geometry keeps
// placed, so nothing is due before the slab's end comes near. When a deforming mesh's
// blocked shadow rays were not followed, every pixel was due at every frame.
TEST(HorizonsTest, BlockedShadowRaysUnderADeformingMeshAreFollowed) {
  const Scene scene = SlabOverItsShadow();
  for (int a : {0, 4}) {
    const HorizonCheck check = Check(scene, a);
    EXPECT_EQ(check.broken, 0u) << "frame " << a;
    EXPECT_EQ(check.changed, 0u) << "frame " << a;
    EXPECT_EQ(check.needless, 0u) << "frame " << a;
    EXPECT_EQ(check.unbounded, check.pixels) << "frame " << a;
  }
}

// Walks place the frames ahead of a deforming mesh, and the geometry keeps only a few:
// while traces jump between frames (segments side by side), the walks would push out the
// frames the other segments trace, so they stop, and the shadow is due at the next frame.
TEST(HorizonsTest, ShadowWalksOverDeformingMeshesStopWhileTracesJumpBetweenFrames) {
  const Scene scene = SlabOverItsShadow();
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  const size_t count = static_cast<size_t>(scene.render.width) * scene.render.height;
  std::vector<uint32_t> pixels(count);
  std::iota(pixels.begin(), pixels.end(), 0u);
  std::vector<float> rgb(count * 3);
  std::vector<int32_t> horizons(count);
  auto dueAt = [&](int frame) {
    tracer.TracePixels(frame, pixels.data(), count, rgb.data(), 9 - frame, horizons.data());
    return std::set<int32_t>(horizons.begin(), horizons.end());
  };
  EXPECT_EQ(dueAt(0), std::set<int32_t>{10});  // walked to the end of the window
  EXPECT_EQ(dueAt(5), std::set<int32_t>{6});   // a jump of 5 frames: not walked
  EXPECT_EQ(dueAt(0), std::set<int32_t>{1});   // and back: not walked
}

// A ball that stops, waits and moves on: at the frames it rests where it was at the traced
// frame it changes nothing, so what is traced during the pause holds until it moves again,
// and every promise holds against brute force.
TEST(HorizonsTest, APauseInAMotionIsNoChange) {
  const Scene scene = Small(std::string(R"({"camera": {"position": [0, 1, 8], "look_at": [0, 1, 0]},)") +
                            kBackdropAndLight + R"(
    "shapes": [{"type": "quad", "corner": [-6, -1, -3], "edge_u": [12, 0, 0], "edge_v": [0, 6, 0], "material": "wall"},
               {"type": "sphere", "center": [0, 1, 0], "radius": 0.6, "material": "ball",
                "motion": {"translation": {"keyframes": [{"frame": 0, "value": [-2, 0, 0]}, {"frame": 3, "value": [0, 0, 0]},
                                                         {"frame": 7, "value": [0, 0, 0]}, {"frame": 9, "value": [1, 0, 0]}]}}}],
    "render": {"width": 48, "height": 36, "frames": {"start": 0, "count": 10}}})");
  HorizonOracle resting(scene, 4, 5);
  EXPECT_EQ(resting.SurfaceChange(1, 0), 8);
  for (size_t offset = 1; offset <= 3; ++offset) EXPECT_LT(resting.MoverAt(0, offset).radius, 0) << offset;
  EXPECT_GT(resting.MoverAt(0, 4).radius, 0);
  for (int a : {0, 3, 4, 6, 7}) {
    const HorizonCheck check = Check(scene, a);
    EXPECT_EQ(check.broken, 0u) << "frame " << a;
    if (a == 4) {
      // Nothing changes before frame 8. Due at the next frame: only the few pixels whose
      // shadow ray grazes the ball's rim, which a blocked ray not surely blocked is taken
      // to clear (HorizonOracle::OnlyTranslatingSpheresMove); all 40 or so while the
      // ball's bounds counted at every frame.
      EXPECT_EQ(check.changed, 0u);
      EXPECT_LE(check.needless, 4u);
    }
  }
}

// A window far longer than a chunk of frames: the meeting found is the real one, late in
// the window, never an offset past a chunk's end (which once wrapped around to frame 0).
TEST(HorizonsTest, LateMeetingsInALongWindowAreFoundWhereTheyAre) {
  Scene scene = ParseScene(R"({"camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
    "shapes": [{"type": "sphere", "center": [-40, 0, 0], "radius": 0.5, "motion": {"polynomial": [[0, 1], [0], [0]]}}],
    "render": {"width": 8, "height": 8, "frames": {"start": 0, "count": 60}}})");
  HorizonOracle oracle(scene, 0, 59);
  // A ray down the y axis at x = 0: the ball's proxy (radius 0.5 and its pad) reaches it
  // at frame 40 - 0.5, so first at frame 40.
  EXPECT_EQ(oracle.FirstMeeting({{0, 5, 0}, {0, -1, 0}, 10}), 40);
  EXPECT_EQ(oracle.FirstMeeting({{30, 5, 0}, {0, -1, 0}, 10}), oracle.Unbounded());
  for (int x = -45; x <= 25; x += 5) {
    const int meeting = oracle.FirstMeeting({{float(x), 5, 0}, {0, -1, 0}, 10});
    EXPECT_GT(meeting, 0) << "x " << x;
    if (x >= -39 && x <= 19) {
      EXPECT_EQ(meeting, x + 40) << "x " << x;
    }
  }
}

// Blocked shadow rays skip ahead over the frames their sphere surely keeps blocking them:
// a run gives the frame that frame-by-frame calls, which cannot skip, give.
TEST(HorizonsTest, SkippingAheadInAShadowStopsWhereFrameByFrameStops) {
  Scene scene = LoadSceneFile("tests/scenes/paper_b_twelve_spheres.json");
  HorizonOracle oracle(scene, 0, scene.render.LastFrame());
  ASSERT_TRUE(oracle.OnlyTranslatingSpheresMove());
  std::mt19937 random(5);
  std::uniform_real_distribution<float> unit(0, 1);
  const Float3 light{5, 6, 9};
  size_t blocked = 0, skipped = 0;
  for (int i = 0; i < 4000; ++i) {
    // From the backdrop toward the light, through where the balls fly.
    const Float3 start{24 * unit(random) - 12, 18 * unit(random) - 9, -3.99f};
    const Float3 toLight = Normalize(light - start);
    const RaySegment ray{start, toLight, Length(light - start)};
    int runHint = -1, stepHint = -1;
    const int run = oracle.FirstNotSurelyBlocked(ray, 1, oracle.Unbounded(), &runHint);
    int stepped = 1;
    while (stepped < oracle.Unbounded() && oracle.FirstNotSurelyBlocked(ray, stepped, stepped + 1, &stepHint) > stepped) {
      ++stepped;
    }
    ASSERT_EQ(run, stepped) << "ray " << i;
    blocked += run > 1;
    skipped += run - 1;
  }
  EXPECT_GT(blocked, 40u) << "some rays should start in a ball's shadow";
  EXPECT_GT(skipped, 200u);
}

}  // namespace
}  // namespace tcfarm
