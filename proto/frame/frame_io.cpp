#include "proto/frame/frame_io.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

#include "proto/frame/page_aligned_output.h"

namespace tcfarm {
namespace {

// PNG deflate level: 3 encodes ~1.5x faster than the default 6 for ~25 % more bytes,
// and frames are written at the rate they are traced.
constexpr int kPngCompressionLevel = 3;
// libpng's PNG_FILTER_NONE. A mask is two values in runs: row filters do nothing for its
// size, and choosing them took three quarters of its encoding (2.4 ms against 0.57 ms
// for a 640x480 mask, 4.3 KB against 4.5 KB), written twice a frame while a job renders.
constexpr int kPngNoFilter = 8;

void WritePixels(const std::filesystem::path& path, int width, int height, int channels,
                 OIIO::TypeDesc format, const void* pixels, const std::string& exrCompression = "",
                 bool filterRows = true) {
  auto out = OIIO::ImageOutput::create(path.string());
  if (!out) throw FrameIoError("cannot write " + path.string() + ": " + OIIO::geterror());
  OIIO::ImageSpec spec(width, height, channels, format);
  if (format == OIIO::TypeDesc::FLOAT) spec.attribute("compression", exrCompression);
  if (format == OIIO::TypeDesc::UINT8) spec.attribute("png:compressionLevel", kPngCompressionLevel);
  if (!filterRows) spec.attribute("png:filter", kPngNoFilter);
  // Write to a temporary name and rename, so a reader never sees half a frame. The image
  // is encoded in memory first and written around the page cache (page_aligned_output.h);
  // the buffer is the thread's own, kept from one image to the next.
  const std::filesystem::path partial = PartialPathFor(path);
  thread_local PageAlignedOutput encoded;
  encoded.Reset();
  if (!out->set_ioproxy(&encoded) || !out->open(partial.string(), spec) || !out->write_image(format, pixels) ||
      !out->close()) {
    throw FrameIoError("cannot write " + path.string() + ": " + out->geterror());
  }
  try {
    WriteFileAroundCache(partial, encoded);
  } catch (const FrameIoError&) {
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    throw;
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) throw FrameIoError("cannot move " + partial.string() + " into place: " + ec.message());
}

void CheckShape(const std::filesystem::path& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0 || image.rgb.size() != image.PixelCount() * 3) {
    throw FrameIoError("cannot write " + path.string() + ": image of " +
                       std::to_string(image.width) + "x" + std::to_string(image.height) +
                       " holds " + std::to_string(image.rgb.size()) + " floats; expected " +
                       std::to_string(image.PixelCount() * 3));
  }
}

float SrgbToLinear(float code) {
  return code <= 0.04045f ? code / 12.92f : std::pow((code + 0.055f) / 1.055f, 2.4f);
}

// thresholds[k] is the smallest float that encodes to code k (k >= 1), found by
// bisection over the float bit patterns (monotone for non-negative floats), so the
// table agrees with LinearToSrgb8 exactly.
//
// Look-up goes by the top 16 bits of the float (exponent and 7 mantissa bits): across
// one such bucket a value grows by less than 1/128, and its code by less than one (the
// curve's steepest relative slope is 1/2.4 of the value's), so the bucket's first code
// or the next is the answer, told apart by one threshold.
struct SrgbThresholds {
  static constexpr int kBucketShift = 16;
  static constexpr uint32_t kOneBits = 0x3f800000;  // 1.0f
  float thresholds[257];
  uint8_t bucketCode[(kOneBits >> kBucketShift) + 1];
  SrgbThresholds() {
    thresholds[256] = INFINITY;  // no code above 255

    thresholds[0] = 0;
    for (int code = 1; code < 256; ++code) {
      uint32_t lo = 0, hi = 0x3f800000;  // bits of 0.0f and 1.0f
      while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        float value;
        std::memcpy(&value, &mid, sizeof value);
        if (LinearToSrgb8(value) >= code) hi = mid; else lo = mid + 1;
      }
      std::memcpy(&thresholds[code], &lo, sizeof lo);
    }
    for (uint32_t bucket = 0; bucket <= (kOneBits >> kBucketShift); ++bucket) {
      uint32_t bits = bucket << kBucketShift;
      float first;
      std::memcpy(&first, &bits, sizeof first);
      bucketCode[bucket] = LinearToSrgb8(first);
    }
  }
  uint8_t Code(float linear) const {
    uint32_t bits;
    std::memcpy(&bits, &linear, sizeof bits);
    uint8_t code = bucketCode[bits >> kBucketShift];
    return static_cast<uint8_t>(code + (linear >= thresholds[code + 1]));
  }
};

}  // namespace

uint8_t LinearToSrgb8Fast(float linear) {
  static const SrgbThresholds table;
  if (!(linear > 0)) return 0;  // also NaN
  if (linear >= 1) return 255;
  return table.Code(linear);
}

bool IsLosslessExrCompression(const std::string& name) {
  for (const char* lossless : {"none", "rle", "zips", "zip", "piz"}) {
    if (name == lossless) return true;
  }
  // zip and zips take a deflate level: "zip:1" .. "zip:9".
  bool zipFamily = name.rfind("zip:", 0) == 0 || name.rfind("zips:", 0) == 0;
  char level = name.empty() ? 0 : name.back();
  return zipFamily && name.size() == name.find(':') + 2 && level >= '1' && level <= '9';
}

uint8_t LinearToSrgb8(float linear) {
  float v = std::isfinite(linear) ? std::clamp(linear, 0.0f, 1.0f) : 0.0f;
  float code = v <= 0.0031308f ? v * 12.92f : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
  return static_cast<uint8_t>(std::lround(code * 255.0f));
}

void WriteExr(const std::filesystem::path& path, const Image& image,
              const std::string& compression) {
  CheckShape(path, image);
  if (!IsLosslessExrCompression(compression)) {
    throw FrameIoError("cannot write " + path.string() + ": EXR compression '" + compression +
                       "' is not lossless; expected none, rle, zips, zip or piz");
  }
  WritePixels(path, image.width, image.height, 3, OIIO::TypeDesc::FLOAT, image.rgb.data(), compression);
}

void WritePng(const std::filesystem::path& path, const Image& image, const ViewTransform& view) {
  CheckShape(path, image);
  const std::vector<uint8_t> codes = DisplayCodes(image.rgb, view);
  WritePixels(path, image.width, image.height, 3, OIIO::TypeDesc::UINT8, codes.data());
}

std::string EncodePng(const Image& image, const ViewTransform& view) {
  CheckShape("a PNG in memory", image);
  const std::vector<uint8_t> codes = DisplayCodes(image.rgb, view);
  std::vector<unsigned char> bytes;
  OIIO::Filesystem::IOVecOutput memory(bytes);
  auto out = OIIO::ImageOutput::create("preview.png");
  if (!out) throw FrameIoError("cannot encode a PNG: " + OIIO::geterror());
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("png:compressionLevel", kPngCompressionLevel);
  if (!out->set_ioproxy(&memory) || !out->open("preview.png", spec) ||
      !out->write_image(OIIO::TypeDesc::UINT8, codes.data()) || !out->close()) {
    throw FrameIoError("cannot encode a PNG: " + out->geterror());
  }
  return std::string(bytes.begin(), bytes.end());
}

void WriteMaskPng(const std::filesystem::path& path, int width, int height,
                  const std::vector<uint8_t>& mask) {
  if (width <= 0 || height <= 0 || mask.size() != static_cast<size_t>(width) * height) {
    throw FrameIoError("cannot write " + path.string() + ": mask of " + std::to_string(width) + "x" +
                       std::to_string(height) + " holds " + std::to_string(mask.size()) +
                       " values; expected " + std::to_string(static_cast<size_t>(width) * height));
  }
  std::vector<uint8_t> codes(mask.size());
  std::transform(mask.begin(), mask.end(), codes.begin(),
                 [](uint8_t value) { return static_cast<uint8_t>(value ? 255 : 0); });
  WritePixels(path, width, height, 1, OIIO::TypeDesc::UINT8, codes.data(), "", /*filterRows=*/false);
}

std::string ExrCompressionOf(const std::filesystem::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) throw FrameIoError("cannot read " + path.string() + ": " + OIIO::geterror());
  return in->spec().get_string_attribute("compression", "none");
}

Image ReadImage(const std::filesystem::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) throw FrameIoError("cannot read " + path.string() + ": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  Image image;
  image.width = spec.width;
  image.height = spec.height;
  image.rgb.resize(image.PixelCount() * 3);
  bool encodedSrgb = spec.format == OIIO::TypeDesc::UINT8;
  if (spec.nchannels < 3) {
    // Greyscale (a mask): its first channel in all three.
    std::vector<float> grey(image.PixelCount());
    if (!in->read_image(0, 0, 0, 1, OIIO::TypeDesc::FLOAT, grey.data())) {
      throw FrameIoError("cannot read " + path.string() + ": " + in->geterror());
    }
    for (size_t pixel = 0; pixel < grey.size(); ++pixel) {
      std::fill_n(&image.rgb[pixel * 3], 3, grey[pixel]);
    }
  } else if (!in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, image.rgb.data())) {
    throw FrameIoError("cannot read " + path.string() + ": " + in->geterror());
  }
  if (encodedSrgb) {
    for (float& v : image.rgb) v = SrgbToLinear(v);
  }
  return image;
}

std::filesystem::path PartialPathFor(const std::filesystem::path& path) {
  static std::atomic<uint64_t> writes{0};
  std::filesystem::path partial = path;
  partial += "." + std::to_string(::getpid()) + "-" + std::to_string(++writes) + ".partial";
  return partial;
}

std::string FrameFileStem(int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%04d", frame);
  return name;
}

std::string MaskFileStem(const std::string& kind, int frame) {
  char number[16];
  std::snprintf(number, sizeof number, "_%04d", frame);
  return kind + number;
}

}  // namespace tcfarm
