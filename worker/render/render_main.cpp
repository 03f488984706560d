// tcfarm-render: the brute-force reference renderer (also reached as `tcfarm-worker
// render`). A program of its own because it writes frame files: OpenImageIO and its
// ~200 shared libraries stay out of the worker daemon, which starts in milliseconds.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "render/render_command.h"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  try {
    return tcfarm::RunRender(tcfarm::ParseRenderArguments(args));
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "tcfarm-render: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {  // SceneError included: the message names the value
    std::fprintf(stderr, "tcfarm-render: %s\n", e.what());
    return 1;
  }
}
