// `tcfarm-coordinator analyze DIR [--json] [--change-mask FILE.png]`: the coherence analysis
// of any rendered sequence (paper, section 2 and equation 3), so a user can see before
// submitting a job what exploiting temporal coherence can buy on footage like it.
#pragma once

#include "proto/command_line/command_line.h"

namespace tcfarm {

// Adds `analyze` to the coordinator's command line. It reads DIR/frame_*.exr in name order
// (DIR/frame_*.png when there is no EXR), prints the summary (JSON with --json) and, with
// --change-mask, writes the pixels that ever change as an 8-bit PNG (white: never changes,
// black: changes; the paper's Figure 7). Its exit code is 0 when analysed, 1 when the folder
// holds no frames or a frame is unreadable or of another size (the message names the file),
// 2 on bad usage.
cli::Subcommand AddAnalyzeCommand(CLI::App& program);

}  // namespace tcfarm
