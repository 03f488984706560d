// Texture images as shading samples them: decoded once with OpenImageIO, their sRGB codes
// turned linear, sampled at a hit's texture coordinates with the texture's wrap and filter.
// Sampling uses the coordinates alone (no derivatives, no mip levels), so a pixel's colour
// never depends on which other pixels are traced with it.
#pragma once

#include <stdexcept>
#include <vector>

#include "proto/scene/scene.h"
#include "worker/trace/float3.h"

namespace tcfarm {

class TextureError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class TextureImage {
 public:
  // How texel codes become values: sRGB-decoded (colours: base colour, emissive) or as
  // they are, over 255 (data: metallic-roughness, normal and occlusion maps).
  enum class Encoding { kSrgb, kLinear };
  // Throws TextureError naming the file when it cannot be read as an image.
  explicit TextureImage(const Texture& texture, Encoding encoding = Encoding::kSrgb);

  // Linear RGB at (u, v): u to the right, v down, [0, 1] across the image.
  Float3 Sample(float u, float v) const;
  // Its alpha at (u, v), filtered as the colour is; 1 where the image has no alpha.
  float SampleAlpha(float u, float v) const;
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  Float3 Texel(int x, int y) const { return texels_[static_cast<size_t>(y) * width_ + x]; }

  int width_ = 0, height_ = 0;
  std::vector<Float3> texels_;
  std::vector<float> alpha_;  // empty: opaque
  // Where (u, v) falls: up to four texels and their weights (nearest: one of weight 1).
  struct Footprint {
    int x[2], y[2];
    float wx, wy;
  };
  Footprint Locate(float u, float v) const;
  Texture::Wrap wrapS_, wrapT_;
  Texture::Filter filter_;
};

}  // namespace tcfarm
