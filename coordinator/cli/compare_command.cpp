#include "cli/compare_command.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>

#include <nlohmann/json.hpp>

#include "frame/compare.h"
#include "frame/frame_io.h"
#include "frame/ssim.h"

namespace tcfarm {
namespace {

std::set<std::string> ExrNames(const std::filesystem::path& folder) {
  std::set<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.path().extension() == ".exr") names.insert(entry.path().filename().string());
  }
  return names;
}

}  // namespace

int RunCompare(const std::vector<std::string>& args) {
  std::vector<std::string> folders;
  bool json = false;
  for (const auto& arg : args) {
    if (arg == "--json") {
      json = true;
    } else {
      folders.push_back(arg);
    }
  }
  if (folders.size() != 2) {
    std::fprintf(stderr, "usage: tcfarm-coordinator compare REFERENCE_DIR TEST_DIR [--json]\n");
    return 2;
  }
  try {
    std::set<std::string> names = ExrNames(folders[0]);
    if (names.empty()) throw FrameIoError("no .exr frames in " + folders[0]);
    FrameError total;
    double ssimSum = 0;
    for (const std::string& name : names) {
      Image reference = ReadImage(std::filesystem::path(folders[0]) / name);
      Image test = ReadImage(std::filesystem::path(folders[1]) / name);
      total += CompareImages(reference, test);
      ssimSum += Ssim(reference, test);
    }
    double psnr = total.Psnr();
    double ssim = ssimSum / names.size();  // mean over frames
    if (json) {
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

}  // namespace tcfarm
