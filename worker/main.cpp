// tcfarm-worker: a stateless tracing process.
//   tcfarm-worker render SCENE --frames A:B --out DIR   brute-force reference render
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "embree/device.h"
#include "frame/frame_io.h"
#include "render/render_command.h"
#include "scene/scene.h"

namespace {

constexpr const char* kUsage =
    "usage: tcfarm-worker render SCENE.json [--frames A:B] [--out DIR] [--threads N]\n";

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h") {
    std::fputs(kUsage, args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  const std::string command = args[0];
  args.erase(args.begin());
  try {
    if (command == "render") return tcfarm::RunRender(tcfarm::ParseRenderArguments(args));
    std::fprintf(stderr, "tcfarm-worker: unknown command '%s'\n%s", command.c_str(), kUsage);
    return 2;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "tcfarm-worker %s: %s\n", command.c_str(), e.what());
    return 2;
  } catch (const tcfarm::SceneError& e) {
    std::fprintf(stderr, "tcfarm-worker: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-worker %s: %s\n", command.c_str(), e.what());
    return 1;
  }
}
