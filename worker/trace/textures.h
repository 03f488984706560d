// Texture images as shading samples them: decoded once with OpenImageIO, their sRGB codes
// turned linear, sampled at a hit's texture coordinates with the texture's wrap and filter.
// Each image keeps a mip pyramid, built once at load: glTF materials sample it at the level
// their own ray's footprint asks for (ray_cone.h), never from neighbouring pixels, so a
// pixel's colour never depends on which other pixels are traced with it.
#pragma once

#include <array>
#include <functional>
#include <memory>
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
  Float3 Sample(float u, float v) const { return SampleLevel(0, u, v, filter_); }
  // At mip level `lod` (log2 of the footprint's width in texels of the full image):
  // trilinear between the two levels around it, the last level beyond it; lod <= 0 (or
  // not a number) samples the full image exactly as Sample does, with the texture's filter
  // (which magnifies: minified, every texture filters linearly). A texture without mip
  // levels (Texture::mipmaps false) samples the full image at any lod.
  Float3 Sample(float u, float v, float lod) const;
  // Its alpha at (u, v), filtered as the colour is; 1 where the image has no alpha.
  float SampleAlpha(float u, float v) const { return SampleAlphaLevel(0, u, v, filter_); }
  float SampleAlpha(float u, float v, float lod) const;
  int width() const { return levels_[0].width; }
  int height() const { return levels_[0].height; }
  // Mip levels, the full image first: each halves the one before (rounded down, at least
  // 1 texel), down to 1 x 1; the full image alone where the texture has no mip levels.
  int Levels() const { return static_cast<int>(levels_.size()); }
  // The level's texel (x, y) and its alpha (1 where the image has none).
  Float3 LevelTexel(int level, int x, int y) const { return levels_[level].Texel(x, y); }
  float LevelAlpha(int level, int x, int y) const { return levels_[level].Alpha(x, y); }

 private:
  struct Level {
    int width = 0, height = 0;
    std::vector<Float3> texels;
    std::vector<float> alpha;  // empty: opaque
    Float3 Texel(int x, int y) const { return texels[static_cast<size_t>(y) * width + x]; }
    float Alpha(int x, int y) const { return alpha.empty() ? 1.0f : alpha[static_cast<size_t>(y) * width + x]; }
  };
  // The level below `finer`: each texel the box average of the finer texels it covers
  // (2 x 2; 3 along an odd side's last texel, so every texel counts once).
  static Level Halved(const Level& finer);
  // Where (u, v) falls: up to four texels and their weights (nearest: one of weight 1).
  struct Footprint {
    int x[2], y[2];
    float wx, wy;
  };
  Footprint Locate(const Level& level, float u, float v, Texture::Filter filter) const;
  Float3 SampleLevel(int level, float u, float v, Texture::Filter filter) const;
  float SampleAlphaLevel(int level, float u, float v, Texture::Filter filter) const;
  // Between levels: trilinear weights of `lod`'s two levels, or the last level alone.
  template <typename Value, typename SampleAt>
  Value Trilinear(float lod, SampleAt sampleAt) const;
  // Whether `lod` samples the full image alone.
  bool AtFullImage(float lod) const { return !(lod > 0) || levels_.size() == 1; }

  std::vector<Level> levels_;
  Texture::Wrap wrapS_, wrapT_;
  Texture::Filter filter_;
};

// Decodes a texture image once: the tracer keeps each image, by its colour encoding. A
// material model's shading takes its images from one, when it is made.
using TextureLoader = std::function<const TextureImage*(const Texture&, TextureImage::Encoding)>;

// A shape's texture coordinates in float, TEXCOORD_0 and _1 (empty where it has none), as
// the tracer holds them: shapes placing one mesh share them.
using ShapeUvSets = std::array<std::shared_ptr<const std::vector<std::array<float, 2>>>, 2>;

}  // namespace tcfarm
