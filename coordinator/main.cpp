// tcfarm-coordinator: owns the jobs, plans which pixels to trace, dispatches tasks to
// workers over ZeroMQ, writes the frames, serves the HTTP API.
//   tcfarm-coordinator serve [options]          the daemon (and, with workers, a local farm)
//   tcfarm-coordinator compare REF_DIR DIR      error of a sequence against its reference
//   tcfarm-coordinator analyze DIR              coherence of a sequence, equation 3 by bin width
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "cli/analyze_command.h"
#include "cli/compare_command.h"
#include "cli/serve_command.h"

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  const char* usage =
      "usage: tcfarm-coordinator serve [--help for options]\n"
      "       tcfarm-coordinator compare REFERENCE_DIR TEST_DIR [--json]\n"
      "       tcfarm-coordinator analyze DIR [--json] [--change-mask FILE.png]\n";
  if (args.empty()) {
    std::fputs(usage, stderr);
    return 2;
  }
  std::string command = args[0];
  args.erase(args.begin());
  try {
    if (command == "serve") return tcfarm::RunServe(args);
    if (command == "compare") return tcfarm::RunCompare(args);
    if (command == "analyze") return tcfarm::RunAnalyze(args);
    if (command == "--help" || command == "-h") {
      std::fputs(usage, stdout);
      return 0;
    }
    std::fprintf(stderr, "tcfarm-coordinator: unknown command '%s'\n%s", command.c_str(), usage);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-coordinator %s: %s\n", command.c_str(), e.what());
    return 1;
  }
}
