// `keygen`: makes a CURVE key pair and writes it as DIR/NAME.key (secret, mode 0600) and
// DIR/NAME.pub (public). Both programs offer it (`tcfarm-coordinator keygen`,
// `tcfarm-worker keygen`): it writes the same files for either side.
#pragma once

#include "proto/command_line/command_line.h"

namespace tcfarm::curve {

// Exit code 0 when both files were written, 1 when they could not be (one exists already
// and --force is not given, the folder is not writable), 2 on bad usage.
cli::Subcommand AddKeygenCommand(CLI::App& program);

}  // namespace tcfarm::curve
