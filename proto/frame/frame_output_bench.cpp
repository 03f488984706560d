// What writing one finished frame costs the coordinator: the lossless EXR (each lossless
// compression), the 8-bit PNG preview, and a traced-pixel mask PNG, on a real frame.
//   build/proto/frame_output_bench FRAME.exr [--benchmark_min_time=1]
// (a frame of `tcfarm-worker render tests/scenes/paper_b_twelve_spheres.json`, say).
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

Image& Frame() {
  static Image image;
  return image;
}

std::filesystem::path Scratch(const char* name) {
  return std::filesystem::temp_directory_path() / (std::string("tcfarm_frame_output_bench_") +
                                                   std::to_string(::getpid()) + "_" + name);
}

void Exr(benchmark::State& state, const char* compression) {
  const std::filesystem::path path = Scratch("frame.exr");
  for (auto _ : state) WriteExr(path, Frame(), compression);
  state.counters["MB"] = double(std::filesystem::file_size(path)) / 1e6;
  std::filesystem::remove(path);
}

void Png(benchmark::State& state) {
  const std::filesystem::path path = Scratch("frame.png");
  for (auto _ : state) WritePng(path, Frame());
  state.counters["MB"] = double(std::filesystem::file_size(path)) / 1e6;
  std::filesystem::remove(path);
}

// Exact's traced mask: about one pixel in seven, in runs along the moving edges.
void MaskPng(benchmark::State& state) {
  std::vector<uint8_t> mask(Frame().PixelCount(), 0);
  std::mt19937 random(1);
  for (size_t i = 0; i < mask.size(); i += 64) {
    if (random() % 7 == 0) std::fill(mask.begin() + i, mask.begin() + std::min(mask.size(), i + 64), 1);
  }
  const std::filesystem::path path = Scratch("mask.png");
  for (auto _ : state) WriteMaskPng(path, Frame().width, Frame().height, mask);
  std::filesystem::remove(path);
}

BENCHMARK_CAPTURE(Exr, zip1, "zip:1")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(Exr, zip, "zip")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(Exr, piz, "piz")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(Exr, rle, "rle")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(Exr, none, "none")->Unit(benchmark::kMillisecond);
BENCHMARK(Png)->Unit(benchmark::kMillisecond);
BENCHMARK(MaskPng)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace tcfarm

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (argc != 2) {
    std::fprintf(stderr, "usage: frame_output_bench FRAME.exr [benchmark flags]\n");
    return 2;
  }
  tcfarm::Frame() = tcfarm::ReadImage(argv[1]);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
