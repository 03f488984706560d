#include "coordinator/cli/compare_command.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "proto/frame/compare.h"
#include "proto/frame/frame_io.h"
#include "proto/frame/ssim.h"

namespace tcfarm {
namespace {

std::set<std::string> ExrNames(const std::filesystem::path& folder) {
  std::set<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.path().extension() == ".exr") names.insert(entry.path().filename().string());
  }
  return names;
}

struct CompareFlags {
  std::string referenceFolder;
  std::string testFolder;
  bool json = false;
};

int RunCompare(const CompareFlags& flags) {
  try {
    std::set<std::string> names = ExrNames(flags.referenceFolder);
    if (names.empty()) throw FrameIoError("no .exr frames in " + flags.referenceFolder);
    FrameError total;
    double ssimSum = 0;
    for (const std::string& name : names) {
      Image reference = ReadImage(std::filesystem::path(flags.referenceFolder) / name);
      Image test = ReadImage(std::filesystem::path(flags.testFolder) / name);
      total += CompareImages(reference, test);
      ssimSum += Ssim(reference, test);
    }
    double psnr = total.Psnr();
    double ssim = ssimSum / names.size();  // mean over frames
    if (flags.json) {
      nlohmann::json out = {{"frames", names.size()},
                            {"pixels", total.pixels},
                            {"differing_pixels", total.differingPixels},
                            {"differing_share", total.DifferingShare()},
                            {"max_abs_error", total.maxAbsError},
                            {"psnr_db", std::isinf(psnr) ? nlohmann::json(nullptr) : nlohmann::json(psnr)},
                            {"ssim", ssim}};
      std::printf("%s\n", out.dump().c_str());
    } else {
      std::printf("frames %zu, pixels differing %llu of %llu (%.4f%%), max abs error %.6g, "
                  "PSNR %s, SSIM %.6f\n",
                  names.size(), static_cast<unsigned long long>(total.differingPixels),
                  static_cast<unsigned long long>(total.pixels), 100 * total.DifferingShare(),
                  total.maxAbsError,
                  std::isinf(psnr) ? "inf (identical)" : (std::to_string(psnr) + " dB").c_str(),
                  ssim);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tcfarm-coordinator compare: %s\n", e.what());
    return 1;
  }
}

}  // namespace

cli::Subcommand AddCompareCommand(CLI::App& program) {
  CLI::App* compare = program.add_subcommand(
      "compare", "Error of a rendered sequence against its reference, frame by frame (EXR)");
  auto flags = std::make_shared<CompareFlags>();
  compare->add_option("REFERENCE_DIR", flags->referenceFolder,
                      "Folder of the reference frames (frame_*.exr)")
      ->required();
  compare->add_option("TEST_DIR", flags->testFolder, "Folder of the frames to check, same names")
      ->required();
  compare->add_flag("--json", flags->json, "Print the summary as one JSON object");
  return {compare, [flags] { return RunCompare(*flags); }};
}

}  // namespace tcfarm
