// Frame files: the farm's output contract. Every frame is written twice: OpenEXR with
// 32-bit float linear RGB (the exact values, for compositing and for bit-exact checks)
// and 8-bit sRGB PNG (for eyes and browsers).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "proto/frame/view_transform.h"

namespace tcfarm {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;  // width * height * 3, linear, row-major from the top row
  size_t PixelCount() const { return static_cast<size_t>(width) * height; }
};

class FrameIoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Lossless EXR compressions only: the EXR is the exact record of every bit. Zip is
// OpenEXR's usual choice; at level 1 ("zip:1") it writes ~1.4x faster than the default
// level at the same size on traced floats, whose low mantissa bits do not compress;
// "none" writes ~10x faster and ~1.8x larger.
bool IsLosslessExrCompression(const std::string& name);
void WriteExr(const std::filesystem::path& path, const Image& image,
              const std::string& compression = "zip:1");
// The 8-bit preview: the image's values through `view` (view_transform.h).
void WritePng(const std::filesystem::path& path, const Image& image, const ViewTransform& view = {});
// The PNG file WritePng writes, as bytes. Throws FrameIoError when it cannot be encoded.
std::string EncodePng(const Image& image, const ViewTransform& view = {});
// The compression an EXR file was written with, as OpenImageIO names it ("zip", "none",
// ...; a level is not recorded). Throws FrameIoError when the file cannot be read.
std::string ExrCompressionOf(const std::filesystem::path& path);
// A mask as an 8-bit greyscale PNG: white (255) where mask is non-zero, black elsewhere.
// mask holds width * height values, row-major from the top row.
void WriteMaskPng(const std::filesystem::path& path, int width, int height,
                  const std::vector<uint8_t>& mask);
// Reads any format OpenImageIO knows into linear float RGB (PNG is decoded from sRGB;
// a greyscale image's one channel fills all three).
Image ReadImage(const std::filesystem::path& path);

// Where a file is written before it is renamed into place: "<path>.<pid>-<n>.partial",
// a name of its own for every write, so that two writers of the same file at once (a frame
// rendered again while the frame finisher compresses it, a preview made on request while
// the finisher makes it) never write into each other's bytes; the last rename wins, whole.
std::filesystem::path PartialPathFor(const std::filesystem::path& path);

// "frame_0042" for frame 42: frames sort by name.
std::string FrameFileStem(int frame);
// "mask_0042" / "change_0042" for frame 42's traced mask and change mask (kind: "mask"
// or "change").
std::string MaskFileStem(const std::string& kind, int frame);

// Linear value to an 8-bit sRGB code, clamped to [0, 1] first.
uint8_t LinearToSrgb8(float linear);
// The same code by table look-up, ~15x faster; equal to LinearToSrgb8 for every float.
uint8_t LinearToSrgb8Fast(float linear);

}  // namespace tcfarm
