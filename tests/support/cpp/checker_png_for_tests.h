// Tests' texture: 2x2 texels as 8-bit sRGB codes, top row red and green, bottom row blue
// and white, written as a PNG.
#pragma once

#include <OpenImageIO/imageio.h>

#include <filesystem>
#include <stdexcept>

namespace tcfarm {

inline void WriteCheckerPng(const std::filesystem::path& path) {
  const unsigned char texels[] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
  auto out = OIIO::ImageOutput::create(path.string());
  const OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::UINT8);
  if (!out || !out->open(path.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT8, texels)) {
    throw std::runtime_error("cannot write " + path.string());
  }
  out->close();
}

}  // namespace tcfarm
