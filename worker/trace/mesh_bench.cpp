// A real shot's load: about 100,000 triangles of smooth meshes that move and turn over a
// floor, 640x480, one point light. The tracer's time per frame beside a bare Embree loop
// over the very same triangles and placements (primary packets as wide as the tracer's, one shadow ray,
// Phong with Embree's own normals; trace/bare_embree_loop.h): the price of everything the
// tracer adds (exact normals, smooth shading, ties, horizons bookkeeping, ray counting).
//   build/worker/mesh_bench [--benchmark_min_time=2]
#include <benchmark/benchmark.h>

#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "worker/embree/device.h"
#include "worker/embree/scene_geometry.h"
#include "proto/scene/scene.h"
#include "worker/trace/bare_embree_loop.h"
#include "worker/trace/tracer.h"
#include "worker/util/tracing_threads.h"

namespace tcfarm {
namespace {

constexpr int kMeshes = 8;
constexpr int kRings = 80, kSegments = 80;  // 2 * 80 * 80 = 12,800 triangles a mesh

// The geometry of a UV sphere of `radius` at `center`, smooth (vertex normals): the
// members "vertices", "normals" and "triangles" of a scene mesh, 2 * rings * segments triangles.
std::string SphereGeometry(double cx, double cy, double cz, double radius, int rings = kRings,
                           int segments = kSegments) {
  std::string vertices, normals, triangles;
  for (int ring = 0; ring <= rings; ++ring) {
    const double theta = M_PI * ring / rings;
    for (int segment = 0; segment <= segments; ++segment) {
      const double phi = 2 * M_PI * segment / segments;
      const double nx = std::sin(theta) * std::cos(phi), ny = std::cos(theta), nz = std::sin(theta) * std::sin(phi);
      vertices += (vertices.empty() ? "" : ",") + std::string("[") + std::to_string(cx + radius * nx) + "," +
                  std::to_string(cy + radius * ny) + "," + std::to_string(cz + radius * nz) + "]";
      normals += (normals.empty() ? "" : ",") + std::string("[") + std::to_string(nx) + "," + std::to_string(ny) + "," +
                 std::to_string(nz) + "]";
    }
  }
  auto at = [&](int ring, int segment) { return ring * (segments + 1) + segment; };
  for (int ring = 0; ring < rings; ++ring) {
    for (int segment = 0; segment < segments; ++segment) {
      const int a = at(ring, segment), b = at(ring + 1, segment), c = at(ring + 1, segment + 1), d = at(ring, segment + 1);
      triangles += (triangles.empty() ? "" : ",") + std::string("[") + std::to_string(a) + "," + std::to_string(b) + "," +
                   std::to_string(c) + "],[" + std::to_string(a) + "," + std::to_string(c) + "," + std::to_string(d) + "]";
    }
  }
  return R"("vertices": [)" + vertices + R"(], "normals": [)" + normals + R"(], "triangles": [)" + triangles + "]";
}

std::string SphereMesh(double cx, double cy, double cz, double radius, int index) {
  const std::string spin = std::to_string(3 + index);
  return R"({"type": "mesh", "material": "clay", )" + SphereGeometry(cx, cy, cz, radius) +
         R"(, "motion": {"translation": {"polynomial": [[0, 0.02], [0], [0]]},
         "rotation": {"axis": [0.2, 1, 0.1], "degrees_per_frame": )" + spin + R"(}, "pivot": [)" + std::to_string(cx) +
         "," + std::to_string(cy) + "," + std::to_string(cz) + "]}}";
}

Scene MovingMeshes() {
  std::string shapes = R"({"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0], "material": "clay"})";
  for (int i = 0; i < kMeshes; ++i) {
    shapes += "," + SphereMesh(-3.5 + i % 4 * 2.3, 0.9, -1 - i / 4 * 2.5, 0.85, i);
  }
  Scene scene = ParseScene(R"({"camera": {"position": [0, 3, 7], "look_at": [0, 0.8, -1.5]},
    "lights": [{"type": "point", "position": [3, 8, 4], "intensity": [80, 80, 80]}],
    "materials": {"clay": {"diffuse": [0.7, 0.6, 0.5]}},
    "shapes": [)" + shapes + R"(], "render": {"width": 640, "height": 480, "frames": {"start": 0, "count": 48}}})");
  PrepareForTracing(scene);
  return scene;
}

const Scene& SharedScene() {
  static const Scene scene = MovingMeshes();
  return scene;
}

// One full frame per iteration, the scene's frames in turn; `report` reads the tracer after.
void TraceFramesInTurn(benchmark::State& state, const Scene& scene, const std::function<void(const Tracer&)>& report) {
  EmbreeDevice device;
  TracingThreads threads;
  Tracer tracer(device, scene, threads);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  int frame = 0;
  for (auto _ : state) {
    tracer.TraceFrame(frame, rgb.data());
    benchmark::DoNotOptimize(rgb.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  report(tracer);
}

void TraceMovingMeshes(benchmark::State& state) {
  const Scene& scene = SharedScene();
  TraceFramesInTurn(state, scene, [](const Tracer&) {});
  size_t triangles = 0;
  for (const Shape& shape : scene.shapes) triangles += shape.Mesh().triangles.size();
  state.counters["triangles"] = static_cast<double>(triangles);
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}

// The same frames with nothing but Embree (trace/bare_embree_loop.h): each mesh in its own
// scene, instanced per frame at its motion's matrix into a top level over the still floor,
// as the tracer places them.
void TraceMovingMeshesBare(benchmark::State& state) {
  const Scene& scene = SharedScene();
  EmbreeDevice device;
  TracingThreads threads;
  BareEmbreeLoop bare(device.get(), scene);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  int frame = 0;
  for (auto _ : state) {
    bare.TraceFrame(frame, threads, rgb.data());
    benchmark::DoNotOptimize(rgb.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}

// --- shared meshes -------------------------------------------------------------------
// N placements of one 10,082-triangle mesh (a UV sphere of 71 x 71), written inline in
// every shape or once in the scene's "meshes": the scene JSON a worker receives, and what
// it takes to parse, prepare and build the tracer's geometry (time, and heap bytes still
// held once built). Moving placements turn; still ones stand on a grid.
//   build/worker/mesh_bench --benchmark_filter=Placements

constexpr int kPlacementRings = 71, kPlacementSegments = 71;

std::string PlacementsScene(int placements, bool shared, bool moving) {
  const std::string geometry = SphereGeometry(0, 0, 0, 0.4, kPlacementRings, kPlacementSegments);
  std::string shapes;
  for (int i = 0; i < placements; ++i) {
    const std::string at = "[" + std::to_string(i % 25 - 12) + ", 0.5, " + std::to_string(-i / 25) + "]";
    const std::string motion = moving ? R"({"translation": )" + at +
                                            R"(, "rotation": {"axis": [0, 1, 0], "degrees_per_frame": 5}})"
                                      : at;
    shapes += std::string(i ? "," : "") + R"({"type": "mesh", )" +
              (shared ? R"("mesh_ref": "ball")" : geometry) + R"(, "motion": )" + motion + "}";
  }
  const std::string meshes = shared ? R"("meshes": {"ball": {)" + geometry + "}}," : "";
  return R"({"camera": {"position": [0, 6, 12], "look_at": [0, 0, -5]}, )" + meshes + R"( "shapes": [)" + shapes +
         R"(], "render": {"width": 64, "height": 48, "frames": {"start": 0, "count": 8}}})";
}

size_t HeapBytesInUse() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

// Arguments: placements, shared (0 inline, 1 shared), moving (0 still, 1 moving).
void BuildPlacements(benchmark::State& state) {
  const int placements = static_cast<int>(state.range(0));
  const bool shared = state.range(1) != 0, moving = state.range(2) != 0;
  const std::string text = PlacementsScene(placements, shared, moving);
  EmbreeDevice device;
  TracingThreads threads;
  double heldBytes = 0;
  for (auto _ : state) {
    const size_t before = HeapBytesInUse();
    Scene scene = ParseScene(text);
    PrepareForTracing(scene);
    Tracer tracer(device, scene, threads);
    heldBytes = static_cast<double>(HeapBytesInUse() - before);
    benchmark::DoNotOptimize(&tracer);
  }
  state.counters["scene_json_MB"] = static_cast<double>(text.size()) / 1e6;
  state.counters["held_MB"] = heldBytes / 1e6;
}

// --- a skinned mesh --------------------------------------------------------------------
// A smooth UV sphere of 2 x 160 x 160 = 51,200 triangles bound to two joints, its upper
// half bending about the centre over 1,000 frames, over a still floor: what posing a frame
// costs (every vertex skinned in double, the tree refit) beside tracing the frame.
//   build/worker/mesh_bench --benchmark_filter=Skinned

constexpr int kSkinnedRings = 160, kSkinnedSegments = 160, kSkinnedFrames = 1000;

Scene SkinnedSphereScene() {
  std::string joints, weights;
  for (int ring = 0; ring <= kSkinnedRings; ++ring) {
    // Upper rings to the bending joint, lower ones to the still one, a band blending them.
    const double upper = std::clamp((kSkinnedRings / 2.0 + 8 - ring) / 16.0, 0.0, 1.0);
    for (int segment = 0; segment <= kSkinnedSegments; ++segment) {
      joints += std::string(joints.empty() ? "" : ",") + "[0, 1, 0, 0]";
      weights += std::string(weights.empty() ? "" : ",") + "[" + std::to_string(1 - upper) + ", " +
                 std::to_string(upper) + ", 0, 0]";
    }
  }
  Scene scene = ParseScene(R"({"camera": {"position": [0, 3, 7], "look_at": [0, 0.8, -1.5]},
    "lights": [{"type": "point", "position": [3, 8, 4], "intensity": [80, 80, 80]}],
    "materials": {"clay": {"diffuse": [0.7, 0.6, 0.5]}},
    "shapes": [{"type": "quad", "corner": [-20, 0, -20], "edge_u": [0, 0, 40], "edge_v": [40, 0, 0], "material": "clay"},
      {"type": "mesh", "material": "clay", )" + SphereGeometry(0, 1.2, -1.5, 1.1, kSkinnedRings, kSkinnedSegments) +
      R"(, "skin": {"joints": [[0, 0, 0], {"translation": [0, 1.2, -1.5],
            "rotation": {"axis": [0, 0, 1], "degrees_per_frame": 0.05}}],
          "inverse_bind_matrices": [[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], [1, 0, 0, 0, 0, 1, 0, -1.2, 0, 0, 1, 1.5]],
          "vertex_joints": [)" + joints + R"(], "vertex_weights": [)" + weights + R"(]}}],
    "render": {"width": 640, "height": 480, "frames": {"start": 0, "count": )" + std::to_string(kSkinnedFrames) + "}}}");
  PrepareForTracing(scene);
  return scene;
}

const Scene& SkinnedScene() {
  static const Scene scene = SkinnedSphereScene();
  return scene;
}

// Posing alone: each iteration a frame not posed before (the frames cached are far fewer
// than the animation's), so every vertex is skinned and the tree refit.
void PoseSkinnedMesh(benchmark::State& state) {
  const Scene& scene = SkinnedScene();
  EmbreeDevice device;
  SceneGeometry geometry(device, scene);
  int frame = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(geometry.ForFrame(frame).get());
    frame = (frame + 1) % kSkinnedFrames;
  }
  const SceneGeometry::DeformationWork work = geometry.DeformationCounts();
  state.counters["triangles"] = static_cast<double>(scene.shapes[1].Mesh().triangles.size());
  state.counters["vertices/pose"] = static_cast<double>(work.verticesDeformed) / std::max<uint64_t>(work.posesComputed, 1);
}

// The whole frame: posing and tracing, 640x480.
void TraceSkinnedMesh(benchmark::State& state) {
  TraceFramesInTurn(state, SkinnedScene(), [&](const Tracer& tracer) {
    state.counters["poses"] = static_cast<double>(tracer.DeformationCounts().posesComputed);
  });
}

BENCHMARK(PoseSkinnedMesh)->Name("SkinnedMeshPose")->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(TraceSkinnedMesh)->Name("SkinnedMeshFrame")->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

BENCHMARK(BuildPlacements)
    ->ArgsProduct({{10, 100}, {0, 1}, {0, 1}})
    ->Args({500, 1, 1})  // a forest only sharing can afford (inline: ~240 MB of JSON)
    ->ArgNames({"placements", "shared", "moving"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

BENCHMARK(TraceMovingMeshes)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(TraceMovingMeshesBare)->Name("BareEmbreeLoop")->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
}  // namespace tcfarm

BENCHMARK_MAIN();
