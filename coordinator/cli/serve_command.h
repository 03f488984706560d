// `tcfarm-coordinator serve`: the coordinator daemon. With --local-workers N it is also
// the embedded local farm: it starts N workers on loopback itself.
#pragma once

#include "proto/command_line/command_line.h"

namespace tcfarm {

// Adds `serve` and its flags to the coordinator's command line.
cli::Subcommand AddServeCommand(CLI::App& program);

}  // namespace tcfarm
