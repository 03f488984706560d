#include "worker/render/render_command.h"

#include <chrono>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "worker/tracing.h"
#include "proto/frame/sequence_analysis.h"
#include "proto/frame/frame_io.h"
#include "proto/frame/frame_writer.h"
#include "proto/scene/import/scene_import.h"
#include "proto/scene/scene.h"
#include "proto/scene/scene_limits.h"

namespace tcfarm {
namespace {

int ParseInt(const std::string& text, const std::string& what) {
  size_t used = 0;
  int value = 0;
  try {
    value = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty()) {
    throw std::invalid_argument(what + ": '" + text + "' is not an integer");
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
  options->import.lastFrame = options->lastFrame;  // a glTF file's frames may run past its animation
}

void ParseSize(const std::string& text, RenderOptions* options) {
  size_t x = text.find('x');
  using scene_limits::kMaxImageSide;
  const std::string expected = "--size " + text + ": expected WxH, both from 1 to " + std::to_string(kMaxImageSide);
  if (x == std::string::npos) throw std::invalid_argument(expected);
  try {
    options->import.width = ParseInt(text.substr(0, x), "--size width");
    options->import.height = ParseInt(text.substr(x + 1), "--size height");
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(expected);
  }
  if (options->import.width < 1 || options->import.width > kMaxImageSide || options->import.height < 1 ||
      options->import.height > kMaxImageSide) {
    throw std::invalid_argument(expected);
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

RenderCommandLine::RenderCommandLine(CLI::App& app) {
  options_.outDirectory = "out";
  app.add_option("SCENE", options_.scenePath, "Scene file: tcfarm JSON (.json), Wavefront OBJ (.obj) or glTF 2.0 (.gltf, .glb)")->type_name("FILE")->required();
  app.add_option("--frames", frames_,
                 "Frames to render, both inclusive, or one frame (default: the scene's own; a glTF file's may "
                 "run past its animation, holding the last key)")
      ->type_name("A:B");
  app.add_option("--out", options_.outDirectory, "Folder the frames are written to")
      ->type_name("DIR")
      ->capture_default_str();
  app.add_option("--threads", options_.threads, "Tracing threads (0: one per core)")
      ->type_name("N")
      ->check(cli::IntegerFrom(0, std::numeric_limits<int>::max()))
      ->capture_default_str();
  app.add_option("--fps", options_.import.framesPerSecond,
                 "glTF: frames per second; frame f shows the animation at time f / fps")
      ->type_name("F")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--animation", options_.import.animation,
                 "glTF: the animation to play, by name or index (default: the first)")
      ->type_name("NAME|INDEX");
  app.add_option("--camera", options_.import.camera,
                 "glTF: the camera, by its (or its node's) name or its index (default: the first camera node)")
      ->type_name("NAME|INDEX");
  app.add_option("--size", size_, "Image size (default: the scene's; 640x480 for glTF and OBJ)")->type_name("WxH");
  app.add_option("--spp", options_.import.samplesPerPixel, "Samples per pixel (default: the scene's)")
      ->type_name("N")
      ->check(cli::IntegerFrom(1, scene_limits::kMaxSamplesPerPixel));
  app.add_flag("--print-scene", options_.printScene,
               "Print the scene as tcfarm JSON, as the farm is given it, and render nothing");
  app.add_option("--light-units", lightUnits_,
                 "glTF lights: photometric (candela and lux at 683 lm/W, as Blender and other tools mean them; the "
                 "default) or radiometric (the numbers as W/sr and W/m2, as the Khronos Sample Viewer takes them)")
      ->check(CLI::IsMember({"photometric", "radiometric"}));
  app.add_flag("--no-shadows", options_.noShadows,
               "Trace no shadow rays: every light reaches what faces it (to compare with a rasterizer)");
  app.add_option("--ambient", options_.ambient, "The ambient term's share of a surface's colour (default: the scene's, 0.05)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_flag("--no-exr", noExr_, "Write no EXR frames");
  app.add_flag("--no-png", noPng_, "Write no PNG frames");
  app.add_option("--view", view_,
                 "How the PNG previews show the linear values: standard (clamped to [0, 1]) or khr-pbr-neutral "
                 "(the Khronos PBR Neutral tone mapper); the EXR keeps the values as traced")
      ->type_name("NAME")
      ->check(CLI::IsMember({"standard", "khr-pbr-neutral"}))
      ->capture_default_str();
  app.add_option("--exposure", options_.output.view.exposure,
                 "Exposure of the PNG previews in stops: values are scaled by 2^EV before the view")
      ->type_name("EV")
      ->check(CLI::Range(-kMaxExposure, kMaxExposure))
      ->capture_default_str();
  app.add_option("--exr-compression", options_.output.exrCompression,
                 "Lossless EXR compression: zip[:1-9], none, rle, zips or piz")
      ->type_name("NAME")
      ->capture_default_str();
}

RenderOptions RenderCommandLine::Options() const {
  RenderOptions options = options_;
  if (!frames_.empty()) ParseFrameRange(frames_, &options);
  if (!size_.empty()) ParseSize(size_, &options);
  if (!lightUnits_.empty()) options.import.lightUnits = *LightUnitsNamed(lightUnits_);
  options.output.writeExr = !noExr_;
  options.output.writePng = !noPng_;
  options.output.view.view = *ParseView(view_);  // the parser took only a view's name
  if (!IsValidExposure(options.output.view.exposure)) {  // NaN passes the parser's range check
    throw std::invalid_argument("--exposure " + std::to_string(options.output.view.exposure) +
                                ": expected a number of stops in [-" + std::to_string(int(kMaxExposure)) + ", " +
                                std::to_string(int(kMaxExposure)) + "]");
  }
  if (!IsLosslessExrCompression(options.output.exrCompression)) {
    throw std::invalid_argument("--exr-compression " + options.output.exrCompression +
                                ": expected a lossless one: none, rle, zips, zip or piz");
  }
  return options;
}

int RunRender(const RenderOptions& requested) {
  RenderOptions options = requested;
  Scene scene = ImportScene(options.scenePath, options.import);
  if (options.noShadows) scene.render.shadows = false;
  if (options.ambient) scene.render.ambient = *options.ambient;
  if (options.printScene) {
    std::printf("%s\n", SerializeScene(scene).c_str());
    return 0;
  }
  ResolveFrameRange(scene, &options);
  PrepareForTracing(scene);  // as the farm's workers do: the same bits

  EmbreeDevice device;
  TracingThreads pool(options.threads);
  Tracer tracer(device, scene, pool);
  std::filesystem::create_directories(options.outDirectory);
  FrameWriter writer(options.outDirectory, options.output);
  SequenceAnalyzer coherence;

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
  const SceneGeometry::DeformationWork deformed = tracer.DeformationCounts();
  std::printf("deforming meshes: %llu poses computed, %llu shared, %llu vertices deformed\n",
              static_cast<unsigned long long>(deformed.posesComputed),
              static_cast<unsigned long long>(deformed.posesShared),
              static_cast<unsigned long long>(deformed.verticesDeformed));
  std::printf("%s\n", CoherenceSummary(coherence.frameToFrame(), coherence.longTerm()).c_str());
  return 0;
}

}  // namespace tcfarm
