// tcfarm-render: the brute-force reference renderer (also reached as `tcfarm-worker
// render`). A program of its own because it writes frame files: OpenImageIO and its
// ~200 shared libraries stay out of the worker daemon, which starts in milliseconds.
#include <cstdio>
#include <exception>
#include <stdexcept>

#include "proto/command_line/command_line.h"
#include "worker/render/render_command.h"

int main(int argc, char** argv) {
  CLI::App app("Brute-force reference render: traces every pixel of every frame, writes the "
               "frames and reports time per frame, rays by type and the sequence's coherence. "
               "Also run as `tcfarm-worker render`.",
               "tcfarm-render");
  tcfarm::cli::SetUpProgram(app);
  tcfarm::RenderCommandLine commandLine(app);
  if (auto exitCode = tcfarm::cli::ParseCommandLine(app, argc, argv)) return *exitCode;
  try {
    return tcfarm::RunRender(commandLine.Options());
  } catch (const std::invalid_argument& e) {  // a flag's value, or frames the scene lacks
    return tcfarm::cli::ReportUsageError(app, e.what());
  } catch (const std::exception& e) {  // SceneError included: the message names the value
    std::fprintf(stderr, "tcfarm-render: %s\n", e.what());
    return 1;
  }
}
