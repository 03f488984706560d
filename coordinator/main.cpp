// tcfarm-coordinator: owns the jobs, plans which pixels to trace, dispatches tasks to
// workers over ZeroMQ, writes the frames, serves the HTTP API.
//   tcfarm-coordinator serve [options]          the daemon (and, with workers, a local farm)
//   tcfarm-coordinator compare REF_DIR DIR      error of a sequence against its reference
//   tcfarm-coordinator analyze DIR              coherence of a sequence, equation 3 by bin width
//   tcfarm-coordinator keygen --name NAME       a CURVE key pair for the workers' link
#include <cstdio>
#include <exception>

#include "coordinator/cli/analyze_command.h"
#include "coordinator/cli/compare_command.h"
#include "coordinator/cli/serve_command.h"
#include "proto/command_line/command_line.h"
#include "proto/curve/keygen_command.h"

int main(int argc, char** argv) {
  CLI::App program("Owns the jobs, plans which pixels to trace, dispatches tasks to the "
                   "workers over ZeroMQ, writes the frames and serves the HTTP API.",
                   "tcfarm-coordinator");
  tcfarm::cli::SetUpProgram(program);
  program.require_subcommand(1);
  const tcfarm::cli::Subcommand commands[] = {tcfarm::AddServeCommand(program),
                                              tcfarm::AddCompareCommand(program),
                                              tcfarm::AddAnalyzeCommand(program),
                                              tcfarm::curve::AddKeygenCommand(program)};
  if (auto exitCode = tcfarm::cli::ParseCommandLine(program, argc, argv)) return *exitCode;
  for (const tcfarm::cli::Subcommand& command : commands) {
    if (!command.app->parsed()) continue;
    try {
      return command.run();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "tcfarm-coordinator %s: %s\n", command.app->get_name().c_str(), e.what());
      return 1;
    }
  }
  return tcfarm::cli::kUsageError;  // require_subcommand(1) leaves no other way here
}
