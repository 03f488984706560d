#include "render/render_command.h"

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "embree/device.h"
#include "frame/coherence.h"
#include "frame/frame_io.h"
#include "frame/frame_writer.h"
#include "scene/import/scene_import.h"
#include "scene/scene.h"
#include "trace/tracer.h"
#include "util/thread_pool.h"

namespace tcfarm {
namespace {

constexpr const char* kUsage =
    "usage: tcfarm-render SCENE (.json or .obj) [--frames A:B] [--out DIR] [--threads N] "
    "[--no-exr] [--no-png] [--exr-compression zip[:1-9]|none|rle|zips|piz]";

int ParseInt(const std::string& text, const std::string& what) {
  size_t used = 0;
  int value = 0;
  try {
    value = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty()) {
    throw std::invalid_argument(what + ": '" + text + "' is not an integer\n" + kUsage);
  }
  return value;
}

void ParseFrameRange(const std::string& text, RenderOptions* options) {
  size_t colon = text.find(':');
  if (colon == std::string::npos) {
    options->firstFrame = options->lastFrame = ParseInt(text, "--frames");
  } else {
    options->firstFrame = ParseInt(text.substr(0, colon), "--frames start");
    options->lastFrame = ParseInt(text.substr(colon + 1), "--frames end");
  }
  if (options->firstFrame < 0 || options->lastFrame < options->firstFrame) {
    throw std::invalid_argument("--frames " + text +
                                ": expected A:B with 0 <= A <= B (both inclusive)");
  }
}

// Motion is validated over the scene's own frame range only, so frames outside it are
// not trusted to be finite.
void ResolveFrameRange(const Scene& scene, RenderOptions* options) {
  if (options->firstFrame < 0) {
    options->firstFrame = scene.render.firstFrame;
    options->lastFrame = scene.render.LastFrame();
  }
  if (options->firstFrame < scene.render.firstFrame ||
      options->lastFrame > scene.render.LastFrame()) {
    throw std::invalid_argument(
        "--frames " + std::to_string(options->firstFrame) + ":" +
        std::to_string(options->lastFrame) + " is outside the scene's frames " +
        std::to_string(scene.render.firstFrame) + ":" + std::to_string(scene.render.LastFrame()));
  }
}

}  // namespace

RenderOptions ParseRenderArguments(const std::vector<std::string>& args) {
  RenderOptions options;
  options.outDirectory = "out";
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    auto value = [&]() -> const std::string& {
      if (i + 1 >= args.size()) throw std::invalid_argument(arg + " needs a value\n" + kUsage);
      return args[++i];
    };
    if (arg == "--frames") {
      ParseFrameRange(value(), &options);
    } else if (arg == "--out") {
      options.outDirectory = value();
    } else if (arg == "--threads") {
      int threads = ParseInt(value(), "--threads");
      if (threads < 0) throw std::invalid_argument("--threads: expected 0 (all cores) or more");
      options.threads = static_cast<unsigned>(threads);
    } else if (arg == "--no-exr") {
      options.output.writeExr = false;
    } else if (arg == "--no-png") {
      options.output.writePng = false;
    } else if (arg == "--exr-compression") {
      options.output.exrCompression = value();
      if (!IsLosslessExrCompression(options.output.exrCompression)) {
        throw std::invalid_argument("--exr-compression " + options.output.exrCompression +
                                    ": expected a lossless one: none, rle, zips, zip or piz");
      }
    } else if (!arg.empty() && arg[0] == '-') {
      throw std::invalid_argument("unknown option " + arg + "\n" + kUsage);
    } else if (options.scenePath.empty()) {
      options.scenePath = arg;
    } else {
      throw std::invalid_argument("unexpected argument " + arg + "\n" + kUsage);
    }
  }
  if (options.scenePath.empty()) throw std::invalid_argument(std::string("no scene\n") + kUsage);
  return options;
}

int RunRender(const RenderOptions& requested) {
  RenderOptions options = requested;
  Scene scene = ImportScene(options.scenePath);
  ResolveFrameRange(scene, &options);
  RebaseOnCamera(scene);  // as the farm's workers do: the same bits

  EmbreeDevice device;
  ThreadPool pool(options.threads);
  Tracer tracer(device, scene, pool);
  std::filesystem::create_directories(options.outDirectory);
  FrameWriter writer(options.outDirectory, options.output);
  CoherenceTracker coherence;

  const int width = scene.render.width, height = scene.render.height;
  double traceSeconds = 0;
  auto start = std::chrono::steady_clock::now();
  for (int frame = options.firstFrame; frame <= options.lastFrame; ++frame) {
    Image image{width, height, std::vector<float>(static_cast<size_t>(width) * height * 3)};
    auto frameStart = std::chrono::steady_clock::now();
    tracer.TraceFrame(frame, image.rgb.data());
    double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - frameStart).count();
    traceSeconds += seconds;
    std::printf("frame %d: %.2f ms\n", frame, seconds * 1e3);
    coherence.Add(image);
    writer.Write(frame, std::move(image));
  }
  writer.Finish();
  double wallSeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  int frames = options.lastFrame - options.firstFrame + 1;
  RayCounts rays = tracer.Counts();
  std::printf("rendered %d frames of %dx%d on %u threads to %s\n", frames, width, height,
              pool.ThreadCount(), options.outDirectory.c_str());
  std::printf("time: %.2f ms per frame traced, %.2f s wall in all\n", traceSeconds * 1e3 / frames,
              wallSeconds);
  std::printf("rays: primary %llu, shadow %llu, reflection %llu, refraction %llu\n",
              static_cast<unsigned long long>(rays.primary),
              static_cast<unsigned long long>(rays.shadow),
              static_cast<unsigned long long>(rays.reflection),
              static_cast<unsigned long long>(rays.refraction));
  std::printf("%s\n", coherence.Summary().c_str());
  return 0;
}

}  // namespace tcfarm
