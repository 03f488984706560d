// Shaded frames per second of the paper's three animations at their full resolution
// (640x480, one sample, primary + shadow rays, Phong), on all cores. Each iteration
// traces the next frame of the sequence, so per-frame placement of moving shapes and
// camera motion are part of the figure. TracerAgainstBareEmbree holds each scene's frames
// to a bare Embree loop over the same primitives and rays (trace/bare_embree_loop.h).
//   build/worker/tracer_bench [--benchmark_min_time=2]
//   build/worker/tracer_bench --benchmark_filter=TracerAgainstBareEmbree
//   build/worker/tracer_bench --gltf=FILE.gltf --benchmark_filter=gltf   (glTF's materials, 1280x720)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <string>
#include <string_view>
#include <random>
#include <vector>

#include "worker/embree/device.h"
#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"
#include "worker/trace/bare_embree_loop.h"
#include "worker/trace/tracer.h"
#include "worker/util/tracing_threads.h"

#ifndef TCFARM_SCENES_DIR
#error "TCFARM_SCENES_DIR must name tests/scenes"
#endif

namespace tcfarm {
namespace {

double ElapsedSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double ProcessCpuSeconds() {
  timespec now{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

void TraceSceneFrames(benchmark::State& state, const std::string& file) {
  Scene scene = LoadSceneFile(std::string(TCFARM_SCENES_DIR) + "/" + file);
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  int frame = 0;
  for (auto _ : state) {
    tracer.TraceFrame(scene.render.firstFrame + frame, rgb.data());
    benchmark::DoNotOptimize(rgb.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  RayCounts rays = tracer.Counts();
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
  state.counters["Mrays/s"] =
      benchmark::Counter(rays.Total() / 1e6, benchmark::Counter::kIsRate);
  state.counters["threads"] = pool.ThreadCount();
}

// The same, also computing every pixel's validity horizon over the rest of the sequence
// (what `exact` asks of a segment's first frame): the price of the horizons.
void TraceSceneFramesWithHorizons(benchmark::State& state, const std::string& file) {
  Scene scene = LoadSceneFile(std::string(TCFARM_SCENES_DIR) + "/" + file);
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  size_t pixels = static_cast<size_t>(scene.render.width) * scene.render.height;
  std::vector<uint32_t> indices(pixels);
  for (size_t i = 0; i < pixels; ++i) indices[i] = static_cast<uint32_t>(i);
  std::vector<float> rgb(pixels * 3);
  std::vector<int32_t> horizons(pixels);
  int frame = 0;
  for (auto _ : state) {
    int absolute = scene.render.firstFrame + frame;
    int window = std::max(1, scene.render.LastFrame() - absolute);
    tracer.TracePixels(absolute, indices.data(), pixels, rgb.data(), window, horizons.data());
    benchmark::DoNotOptimize(horizons.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}

// A frame's pixel set is traced in tasks of at most this many pixels, as the farm cuts it
// for one worker (PlannerOptions::maxTaskPixels).
constexpr size_t kTaskPixels = 16384;

// The pixel sets of a whole `exact` sequence, frame by frame: frame 0 in full, then each
// frame only the pixels whose horizon it is.
// A scene of tests/scenes by its name, or any scene file by its path (--exact-scene).
Scene BenchScene(const std::string& file) {
  if (std::filesystem::exists(file)) return ImportScene(file, ImportOptions{});
  return LoadSceneFile(std::string(TCFARM_SCENES_DIR) + "/" + file);
}

std::vector<std::vector<uint32_t>> ExactPixelSets(Tracer& tracer, const Scene& scene) {
  const size_t pixels = static_cast<size_t>(scene.render.width) * scene.render.height;
  const int first = scene.render.firstFrame, last = scene.render.LastFrame();
  std::vector<std::vector<uint32_t>> sets;
  std::vector<int32_t> next(pixels, first);  // frame at which each pixel is traced next
  std::vector<float> rgb;
  std::vector<int32_t> horizons;
  for (int frame = first; frame <= last; ++frame) {
    std::vector<uint32_t>& indices = sets.emplace_back();
    for (size_t p = 0; p < pixels; ++p) {
      if (next[p] == frame) indices.push_back(static_cast<uint32_t>(p));
    }
    rgb.resize(indices.size() * 3);
    horizons.resize(indices.size());
    int window = last - frame;
    for (size_t task = 0; task < indices.size(); task += kTaskPixels) {
      const size_t count = std::min(kTaskPixels, indices.size() - task);
      tracer.TracePixels(frame, indices.data() + task, count, rgb.data() + 3 * task, window,
                         window > 0 ? horizons.data() + task : nullptr);
    }
    for (size_t i = 0; window > 0 && i < indices.size(); ++i) next[indices[i]] = horizons[i];
  }
  return sets;
}

double TracedRatio(const std::vector<std::vector<uint32_t>>& sets, const Scene& scene) {
  size_t traced = 0;
  for (const auto& set : sets) traced += set.size();
  return double(traced) / (double(scene.render.width) * scene.render.height * sets.size());
}

// The tracing threads' CPU seconds (what the farm's jobs report) for every frame in full.
double BruteForceCpuSeconds(Tracer& tracer, const Scene& scene) {
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  const double before = tracer.CpuSeconds();
  for (int f = scene.render.firstFrame; f <= scene.render.LastFrame(); ++f) tracer.TraceFrame(f, rgb.data());
  return tracer.CpuSeconds() - before;
}

// A whole `exact` sequence in one process, without the farm, in tasks as one worker gets
// them. cpu_ratio: its tracing threads' CPU over brute force's in the same process, as
// the farm prices a job (stats.cost); the process's time also holds the bookkeeping.
void TraceExactSequence(benchmark::State& state, const std::string& file) {
  Scene scene = BenchScene(file);
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  const double bruteForce = BruteForceCpuSeconds(tracer, scene);
  std::vector<std::vector<uint32_t>> sets;
  const double before = tracer.CpuSeconds();
  for (auto _ : state) sets = ExactPixelSets(tracer, scene);
  state.counters["cpu_ratio"] = (tracer.CpuSeconds() - before) / state.iterations() / bruteForce;
  state.counters["traced_ratio"] = TracedRatio(sets, scene);
  state.counters["frames/s"] = benchmark::Counter(state.iterations() * scene.render.frameCount,
                                                  benchmark::Counter::kIsRate);
}

// Where exact's cost goes, each part against brute force, measured interleaved frame by
// frame in one process so that the machine's drift falls on all of them alike: every
// frame traced in full (brute force), its exact pixel set traced with horizons (exact)
// and again without (sets). horizons = exact - sets: what the horizons cost.
void ExactCostInParts(benchmark::State& state, const std::string& file) {
  Scene scene = BenchScene(file);
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  const std::vector<std::vector<uint32_t>> sets = ExactPixelSets(tracer, scene);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  std::vector<int32_t> horizons(rgb.size() / 3);
  double bruteForce = 0, exact = 0, alone = 0;
  auto cpu = [&](auto trace) {
    const double before = tracer.CpuSeconds();
    trace();
    return tracer.CpuSeconds() - before;
  };
  for (auto _ : state) {
    for (size_t f = 0; f < sets.size(); ++f) {
      const int frame = scene.render.firstFrame + static_cast<int>(f);
      const int window = scene.render.LastFrame() - frame;
      const std::vector<uint32_t>& set = sets[f];
      bruteForce += cpu([&] { tracer.TraceFrame(frame, rgb.data()); });
      for (const bool withHorizons : {true, false}) {
        (withHorizons ? exact : alone) += cpu([&] {
          for (size_t task = 0; task < set.size(); task += kTaskPixels) {
            tracer.TracePixels(frame, set.data() + task, std::min(kTaskPixels, set.size() - task),
                               rgb.data() + 3 * task, withHorizons ? window : 0,
                               withHorizons && window > 0 ? horizons.data() + task : nullptr);
          }
        });
      }
    }
  }
  state.counters["exact"] = exact / bruteForce;
  state.counters["sets"] = alone / bruteForce;
  state.counters["horizons"] = (exact - alone) / bruteForce;
  state.counters["traced_ratio"] = TracedRatio(sets, scene);
}

// How near `exact` comes to tracing only what changes. Brute force decides: a pixel
// "changes" at frame f when its value differs from frame f-1; a trace after the first
// frame is needless when the pixel did not change. Missed changes would be errors (the
// tests hold them at 0); they are counted here too.
void ExactNeedlessTraces(benchmark::State& state, const std::string& file) {
  Scene scene = BenchScene(file);
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  const size_t pixels = static_cast<size_t>(scene.render.width) * scene.render.height;
  size_t traced = 0, changed = 0, needless = 0, missed = 0;
  for (auto _ : state) {
    const std::vector<std::vector<uint32_t>> sets = ExactPixelSets(tracer, scene);
    std::vector<float> previous(3 * pixels), current(3 * pixels);
    tracer.TraceFrame(scene.render.firstFrame, previous.data());
    traced = changed = needless = missed = 0;
    for (size_t f = 1; f < sets.size(); ++f) {
      tracer.TraceFrame(scene.render.firstFrame + static_cast<int>(f), current.data());
      std::vector<bool> inSet(pixels, false);
      for (uint32_t p : sets[f]) inSet[p] = true;
      for (size_t p = 0; p < pixels; ++p) {
        bool differs = !std::equal(&previous[3 * p], &previous[3 * p] + 3, &current[3 * p]);
        changed += differs;
        traced += inSet[p];
        needless += inSet[p] && !differs;
        missed += differs && !inSet[p];
      }
      std::swap(previous, current);
    }
  }
  state.counters["traced_after_first"] = static_cast<double>(traced);
  state.counters["changed"] = static_cast<double>(changed);
  state.counters["needless"] = static_cast<double>(needless);
  state.counters["missed"] = static_cast<double>(missed);
}

// Per-pixel cost of pixel sets of one frame of the 12-sphere animation: a full frame, three
// sparse patterns, and the set `exact` traces at frame 30. Sparseness itself costs
// nothing; exact's pixels cost more because they are the dear ones (moving spheres,
// shadow edges).
// kSpotCheck: one pixel in a hundred at random, as a spot check of a frame asks (verification.h).
enum class Subset { kFull, kCheckerboard, kEveryOtherRow, kTiles16, kExactAt30, kSpotCheck };

void TraceSubsetsOfAFrame(benchmark::State& state, Subset subset) {
  Scene scene = LoadSceneFile(std::string(TCFARM_SCENES_DIR) + "/paper_b_twelve_spheres.json");
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  const int frame = 30;
  std::vector<uint32_t> pixels;
  if (subset == Subset::kExactAt30) {
    pixels = ExactPixelSets(tracer, scene)[frame - scene.render.firstFrame];
  } else if (subset == Subset::kSpotCheck) {
    std::mt19937 random(1);
    for (uint32_t p = 0; p < static_cast<uint32_t>(scene.render.width * scene.render.height); ++p) {
      if (random() % 100 == 0) pixels.push_back(p);
    }
  } else {
    for (uint32_t y = 0; y < static_cast<uint32_t>(scene.render.height); ++y) {
      for (uint32_t x = 0; x < static_cast<uint32_t>(scene.render.width); ++x) {
        bool keep = subset == Subset::kFull || (subset == Subset::kCheckerboard && (x + y) % 2 == 0) ||
                    (subset == Subset::kEveryOtherRow && y % 2 == 0) ||
                    (subset == Subset::kTiles16 && (x / 16 + y / 16) % 2 == 0);
        if (keep) pixels.push_back(y * scene.render.width + x);
      }
    }
  }
  std::vector<float> rgb(pixels.size() * 3);
  for (auto _ : state) tracer.TracePixels(frame, pixels.data(), pixels.size(), rgb.data());
  state.counters["ns/pixel"] = benchmark::Counter(
      double(state.iterations()) * pixels.size(), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// The tracer's time per frame beside the bare loop's, frame by frame in turns so that both
// see the same load from whatever else shares the cores: tracer_ms, bare_ms and their
// ratio in elapsed time, and the same in the process's CPU time (cpu_ratio; time the
// threads wait for the cores does not count there); bare_tracer_flags_ms is the bare loop
// with the tracer's Embree flags (high-quality trees, robust traversal where shapes share
// edges: scene_geometry.h), the part of the ratio that is Embree's own.
void CompareWithBareLoop(benchmark::State& state, const Scene& scene) {
  if (!BareEmbreeLoop::Covers(scene)) {
    state.SkipWithError("the bare loop traces no mirrors or refraction");
    return;
  }
  EmbreeDevice device;
  TracingThreads pool;
  Tracer tracer(device, scene, pool);
  BareEmbreeLoop bare(device.get(), scene);
  BareEmbreeLoop bareTracerFlags(device.get(), scene, BareEmbreeLoop::Flags::kTracers);
  std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
  // Every frame once before timing: both keep their placed frames.
  for (int frame = 0; frame < scene.render.frameCount; ++frame) {
    tracer.TraceFrame(scene.render.firstFrame + frame, rgb.data());
    bare.TraceFrame(scene.render.firstFrame + frame, pool, rgb.data());
    bareTracerFlags.TraceFrame(scene.render.firstFrame + frame, pool, rgb.data());
  }
  // Elapsed and CPU seconds of each loop, summed over the iterations.
  double tracerTime = 0, bareTime = 0, bareFlagsTime = 0, tracerCpu = 0, bareCpu = 0, bareFlagsCpu = 0;
  int frame = 0;
  for (auto _ : state) {
    const int absolute = scene.render.firstFrame + frame;
    const double start = ElapsedSeconds(), startCpu = ProcessCpuSeconds();
    tracer.TraceFrame(absolute, rgb.data());
    const double traced = ElapsedSeconds(), tracedCpu = ProcessCpuSeconds();
    bare.TraceFrame(absolute, pool, rgb.data());
    const double bared = ElapsedSeconds(), baredCpu = ProcessCpuSeconds();
    bareTracerFlags.TraceFrame(absolute, pool, rgb.data());
    bareFlagsTime += ElapsedSeconds() - bared, bareFlagsCpu += ProcessCpuSeconds() - baredCpu;
    tracerTime += traced - start, tracerCpu += tracedCpu - startCpu;
    bareTime += bared - traced, bareCpu += baredCpu - tracedCpu;
    benchmark::DoNotOptimize(rgb.data());
    frame = (frame + 1) % scene.render.frameCount;
  }
  auto ms = [&](double total) { return 1e3 * total / static_cast<double>(state.iterations()); };
  state.counters["tracer_ms"] = ms(tracerTime);
  state.counters["bare_ms"] = ms(bareTime);
  state.counters["ratio"] = tracerTime / bareTime;
  state.counters["tracer_cpu_ms"] = ms(tracerCpu);
  state.counters["bare_cpu_ms"] = ms(bareCpu);
  state.counters["cpu_ratio"] = tracerCpu / bareCpu;
  // Like for like: the bare loop with the tracer's scene flags (robust traversal and
  // watertight triangles wherever shapes share edges).
  state.counters["bare_tracer_flags_ms"] = ms(bareFlagsTime);
  state.counters["bare_tracer_flags_cpu_ms"] = ms(bareFlagsCpu);
  state.counters["cpu_ratio_same_flags"] = tracerCpu / bareFlagsCpu;
  state.counters["threads"] = pool.ThreadCount();
  state.counters["packet_width"] = tracer.PacketWidth();  // the bare loop's too
}

void TracerAgainstBareEmbree(benchmark::State& state, const std::string& file) {
  CompareWithBareLoop(state, LoadSceneFile(std::string(TCFARM_SCENES_DIR) + "/" + file));
}

// A glTF file (--gltf=FILE, any number) at 1280x720, imported as `tcfarm-worker render`
// imports it, with no mirror or refraction rays (maxDepth 0): the bare loop traces none,
// so both trace the same camera and shadow rays and shade them with glTF's BRDF and
// textures. Alpha masks, blending's shadow attenuation and normal maps stay the tracer's
// own work.
void TracerAgainstBareEmbreeOnGltf(benchmark::State& state, const std::string& path) {
  ImportOptions options;
  options.width = 1280, options.height = 720;
  Scene scene = ImportScene(path, options);
  scene.render.maxDepth = 0;
  CompareWithBareLoop(state, scene);
}

// Registers a TracerAgainstBareEmbree case for each --gltf=FILE, and the exact cost
// cases (TraceExactSequence, ExactCostInParts, ExactNeedlessTraces) for each --exact-scene=FILE (a scene file
// at its own size and frames), taking those arguments out of the command line.
void RegisterFileCases(int* argc, char** argv) {
  constexpr std::string_view kGltf = "--gltf=", kExact = "--exact-scene=";
  auto valueOf = [](std::string_view argument, std::string_view flag) {
    return argument.substr(0, flag.size()) == flag ? std::string(argument.substr(flag.size())) : std::string();
  };
  int kept = 1;
  for (int i = 1; i < *argc; ++i) {
    const std::string_view argument = argv[i];
    if (const std::string path = valueOf(argument, kGltf); !path.empty()) {
      const std::string name = "TracerAgainstBareEmbree/gltf_1280x720:" + std::filesystem::path(path).filename().string();
      benchmark::RegisterBenchmark(name.c_str(), TracerAgainstBareEmbreeOnGltf, path)
          ->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3);
    } else if (const std::string scene = valueOf(argument, kExact); !scene.empty()) {
      const std::string file = std::filesystem::path(scene).filename().string();
      benchmark::RegisterBenchmark(("TraceExactSequence/" + file).c_str(), TraceExactSequence, scene)
          ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime()->Iterations(1);
      benchmark::RegisterBenchmark(("ExactCostInParts/" + file).c_str(), ExactCostInParts, scene)
          ->Unit(benchmark::kMillisecond)->Iterations(1);
      benchmark::RegisterBenchmark(("ExactNeedlessTraces/" + file).c_str(), ExactNeedlessTraces, scene)
          ->Unit(benchmark::kMillisecond)->Iterations(1);
    } else {
      argv[kept++] = argv[i];
    }
  }
  *argc = kept;
}

BENCHMARK_CAPTURE(TracerAgainstBareEmbree, a_one_sphere, "paper_a_one_sphere.json")
    ->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3);
BENCHMARK_CAPTURE(TracerAgainstBareEmbree, b_twelve_spheres, "paper_b_twelve_spheres.json")
    ->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3);
BENCHMARK_CAPTURE(TracerAgainstBareEmbree, c_terrain_flyover, "paper_c_terrain_flyover.json")
    ->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3);

BENCHMARK_CAPTURE(TraceSubsetsOfAFrame, full, Subset::kFull)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSubsetsOfAFrame, checkerboard, Subset::kCheckerboard)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSubsetsOfAFrame, every_other_row, Subset::kEveryOtherRow)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSubsetsOfAFrame, tiles16, Subset::kTiles16)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSubsetsOfAFrame, exact_set_at_30, Subset::kExactAt30)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSubsetsOfAFrame, spot_check, Subset::kSpotCheck)->MeasureProcessCPUTime()->UseRealTime();

BENCHMARK_CAPTURE(TraceExactSequence, a_one_sphere, "paper_a_one_sphere.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime()->Iterations(3);
BENCHMARK_CAPTURE(TraceExactSequence, b_twelve_spheres, "paper_b_twelve_spheres.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime()->Iterations(3);

BENCHMARK_CAPTURE(ExactNeedlessTraces, a_one_sphere, "paper_a_one_sphere.json")
    ->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK_CAPTURE(ExactNeedlessTraces, b_twelve_spheres, "paper_b_twelve_spheres.json")
    ->Unit(benchmark::kMillisecond)->Iterations(1);

BENCHMARK_CAPTURE(ExactCostInParts, a_one_sphere, "paper_a_one_sphere.json")
    ->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK_CAPTURE(ExactCostInParts, b_twelve_spheres, "paper_b_twelve_spheres.json")
    ->Unit(benchmark::kMillisecond)->Iterations(3);

BENCHMARK_CAPTURE(TraceSceneFramesWithHorizons, a_one_sphere, "paper_a_one_sphere.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSceneFramesWithHorizons, b_twelve_spheres, "paper_b_twelve_spheres.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

BENCHMARK_CAPTURE(TraceSceneFrames, a_one_sphere, "paper_a_one_sphere.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSceneFrames, b_twelve_spheres, "paper_b_twelve_spheres.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK_CAPTURE(TraceSceneFrames, c_terrain_flyover, "paper_c_terrain_flyover.json")
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
}  // namespace tcfarm

int main(int argc, char** argv) {
  tcfarm::RegisterFileCases(&argc, argv);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
