// tcfarm-render: the brute-force reference renderer (also reached as `tcfarm-worker
// render`). A program of its own because it writes frame files: OpenImageIO and its
// ~200 shared libraries stay out of the worker daemon, which starts in milliseconds.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "render/render_command.h"
#include "scene/scene.h"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  try {
    return tcfarm::RunRender(tcfarm::ParseRenderArguments(args));
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "tcfarm-worker render: %s\n", e.what());
    return 2;
  } catch (const tcfarm::SceneError& e) {
    std::fprintf(stderr, "tcfarm-worker: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-worker render: %s\n", e.what());
    return 1;
  }
}
