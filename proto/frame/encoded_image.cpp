#include "proto/frame/encoded_image.h"

#include <algorithm>
#include <cstdint>
#include <exception>
#include <vector>

namespace tcfarm {
namespace {

// OpenImageIO's messages may span lines; an API error is one line.
std::string OneLine(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  for (size_t at = text.find('\n'); at != std::string::npos; at = text.find('\n', at)) text.replace(at, 1, "; ");
  return text;
}

// Texture images the tracer accepts: a side of at most 65536 texels, at most 2^28 texels
// (a 16k x 16k image), so that what a header claims cannot make a reader allocate without bound.
constexpr int64_t kMaxSide = 65536;
constexpr int64_t kMaxTexels = int64_t{1} << 28;

std::optional<std::string> SizeProblem(const OIIO::ImageSpec& spec) {
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0) return std::string("it holds no pixels");
  if (spec.width > kMaxSide || spec.height > kMaxSide || int64_t{spec.width} * spec.height > kMaxTexels ||
      spec.nchannels > 64) {
    return "it claims " + std::to_string(spec.width) + " x " + std::to_string(spec.height) + " texels of " +
           std::to_string(spec.nchannels) + " channels, more than the " + std::to_string(kMaxTexels) +
           " texels (sides up to " + std::to_string(kMaxSide) + ") a texture may have";
  }
  return std::nullopt;
}

constexpr int kRowsAtOnce = 64;

std::optional<std::string> DecodeProblem(const std::string& bytes) {
  MemoryImageInput opened = OpenImageInMemory(bytes);
  if (!opened.input) return "it is not an image OpenImageIO can read (" + OneLine(opened.error) + ")";
  const OIIO::ImageSpec& spec = opened.input->spec();
  if (auto problem = SizeProblem(spec)) return problem;
  std::vector<unsigned char> rows(static_cast<size_t>(spec.width) * spec.nchannels * kRowsAtOnce);
  for (int y = spec.y; y < spec.y + spec.height; y += kRowsAtOnce) {
    const int end = std::min(y + kRowsAtOnce, spec.y + spec.height);
    if (!opened.input->read_scanlines(0, 0, y, end, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, rows.data())) {
      return "its pixels do not decode (" + OneLine(opened.input->geterror()) + ")";
    }
  }
  return std::nullopt;
}

}  // namespace

std::string ReaderNameFor(const std::string& bytes) {
  if (bytes.rfind("\x89PNG", 0) == 0) return "image.png";
  if (bytes.rfind("\xff\xd8", 0) == 0) return "image.jpg";
  if (bytes.size() >= 12 && bytes.rfind("RIFF", 0) == 0 && bytes.compare(8, 4, "WEBP") == 0) return "image.webp";
  return "image";
}

MemoryImageInput OpenImageInMemory(const std::string& bytes) {
  MemoryImageInput opened;
  opened.reader = std::make_unique<OIIO::Filesystem::IOMemReader>(bytes.data(), bytes.size());
  opened.input = OIIO::ImageInput::open(ReaderNameFor(bytes), nullptr, opened.reader.get());
  if (!opened.input) {
    opened.error = OIIO::geterror();
    if (opened.error.empty()) opened.error = "no image reader recognises it";
  }
  return opened;
}

std::optional<std::string> EncodedImageProblem(const std::string& bytes) {
  try {
    return DecodeProblem(bytes);
  } catch (const std::exception& error) {  // a reader that throws on hostile bytes
    return "it is not an image OpenImageIO can read (" + OneLine(error.what()) + ")";
  }
}

uint64_t EncodedImageDecodeBytes(const std::string& bytes) {
  try {
    MemoryImageInput opened = OpenImageInMemory(bytes);
    if (!opened.input || SizeProblem(opened.input->spec())) return 0;
    const OIIO::ImageSpec& spec = opened.input->spec();
    const uint64_t channels = static_cast<uint64_t>(spec.width) * static_cast<uint64_t>(spec.nchannels);
    return 2 * channels * static_cast<uint64_t>(spec.height) + channels * kRowsAtOnce;
  } catch (const std::exception&) {  // EncodedImageProblem says why
    return 0;
  }
}

}  // namespace tcfarm
