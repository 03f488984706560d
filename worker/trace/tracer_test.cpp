#include "worker/trace/tracer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>

#include "worker/embree/ray_packets.h"
#include "worker/embree/scene_geometry.h"
#include "worker/shapes/shape_kind.h"
#include "proto/frame/frame_io.h"
#include "tests/support/cpp/scaled_scene.h"

namespace tcfarm {
namespace {

using test::ScaleScene;

std::vector<float> RenderFrame(const Scene& scene, int frame, unsigned threads = 0,
                               RayCounts* counts = nullptr, uint64_t* frameBuilds = nullptr) {
  EmbreeDevice device;
  TracingThreads pool(threads);
  Tracer tracer(device, scene, pool);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  tracer.TraceFrame(frame, rgb.data());
  if (counts) *counts = tracer.Counts();
  if (frameBuilds) *frameBuilds = tracer.FrameBuilds();
  return rgb;
}

size_t DifferingPixels(const std::vector<float>& a, const std::vector<float>& b) {
  size_t differing = 0;
  for (size_t i = 0; i < a.size(); i += 3) {
    differing += std::memcmp(&a[i], &b[i], 3 * sizeof(float)) != 0;
  }
  return differing;
}

double Psnr(const std::vector<float>& a, const std::vector<float>& b) {
  double squared = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    double d = std::clamp(a[i], 0.0f, 1.0f) - std::clamp(b[i], 0.0f, 1.0f);
    squared += d * d;
  }
  double mse = squared / a.size();
  return mse == 0 ? INFINITY : 10 * std::log10(1.0 / mse);
}

// Small versions of the paper's scenes plus a mirror and a glass ball, so every ray type
// and the moving-instance path are exercised.
std::string ShowcaseScene(int width = 96, int height = 72, int samples = 1) {
  return R"({
    "camera": {"position": [0, 1, 9], "look_at": [0, 0, 0], "fov_degrees": 45},
    "lights": [{"type": "point", "position": [4, 6, 7], "intensity": [120, 120, 120]},
               {"type": "directional", "direction": [-1, -2, -1], "intensity": [0.3, 0.3, 0.3]}],
    "materials": {
      "wall": {"diffuse": [0.7, 0.7, 0.65]},
      "mirror": {"diffuse": [0.1, 0.1, 0.1], "reflectivity": 0.8, "specular": [0.5, 0.5, 0.5]},
      "glass": {"diffuse": [0.05, 0.05, 0.05], "transparency": 0.85, "ior": 1.5,
                "specular": [0.6, 0.6, 0.6], "shininess": 80},
      "red": {"diffuse": [0.8, 0.2, 0.2], "specular": [0.3, 0.3, 0.3]}
    },
    "shapes": [
      {"type": "quad", "corner": [-6, -2, -4], "edge_u": [12, 0, 0], "edge_v": [0, 0, 8], "material": "wall"},
      {"type": "quad", "corner": [-6, -2, -4], "edge_u": [12, 0, 0], "edge_v": [0, 9, 0], "material": "wall"},
      {"type": "sphere", "center": [-1.5, -0.8, 0], "radius": 1.2, "material": "mirror"},
      {"type": "sphere", "center": [1.6, -0.9, 1], "radius": 1.0, "material": "glass"},
      {"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": "red",
       "motion": {"polynomial": [[-2, 0.2], [1.5, -0.05], [0, 0.01, 0.001]]}},
      {"type": "mesh", "vertices": [[2, 1, -2], [3.5, 1, -2], [2.7, 2.6, -1.5]],
       "triangles": [[0, 1, 2]], "material": "red"}
    ],
    "background": [0.1, 0.1, 0.2],
    "render": {"width": )" + std::to_string(width) + R"(, "height": )" + std::to_string(height) +
         R"(, "frames": {"start": 0, "count": 20}, "samples_per_pixel": )" +
         std::to_string(samples) + R"(, "max_depth": 4}
  })";
}

// Also far from the origin, where packets of neighbouring rays are hardest to traverse
// together: a pixel's bits may not depend on its packet mates there either, nor on the
// packet's width.
TEST(TracerTest, PixelSubsetsMatchTheFullFrameBitForBit) {
  const std::pair<int, Vec3> cases[] = {{1, {0, 0, 0}}, {4, {0, 0, 0}}, {1, {0, 0, 1e4}}, {1, {3e4, 3e4, 3e4}}};
  for (const auto& [samples, offset] : cases) {
    Scene scene = test::TranslatedScene(ParseScene(ShowcaseScene(98, 72, samples)), offset);
    const int frame = 7;
    std::vector<float> full = RenderFrame(scene, frame);

    EmbreeDevice device;
    std::mt19937 random(42);
    for (unsigned threads : {1u, 2u, 3u}) {
      TracingThreads pool(threads);
      Tracer tracer(device, scene, pool);
      tracer.SetPacketWidth(threads == 2 ? 8 : 16);
      for (int trial = 0; trial < 4; ++trial) {
        // A random subset in random order, so lanes, chunks and threads all differ.
        std::vector<uint32_t> pixels(full.size() / 3);
        std::iota(pixels.begin(), pixels.end(), 0u);
        std::shuffle(pixels.begin(), pixels.end(), random);
        pixels.resize(1 + random() % pixels.size());
        std::vector<float> rgb(pixels.size() * 3);
        tracer.TracePixels(frame, pixels.data(), pixels.size(), rgb.data());
        for (size_t i = 0; i < pixels.size(); ++i) {
          ASSERT_EQ(0, std::memcmp(&rgb[3 * i], &full[3 * pixels[i]], 3 * sizeof(float)))
              << "pixel " << pixels[i] << " traced among " << pixels.size() << " on " << threads
              << " threads, " << tracer.PacketWidth() << "-wide packets, " << samples
              << " samples, scene moved by " << offset.x << ","
              << offset.y << "," << offset.z;
        }
      }
    }
  }
}

// Exact copies a pixel for as long as its horizon says: a horizon may not depend on the
// width of the packet its samples were cast in, any more than the pixel's bits may.
TEST(TracerTest, PacketWidthsGiveTheSameBitsAndHorizons) {
  const Scene scene = ParseScene(ShowcaseScene(98, 72, 2));
  EmbreeDevice device;
  TracingThreads pool(2);
  const int frame = 3, window = 12;
  std::vector<uint32_t> pixels(static_cast<size_t>(scene.render.width) * scene.render.height);
  std::iota(pixels.begin(), pixels.end(), 0u);
  std::vector<float> rgb[2];
  std::vector<int32_t> horizons[2];
  for (int i = 0; i < 2; ++i) {
    Tracer tracer(device, scene, pool);
    tracer.SetPacketWidth(i == 0 ? 8 : 16);
    rgb[i].resize(3 * pixels.size());
    horizons[i].resize(pixels.size());
    tracer.TracePixels(frame, pixels.data(), pixels.size(), rgb[i].data(), window, horizons[i].data());
  }
  EXPECT_EQ(DifferingPixels(rgb[0], rgb[1]), 0u);
  EXPECT_EQ(horizons[0], horizons[1]);
  EXPECT_NE(std::count(horizons[0].begin(), horizons[0].end(), frame + window + 1), 0)
      << "some pixel should stay valid through the window";
  EXPECT_NE(std::count(horizons[0].begin(), horizons[0].end(), frame + 1), 0)
      << "some pixel should change next frame";
  Tracer tracer(device, scene, pool);
  EXPECT_THROW(tracer.SetPacketWidth(4), std::invalid_argument);
}

// The paper's 12 balls before a backdrop that fills the view, moved 1e4 and more from the
// origin, at a width that puts packets of 8 or 16 rays across the image's centre: no ray may
// slip through the backdrop, and no pixel may change with the packet it is traced in.
TEST(TracerTest, FarFromTheOriginPacketsMissNothing) {
  for (Vec3 offset : {Vec3{0, 0, 1e4}, Vec3{3e4, 3e4, 3e4}}) {
    Scene scene = test::TranslatedScene(LoadSceneFile("tests/scenes/paper_b_twelve_spheres.json"), offset);
    scene.render.width = 164;
    scene.render.height = 120;
    std::vector<float> full = RenderFrame(scene, 0);
    const Vec3 background = scene.background;
    size_t holes = 0;
    for (size_t i = 0; i < full.size(); i += 3) {
      holes += full[i] == float(background.x) && full[i + 1] == float(background.y) &&
               full[i + 2] == float(background.z);
    }
    EXPECT_EQ(holes, 0u) << "scene moved by " << offset.z;

    EmbreeDevice device;
    TracingThreads pool(1);
    Tracer tracer(device, scene, pool);
    std::vector<uint32_t> pixels(full.size() / 3);
    for (uint32_t shift = 1; shift < 8; ++shift) {  // every other way to cut rows into packets
      for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<uint32_t>((i + shift) % pixels.size());
      std::vector<float> rgb(full.size());
      tracer.TracePixels(0, pixels.data(), pixels.size(), rgb.data());
      size_t differing = 0;
      for (size_t i = 0; i < pixels.size(); ++i) {
        differing += std::memcmp(&rgb[3 * i], &full[3 * pixels[i]], 3 * sizeof(float)) != 0;
      }
      EXPECT_EQ(differing, 0u) << "packets shifted by " << shift << ", scene moved by " << offset.z;
    }
  }
}

TEST(TracerTest, StillPixelsStayBitIdenticalAcrossFrames) {
  // Only the small red ball moves; the far corner of the wall never sees it.
  Scene scene = ParseScene(ShowcaseScene());
  std::vector<float> a = RenderFrame(scene, 0), b = RenderFrame(scene, 5);
  size_t differing = DifferingPixels(a, b);
  EXPECT_GT(differing, 0u);
  EXPECT_LT(differing, a.size() / 3 / 4);
}

TEST(TracerTest, ScaledScenesRenderTheSameImage) {
  Scene scene = ParseScene(ShowcaseScene(128, 96));
  std::vector<float> reference = RenderFrame(scene, 3);
  for (double s : {1e-3, 1e5}) {
    std::vector<float> scaled = RenderFrame(ScaleScene(scene, s), 3);
    EXPECT_GE(Psnr(reference, scaled), 40.0) << "scale " << s;
  }
}

// The same world far from the origin, moved back onto its camera as the farm's workers and
// the reference renderer do: float rounding stays that of the world at the origin. Moved
// as it is, at 1e5 shadows and refraction already go wrong, and at 1e7 the mirror and the
// glass ball render as background.
TEST(TracerTest, ScenesFarFromTheOriginRenderAsAtTheOrigin) {
  Scene scene = ParseScene(ShowcaseScene(128, 96));
  Scene atOrigin = scene;
  RebaseOnCamera(atOrigin);
  const std::vector<float> reference = RenderFrame(atOrigin, 3);
  for (Vec3 offset : {Vec3{0, 0, 1e4}, Vec3{1e5, 1e5, 1e5}, Vec3{1e7, -1e7, 1e7}}) {
    Scene far = test::TranslatedScene(scene, offset);
    RebaseOnCamera(far);
    const std::vector<float> rgb = RenderFrame(far, 3);
    size_t off = 0;  // pixels more than 5 % away from the reference
    for (size_t i = 0; i < rgb.size(); i += 3) {
      bool pixelOff = false;
      for (int c = 0; c < 3; ++c) {
        pixelOff |= std::fabs(rgb[i + c] - reference[i + c]) > 0.05f * std::max(reference[i + c], 0.05f);
      }
      off += pixelOff;
    }
    EXPECT_LE(off, reference.size() / 3 / 1000) << "moved by " << offset.x;
    EXPECT_GE(Psnr(reference, rgb), 50.0) << "moved by " << offset.x;
  }
}

// A floor lit by a sun 2 degrees above the horizon, with nothing to cast a shadow: every
// floor pixel must get the same light. Self-shadowing (acne) would darken some of them.
TEST(TracerTest, NoShadowAcneAtGrazingLight) {
  for (double s : {1e-3, 1.0, 1e5}) {
    Scene scene = ParseScene(R"({
      "camera": {"position": [0, 3, 10], "look_at": [0, 0, -20], "fov_degrees": 60},
      "lights": [{"type": "directional", "direction": [1, -0.0349, 0.2], "intensity": [1, 1, 1]}],
      "shapes": [{"type": "quad", "corner": [-500, 0, -500], "edge_u": [1000, 0, 0], "edge_v": [0, 0, 1000]}],
      "render": {"width": 160, "height": 120}
    })");
    scene = ScaleScene(scene, s);
    std::vector<float> rgb = RenderFrame(scene, 0);
    float brightest = 0;
    for (float v : rgb) brightest = std::max(brightest, v);
    size_t floorPixels = 0, darkFloorPixels = 0;
    for (size_t i = 0; i < rgb.size(); i += 3) {
      if (rgb[i] == 0) continue;  // background above the horizon
      ++floorPixels;
      darkFloorPixels += rgb[i] < brightest * 0.999f;
    }
    EXPECT_GT(floorPixels, rgb.size() / 3 / 2) << "scale " << s;
    EXPECT_EQ(darkFloorPixels, 0u) << "scale " << s;
  }
}

TEST(TracerTest, LambertQuadMatchesTheClosedForm) {
  Scene scene = ParseScene(R"({
    "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "lights": [{"type": "directional", "direction": [0, 0, -1], "intensity": [2, 1, 0.5]}],
    "materials": {"m": {"diffuse": [0.5, 0.25, 0.1]}},
    "shapes": [{"type": "quad", "corner": [-100, -100, 0], "edge_u": [200, 0, 0], "edge_v": [0, 200, 0], "material": "m"}],
    "render": {"width": 8, "height": 8}
  })");
  std::vector<float> rgb = RenderFrame(scene, 0);
  const float kAmbient = 0.05f;
  for (size_t i = 0; i < rgb.size(); i += 3) {
    EXPECT_NEAR(rgb[i + 0], 0.5f * kAmbient + 0.5f * 2.0f, 1e-5);
    EXPECT_NEAR(rgb[i + 1], 0.25f * kAmbient + 0.25f * 1.0f, 1e-5);
    EXPECT_NEAR(rgb[i + 2], 0.1f * kAmbient + 0.1f * 0.5f, 1e-5);
  }
}

TEST(TracerTest, NoNonFiniteValueReachesAFrame) {
  Scene scene = ParseScene(ShowcaseScene(64, 48, 2));
  for (int frame : {0, 10, 19}) {
    for (float v : RenderFrame(scene, frame)) ASSERT_TRUE(std::isfinite(v) && v >= 0);
  }
}

// A light of intensity 1e30 a micrometre above a floor: the irradiance overflows float.
// Lit pixels saturate at the largest float; they must not come out black.
TEST(TracerTest, LightBeyondFloatRangeSaturates) {
  Scene scene = ParseScene(R"({
    "camera": {"position": [0, 2e-6, 8e-6], "look_at": [0, 0, 0], "fov_degrees": 40},
    "lights": [{"type": "point", "position": [0, 1e-6, 0], "intensity": [1e30, 1e30, 1e30]}],
    "materials": {"m": {"diffuse": [0.5, 0.5, 0.5]}},
    "shapes": [{"type": "quad", "corner": [-1, 0, -1], "edge_u": [0, 0, 2], "edge_v": [2, 0, 0], "material": "m"}],
    "render": {"width": 16, "height": 12}
  })");
  size_t saturated = 0;
  for (float v : RenderFrame(scene, 0)) {
    ASSERT_TRUE(std::isfinite(v) && v >= 0);
    saturated += v == std::numeric_limits<float>::max();
  }
  EXPECT_GT(saturated, 0u);
}

TEST(TracerTest, NoShadowRaysWithoutLights) {
  Scene scene = ParseScene(ShowcaseScene());
  scene.lights.clear();
  RayCounts counts;
  RenderFrame(scene, 0, 0, &counts);
  EXPECT_EQ(counts.shadow, 0u);
  EXPECT_EQ(counts.primary, 96u * 72u);
  EXPECT_GT(counts.reflection, 0u);
}

TEST(TracerTest, NoSecondaryRaysWithoutMirrorsOrGlass) {
  Scene scene = ParseScene(ShowcaseScene());
  for (Material& m : scene.materials) m.As<Phong>().reflectivity = m.As<Phong>().transparency = 0;
  RayCounts counts;
  RenderFrame(scene, 0, 0, &counts);
  EXPECT_EQ(counts.reflection, 0u);
  EXPECT_EQ(counts.refraction, 0u);
  EXPECT_GT(counts.shadow, 0u);
}

TEST(TracerTest, MirrorsAndGlassCastSecondaryRays) {
  RayCounts counts;
  RenderFrame(ParseScene(ShowcaseScene()), 0, 0, &counts);
  EXPECT_GT(counts.reflection, 0u);
  EXPECT_GT(counts.refraction, 0u);
}

TEST(TracerTest, NoPerFramePlacementWhenNothingMoves) {
  Scene scene = ParseScene(ShowcaseScene());
  uint64_t builds = 0;
  RenderFrame(scene, 4, 0, nullptr, &builds);
  EXPECT_EQ(builds, 1u);  // the red ball moves
  for (Shape& shape : scene.shapes) shape.motion = Motion{};
  RenderFrame(scene, 4, 0, nullptr, &builds);
  EXPECT_EQ(builds, 0u);
}

// Robust traversal closes the edges triangles share (a mesh's, a quad's diagonal); a scene
// of spheres alone has none and traces with Embree's faster kernels.
TEST(TracerTest, RobustTraversalWhereShapesShareEdges) {
  const Scene spheres = LoadSceneFile("tests/scenes/paper_b_twelve_spheres.json");
  for (const Shape& shape : spheres.shapes) {
    EXPECT_EQ(HasSharedEdges(shape), shape.type != Shape::Type::kSphere) << shape.name;
  }
  EXPECT_TRUE(NeedsRobustTraversal(spheres));  // its backdrop is a quad
  Scene onlySpheres = spheres;
  onlySpheres.shapes.erase(std::remove_if(onlySpheres.shapes.begin(), onlySpheres.shapes.end(),
                                          [](const Shape& shape) { return shape.type != Shape::Type::kSphere; }),
                           onlySpheres.shapes.end());
  ASSERT_FALSE(onlySpheres.shapes.empty());
  EXPECT_FALSE(NeedsRobustTraversal(onlySpheres));
  EXPECT_TRUE(NeedsRobustTraversal(LoadSceneFile("tests/scenes/paper_c_terrain_flyover.json")));
  EXPECT_TRUE(NeedsRobustTraversal(LoadSceneFile("tests/scenes/valid/quad.json")));
  EXPECT_TRUE(NeedsRobustTraversal(LoadSceneFile("tests/scenes/valid/mesh_with_normals_and_uvs.json")));
  EXPECT_TRUE(NeedsRobustTraversal(LoadSceneFile("tests/scenes/valid/imports_an_obj.json")));
}

// Rays aimed at points of the edge two triangles share (a quad's diagonal, corner + u to
// corner + v), cast as the tracer casts them: 16-wide packets into the frame's scene.
// Returns how many miss.
size_t MissesOnTheSharedEdge(RTCScene scene, const Shape& quad) {
  const Vec3 &corner = quad.corner, &u = quad.edgeU, &v = quad.edgeV;
  std::mt19937 random(7);
  std::uniform_real_distribution<float> along(0.02f, 0.98f), offset(-3, 3), height(3, 8);
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  size_t misses = 0;
  for (int packet = 0; packet < 20000; ++packet) {
    alignas(64) RayPacket<16>::RayHit rays{};
    alignas(64) int valid[16];
    const float ox = offset(random), oy = height(random), oz = offset(random);
    for (int lane = 0; lane < 16; ++lane) {
      const float a = along(random);
      const float px = static_cast<float>(corner.x + u.x) + a * static_cast<float>(v.x - u.x);
      const float py = static_cast<float>(corner.y + u.y) + a * static_cast<float>(v.y - u.y);
      const float pz = static_cast<float>(corner.z + u.z) + a * static_cast<float>(v.z - u.z);
      const float dx = px - ox, dy = py - oy, dz = pz - oz;
      const float length = std::sqrt(dx * dx + dy * dy + dz * dz);
      valid[lane] = -1;
      rays.ray.org_x[lane] = ox, rays.ray.org_y[lane] = oy, rays.ray.org_z[lane] = oz;
      rays.ray.dir_x[lane] = dx / length, rays.ray.dir_y[lane] = dy / length, rays.ray.dir_z[lane] = dz / length;
      rays.ray.tnear[lane] = 0;
      rays.ray.tfar[lane] = std::numeric_limits<float>::infinity();
      rays.ray.mask[lane] = ~0u;
      rays.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
    }
    RayPacket<16>::Intersect(valid, scene, &context, &rays);
    for (int lane = 0; lane < 16; ++lane) misses += rays.hit.geomID[lane] == RTC_INVALID_GEOMETRY_ID;
  }
  return misses;
}

// What robust traversal buys: no ray aimed at a quad's diagonal slips between its two
// triangles. The same rays into a scene without it find the crack, so the check can fail.
TEST(TracerTest, NoRaySlipsThroughAQuadsDiagonal) {
  Scene scene = ParseScene(R"({
    "camera": {"position": [0, 5, 0], "look_at": [0, 0, 0.1]},
    "shapes": [{"type": "quad", "corner": [-10.3, -1, -7.1], "edge_u": [20.1, 0.3, -1.2],
                "edge_v": [1.4, 0.2, 20.3]}],
    "render": {"width": 4, "height": 4}
  })");
  EmbreeDevice device;
  SceneGeometry geometry(device, scene);
  const Shape& quad = scene.shapes[0];
  EXPECT_EQ(MissesOnTheSharedEdge(geometry.ForFrame(0)->scene(), quad), 0u);

  RTCScene fast = rtcNewScene(device.get());  // Embree's default flags
  RTCGeometry geometryOfQuad = KindOf(quad).NewGeometry(device.get(), quad);
  rtcCommitGeometry(geometryOfQuad);
  rtcAttachGeometry(fast, geometryOfQuad);
  rtcReleaseGeometry(geometryOfQuad);
  rtcCommitScene(fast);
  EXPECT_GT(MissesOnTheSharedEdge(fast, quad), 0u);
  rtcReleaseScene(fast);
}

TEST(TracerTest, MovingShapeIsPlacedAtItsFramePosition) {
  // A ball moving right across a dark background: its image moves right.
  Scene scene = ParseScene(R"({
    "camera": {"position": [0, 0, 10], "look_at": [0, 0, 0]},
    "lights": [{"type": "directional", "direction": [0, 0, -1], "intensity": [1, 1, 1]}],
    "shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 0.5,
                "motion": {"keyframes": [{"frame": 0, "value": [-2, 0, 0]}, {"frame": 10, "value": [2, 0, 0]}]}}],
    "render": {"width": 64, "height": 16, "frames": {"start": 0, "count": 11}}
  })");
  auto centroidX = [&](int frame) {
    std::vector<float> rgb = RenderFrame(scene, frame);
    double sum = 0, count = 0;
    for (size_t i = 0; i < rgb.size(); i += 3) {
      if (rgb[i] > 0) sum += (i / 3) % 64, ++count;
    }
    return sum / count;
  };
  EXPECT_LT(centroidX(0), 28);
  EXPECT_NEAR(centroidX(5), 31.5, 1.0);
  EXPECT_GT(centroidX(10), 35);
}

// A build asked to stop gives up with BuildStopped, whichever step it is at: generating
// terrain (the parse's checkpoint) or building the tracer; left alone, the same scene builds.
TEST(TracerTest, ABuildAskedToStopGivesUp) {
  const std::string json = R"({"camera": {"position": [0, 5, 10], "look_at": [0, 0, 0]},
    "shapes": [{"type": "terrain", "origin": [-5, 0, -5], "size": [10, 10], "cells": [64, 64]},
               {"type": "sphere", "center": [0, 1, 0], "radius": 1}],
    "render": {"width": 8, "height": 8}})";
  std::atomic<bool> stop{true};
  EXPECT_THROW(ParseScene(json, std::nullopt, [&stop] { ThrowIfStopRequested(&stop); }), BuildStopped);
  Scene scene = ParseScene(json);
  PrepareForTracing(scene);
  EmbreeDevice device;
  TracingThreads pool(1);
  EXPECT_THROW(Tracer(device, scene, pool, &stop), BuildStopped);
  stop = false;
  Tracer tracer(device, scene, pool, &stop);
  EXPECT_EQ(&tracer.scene(), &scene);
}

}  // namespace
}  // namespace tcfarm
