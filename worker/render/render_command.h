// `tcfarm-worker render`: the brute-force reference. Traces every pixel of every frame,
// writes the frames, and reports time per frame, rays by type and the sequence's
// frame-to-frame and long-term coherence (paper, section 2).
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "proto/command_line/command_line.h"
#include "proto/frame/frame_writer.h"
#include "proto/scene/import/scene_import.h"

namespace tcfarm {

struct RenderOptions {
  std::filesystem::path scenePath;
  std::filesystem::path outDirectory;
  int firstFrame = -1;  // -1: the scene's range
  int lastFrame = -1;
  unsigned threads = 0;  // 0: all cores
  FrameWriterOptions output;
  // How a file that is not tcfarm JSON becomes a scene (glTF: fps, animation, camera), and
  // the render size and samples for any format.
  ImportOptions import;
  // Print the scene as tcfarm JSON (what the farm is given) instead of rendering it.
  bool printScene = false;
  // Lighting switches for comparisons with other renderers (RenderSettings).
  bool noShadows = false;
  std::optional<double> ambient;
};

// The renderer's command line, SCENE and its flags, on app; Options() once app has parsed.
class RenderCommandLine {
 public:
  explicit RenderCommandLine(CLI::App& app);
  // app writes into this object's members.
  RenderCommandLine(const RenderCommandLine&) = delete;
  RenderCommandLine& operator=(const RenderCommandLine&) = delete;
  // Throws std::invalid_argument, naming the flag, for what the parser does not check.
  RenderOptions Options() const;

 private:
  RenderOptions options_;
  std::string frames_;  // empty: the scene's own frames
  std::string size_;    // WxH; empty: the scene's own
  bool noExr_ = false;
  bool noPng_ = false;
  std::string lightUnits_;
  std::string view_ = "standard";
};

// Returns the process exit code.
int RunRender(const RenderOptions& options);

}  // namespace tcfarm
