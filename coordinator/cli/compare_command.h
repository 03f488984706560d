// `tcfarm-coordinator compare REFERENCE_DIR TEST_DIR`: the error of a rendered sequence
// against its brute-force reference, frame by frame (EXR, bitwise).
#pragma once

#include "proto/command_line/command_line.h"

namespace tcfarm {

// Adds `compare` to the coordinator's command line. It prints the error summary (JSON with
// --json); its exit code is 0 when the folders could be compared, 1 when a frame is missing
// or unreadable, 2 on bad usage.
cli::Subcommand AddCompareCommand(CLI::App& program);

}  // namespace tcfarm
