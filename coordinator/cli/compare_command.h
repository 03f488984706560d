// `tcfarm-coordinator compare REFERENCE_DIR TEST_DIR`: the error of a rendered sequence
// against its brute-force reference, frame by frame (EXR, bitwise).
#pragma once

#include <string>
#include <vector>

namespace tcfarm {

// Prints the error summary (JSON with --json) and returns the exit code: 0 when the
// folders could be compared, 1 when a frame is missing or unreadable, 2 on bad usage.
int RunCompare(const std::vector<std::string>& args);

}  // namespace tcfarm
