// What a worker pays before its first task on a scene of many spheres: parsing the scene
// JSON, preparing it, building the tracer (Embree trees, the tie-candidate tests), then a
// 32x24 first frame with horizons over the scene's 8 frames. One sphere in a hundred
// moves, each with a radius of its own; the still ones share one radius but no centre, so
// no test can stop early at a coinciding pair.
//   build/worker/scene_build_bench [--benchmark_filter=BuildSpheres/200000]
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "worker/embree/device.h"
#include "worker/embree/tie_candidates.h"
#include "proto/scene/scene.h"
#include "worker/trace/tracer.h"
#include "worker/util/tracing_threads.h"

namespace tcfarm {
namespace {

std::string Number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", value);
  return text;
}

// `count` spheres over a square floor that grows with them, one in each unit cell of a
// grid, jittered within it: none can be taken for another at the comparison grid's
// tolerance (1e-5 of the coordinates, 2e-3 at 200,000 spheres).
std::string ManySpheresJson(int count) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  const int columns = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count))));
  std::string shapes = R"({"type": "quad", "corner": [-1000, 0, -1000], "edge_u": [0, 0, 2000], "edge_v": [2000, 0, 0]})";
  for (int i = 0; i < count; ++i) {
    const double x = i % columns - columns / 2 + jitter(random), z = -(i / columns) + jitter(random);
    const bool moves = i % 100 == 0;
    const double radius = moves ? 0.4 + 1e-4 * (i / 100) : 0.25;
    shapes += R"(, {"type": "sphere", "center": [)" + Number(x) + ", " + Number(radius) + ", " + Number(z) +
              R"(], "radius": )" + Number(radius);
    if (moves) shapes += R"(, "motion": {"polynomial": [[0, 0.05], [0], [0]]})";
    shapes += "}";
  }
  return R"({"camera": {"position": [0, 6, 8], "look_at": [0, 0, -10]},
    "lights": [{"type": "point", "position": [3, 30, 4], "intensity": [900, 900, 900]}],
    "shapes": [)" + shapes + R"(], "render": {"width": 32, "height": 24, "frames": {"start": 0, "count": 8}}})";
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void BuildSpheres(benchmark::State& state) {
  const std::string json = ManySpheresJson(static_cast<int>(state.range(0)));
  EmbreeDevice device;
  TracingThreads threads;
  std::vector<uint32_t> pixels(32 * 24);
  std::iota(pixels.begin(), pixels.end(), 0u);
  std::vector<float> rgb(pixels.size() * 3);
  std::vector<int32_t> horizons(pixels.size());
  double parse = 0, build = 0, firstFrame = 0;
  bool tieRule = false;
  for (auto _ : state) {
    auto start = std::chrono::steady_clock::now();
    Scene scene = ParseScene(json);
    PrepareForTracing(scene);
    parse += SecondsSince(start);
    start = std::chrono::steady_clock::now();
    Tracer tracer(device, scene, threads);
    build += SecondsSince(start);
    start = std::chrono::steady_clock::now();
    tracer.TracePixels(0, pixels.data(), pixels.size(), rgb.data(), 7, horizons.data());
    firstFrame += SecondsSince(start);
    benchmark::DoNotOptimize(rgb.data());
    state.PauseTiming();
    tieRule = SceneMayTie(scene);  // the answer the build used, shown beside its cost
    state.ResumeTiming();
  }
  const double runs = static_cast<double>(state.iterations());
  state.counters["parse_s"] = parse / runs;
  state.counters["tracer_build_s"] = build / runs;
  state.counters["first_frame_s"] = firstFrame / runs;
  state.counters["tie_rule"] = tieRule;
}
BENCHMARK(BuildSpheres)->Arg(10000)->Arg(40000)->Arg(200000)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace tcfarm

BENCHMARK_MAIN();
