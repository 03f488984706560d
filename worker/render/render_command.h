// `tcfarm-worker render`: the brute-force reference. Traces every pixel of every frame,
// writes the frames, and reports time per frame, rays by type and the sequence's
// frame-to-frame and long-term coherence (paper, section 2).
#pragma once

#include <filesystem>

#include "frame/frame_writer.h"
#include <string>
#include <vector>

namespace tcfarm {

struct RenderOptions {
  std::filesystem::path scenePath;
  std::filesystem::path outDirectory;
  int firstFrame = -1;  // -1: the scene's range
  int lastFrame = -1;
  unsigned threads = 0;  // 0: all cores
  FrameWriterOptions output;
};

// Parses `render SCENE --frames A:B --out DIR [--threads N] [--no-exr] [--no-png]
// [--exr-compression NAME]`
// (argv after the command word). Throws std::invalid_argument with a usage message.
RenderOptions ParseRenderArguments(const std::vector<std::string>& args);

// Returns the process exit code.
int RunRender(const RenderOptions& options);

}  // namespace tcfarm
