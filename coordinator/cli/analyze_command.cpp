#include "coordinator/cli/analyze_command.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "proto/frame/frame_io.h"
#include "proto/frame/sequence_analysis.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

// The widest bin the paper measured (Figure 9) and showed its audience (Figure 11). Equation 3
// alone always favours the widest bin allowed, so the best n is reported under this cap.
constexpr int kPaperMaxBinWidth = 10;

struct AnalyzeOptions {
  fs::path folder;
  bool json = false;
  fs::path changeMaskPath;  // empty: no mask written
};

std::vector<fs::path> FramesWithExtension(const fs::path& folder, const std::string& extension) {
  std::vector<fs::path> paths;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const fs::path& path = entry.path();
    if (path.extension() == extension && path.filename().string().rfind("frame_", 0) == 0) {
      paths.push_back(path);
    }
  }
  // frame_0042: the zero-padded number sorts by name.
  std::sort(paths.begin(), paths.end());
  return paths;
}

// The EXRs hold the exact bits; the PNGs are the fallback for folders of 8-bit frames only.
std::vector<fs::path> FramePaths(const fs::path& folder) {
  if (!fs::is_directory(folder)) throw FrameIoError("no folder " + folder.string());
  std::vector<fs::path> paths = FramesWithExtension(folder, ".exr");
  if (paths.empty()) paths = FramesWithExtension(folder, ".png");
  if (paths.empty()) {
    throw FrameIoError("no frame_*.exr or frame_*.png frames in " + folder.string());
  }
  return paths;
}

SequenceAnalysis AnalyzeFrames(const std::vector<fs::path>& paths) {
  SequenceAnalyzer analyzer;
  for (const fs::path& path : paths) {
    Image frame = ReadImage(path);  // its errors name the file
    try {
      analyzer.Add(frame);
    } catch (const std::invalid_argument& e) {
      throw FrameIoError(path.string() + ": " + e.what());
    }
  }
  return analyzer.Finish();
}

void WriteChangeMask(const fs::path& path, const SequenceAnalysis& analysis) {
  Image mask{analysis.width, analysis.height, std::vector<float>(analysis.changeMask.size() * 3)};
  for (size_t p = 0; p < analysis.changeMask.size(); ++p) {
    float value = analysis.changeMask[p] ? 0.0f : 1.0f;  // the paper's Figure 7: white = still
    std::fill_n(&mask.rgb[3 * p], 3, value);
  }
  WritePng(path, mask);
}

int BestPaperBinWidth(const SequenceAnalysis& analysis) {
  return BestBinWidth(analysis.frames, analysis.d, std::min(analysis.frames, kPaperMaxBinWidth));
}

void PrintJson(const SequenceAnalysis& analysis) {
  nlohmann::json out = analysis.ToJson();
  out["best_bin_width_max"] = kPaperMaxBinWidth;
  out["best_bin_width"] =
      analysis.frames >= 2 ? nlohmann::json(BestPaperBinWidth(analysis)) : nlohmann::json(nullptr);
  std::printf("%s\n", out.dump().c_str());
}

void PrintCoherence(const char* name, const RunningStats& stats) {
  std::printf("%s coherence: mean %.2f%% (min %.2f%%, max %.2f%%)\n", name, 100 * stats.Mean(),
              100 * stats.min, 100 * stats.max);
}

void PrintPredictions(const SequenceAnalysis& analysis) {
  std::printf("equation 3, relative cost (performance ratio) by bin width n:\n");
  int widest = std::min(analysis.frames, kPaperMaxBinWidth);
  for (int n = 2; n <= widest; ++n) {
    double cost = Equation3RelativeCost(analysis.frames, n, analysis.d);
    std::printf("  n=%-2d %.3f (%.2fx)\n", n, cost, 1 / cost);
  }
  int best = BestPaperBinWidth(analysis);
  double cost = Equation3RelativeCost(analysis.frames, best, analysis.d);
  std::printf("best bin width up to %d: n=%d, relative cost %.3f (%.2fx)\n", kPaperMaxBinWidth,
              best, cost, 1 / cost);
}

void PrintSummary(const SequenceAnalysis& analysis) {
  std::printf("frames: %d of %dx%d\n", analysis.frames, analysis.width, analysis.height);
  if (analysis.frames >= 2) {
    PrintCoherence("frame-to-frame", analysis.frameToFrame);
    PrintCoherence("long-term", analysis.longTerm);
  } else {
    std::printf("coherence: needs at least two frames\n");
  }
  std::printf("d = 1 - mean frame-to-frame coherence = %.4f\n", analysis.d);
  std::printf("pixel events: %llu, mean duration %.2f frames (sd %.2f)\n",
              static_cast<unsigned long long>(analysis.eventCount), analysis.meanEventDuration,
              analysis.eventDurationStdDev);
  std::printf("pixels that ever change: %.2f%%\n", 100 * analysis.ChangedPixelShare());
  if (analysis.frames >= 2) PrintPredictions(analysis);
}

int RunAnalyze(const AnalyzeOptions& options) {
  try {
    SequenceAnalysis analysis = AnalyzeFrames(FramePaths(options.folder));
    if (!options.changeMaskPath.empty()) WriteChangeMask(options.changeMaskPath, analysis);
    if (options.json) {
      PrintJson(analysis);
    } else {
      PrintSummary(analysis);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-coordinator analyze: %s\n", e.what());
    return 1;
  }
}

}  // namespace

cli::Subcommand AddAnalyzeCommand(CLI::App& program) {
  CLI::App* analyze = program.add_subcommand(
      "analyze", "Coherence of a rendered sequence, and what equation 3 predicts by bin width");
  auto options = std::make_shared<AnalyzeOptions>();
  analyze->add_option("DIR", options->folder, "Folder of the frames: frame_*.exr, else frame_*.png")
      ->required();
  analyze->add_flag("--json", options->json, "Print the analysis as one JSON object");
  analyze->add_option("--change-mask", options->changeMaskPath,
                      "Also write the pixels that ever change as a PNG (white: never changes)")
      ->type_name("FILE.png");
  return {analyze, [options] { return RunAnalyze(*options); }};
}

}  // namespace tcfarm
