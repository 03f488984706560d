#include "worker/trace/textures.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>
#include <string>

#include "proto/frame/encoded_image.h"

namespace tcfarm {
namespace {

// The sRGB transfer function, inverted, in double: every code decodes to the same float.
float LinearFromSrgb(float code) {
  const double c = code;
  return static_cast<float>(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

// A texel index wrapped into [0, size) as the texture's wrap mode says.
int WrapIndex(int index, int size, Texture::Wrap wrap) {
  switch (wrap) {
    case Texture::Wrap::kRepeat:
      return ((index % size) + size) % size;
    case Texture::Wrap::kClampToEdge:
      return std::clamp(index, 0, size - 1);
    case Texture::Wrap::kMirroredRepeat: {
      const int period = 2 * size;
      const int folded = ((index % period) + period) % period;
      return folded < size ? folded : period - 1 - folded;
    }
  }
  return 0;
}

}  // namespace

TextureImage::TextureImage(const Texture& texture, Encoding encoding)
    : wrapS_(texture.wrapS), wrapT_(texture.wrapT), filter_(texture.filter) {
  const std::string name = texture.Describe();
  if (!texture.bytes && texture.file.empty()) throw TextureError("texture " + name + " has not been fetched");
  // The reader of an image in memory must outlive the read below, which is forced whole.
  std::unique_ptr<OIIO::Filesystem::IOMemReader> memory;
  if (texture.bytes) memory = std::make_unique<OIIO::Filesystem::IOMemReader>(texture.bytes->data(), texture.bytes->size());
  // PNG alpha is unassociated (glTF's base colour and its coverage apart): read as it is,
  // not premultiplied into the colour, which would darken every part less than opaque.
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  OIIO::ImageBuf image(texture.bytes ? ReaderNameFor(*texture.bytes) : texture.file.string(), 0, 0, nullptr, &config,
                       memory.get());
  if (!image.read(0, 0, true, OIIO::TypeDesc::FLOAT)) {
    throw TextureError("cannot read texture image " + name + ": " + image.geterror());
  }
  const OIIO::ROI roi = image.roi();
  Level full;
  full.width = roi.width();
  full.height = roi.height();
  const int channels = image.nchannels();
  if (full.width <= 0 || full.height <= 0 || channels <= 0) throw TextureError("texture image " + name + " is empty");
  const size_t count = static_cast<size_t>(full.width) * full.height;
  std::vector<float> pixels(count * channels);
  image.get_pixels(roi, OIIO::TypeDesc::FLOAT, pixels.data());
  full.texels.reserve(count);
  // Grey and alpha, or RGB and alpha: the last channel is coverage (glTF's base colour alpha).
  const bool hasAlpha = channels == 2 || channels >= 4;
  if (hasAlpha) full.alpha.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    const float* p = &pixels[i * channels];
    if (hasAlpha) full.alpha.push_back(p[channels == 2 ? 1 : 3]);
    // Grey images repeat their one channel.
    const float r = p[0], g = channels >= 3 ? p[1] : p[0], b = channels >= 3 ? p[2] : p[0];
    full.texels.push_back(encoding == Encoding::kSrgb ? Float3{LinearFromSrgb(r), LinearFromSrgb(g), LinearFromSrgb(b)}
                                                      : Float3{r, g, b});
  }
  levels_.push_back(std::move(full));
  if (!texture.mipmaps) return;
  while (levels_.back().width > 1 || levels_.back().height > 1) levels_.push_back(Halved(levels_.back()));
}

TextureImage::Level TextureImage::Halved(const Level& finer) {
  Level coarser;
  coarser.width = std::max(finer.width / 2, 1);
  coarser.height = std::max(finer.height / 2, 1);
  // The finer texels [first, end) that coarser texel i covers along a side: two, or three
  // at an odd side's end (and one where the side is already 1 texel).
  auto span = [](int i, int coarse, int fine) {
    const int first = fine == 1 ? 0 : 2 * i;
    const int end = fine == 1 ? 1 : (i == coarse - 1 ? fine : 2 * i + 2);
    return std::pair<int, int>{first, end};
  };
  const bool hasAlpha = !finer.alpha.empty();
  for (int y = 0; y < coarser.height; ++y) {
    const auto [y0, y1] = span(y, coarser.height, finer.height);
    for (int x = 0; x < coarser.width; ++x) {
      const auto [x0, x1] = span(x, coarser.width, finer.width);
      // Summed in double, in one fixed order: every worker builds the same levels.
      double r = 0, g = 0, b = 0, a = 0;
      for (int fy = y0; fy < y1; ++fy) {
        for (int fx = x0; fx < x1; ++fx) {
          const Float3 t = finer.Texel(fx, fy);
          r += t.x, g += t.y, b += t.z;
          if (hasAlpha) a += finer.Alpha(fx, fy);
        }
      }
      const double n = static_cast<double>((x1 - x0) * (y1 - y0));
      coarser.texels.push_back({static_cast<float>(r / n), static_cast<float>(g / n), static_cast<float>(b / n)});
      if (hasAlpha) coarser.alpha.push_back(static_cast<float>(a / n));
    }
  }
  return coarser;
}

TextureImage::Footprint TextureImage::Locate(const Level& level, float u, float v, Texture::Filter filter) const {
  const int width = level.width, height = level.height;
  // Coordinates far out (or not numbers) would overflow the texel index: they sample the
  // image's origin instead, which no sensible mesh asks for.
  float x = u * width, y = v * height;
  if (!(std::fabs(x) < 1e8f)) x = 0;
  if (!(std::fabs(y) < 1e8f)) y = 0;
  if (filter == Texture::Filter::kNearest) {
    const int ix = WrapIndex(static_cast<int>(std::floor(x)), width, wrapS_);
    const int iy = WrapIndex(static_cast<int>(std::floor(y)), height, wrapT_);
    return {{ix, ix}, {iy, iy}, 0, 0};
  }
  // Bilinear between the four texel centres around the point.
  const float fx = x - 0.5f, fy = y - 0.5f;
  const float x0 = std::floor(fx), y0 = std::floor(fy);
  const int ix = static_cast<int>(x0), iy = static_cast<int>(y0);
  return {{WrapIndex(ix, width, wrapS_), WrapIndex(ix + 1, width, wrapS_)},
          {WrapIndex(iy, height, wrapT_), WrapIndex(iy + 1, height, wrapT_)},
          fx - x0,
          fy - y0};
}

Float3 TextureImage::SampleLevel(int index, float u, float v, Texture::Filter filter) const {
  const Level& level = levels_[static_cast<size_t>(index)];
  const Footprint at = Locate(level, u, v, filter);
  if (filter == Texture::Filter::kNearest) return level.Texel(at.x[0], at.y[0]);
  const Float3 upper = level.Texel(at.x[0], at.y[0]) * (1 - at.wx) + level.Texel(at.x[1], at.y[0]) * at.wx;
  const Float3 lower = level.Texel(at.x[0], at.y[1]) * (1 - at.wx) + level.Texel(at.x[1], at.y[1]) * at.wx;
  return upper * (1 - at.wy) + lower * at.wy;
}

float TextureImage::SampleAlphaLevel(int index, float u, float v, Texture::Filter filter) const {
  const Level& level = levels_[static_cast<size_t>(index)];
  if (level.alpha.empty()) return 1.0f;
  const Footprint at = Locate(level, u, v, filter);
  if (filter == Texture::Filter::kNearest) return level.Alpha(at.x[0], at.y[0]);
  const float upper = level.Alpha(at.x[0], at.y[0]) * (1 - at.wx) + level.Alpha(at.x[1], at.y[0]) * at.wx;
  const float lower = level.Alpha(at.x[0], at.y[1]) * (1 - at.wx) + level.Alpha(at.x[1], at.y[1]) * at.wx;
  return upper * (1 - at.wy) + lower * at.wy;
}

template <typename Value, typename SampleAt>
Value TextureImage::Trilinear(float lod, SampleAt sampleAt) const {
  const int last = Levels() - 1;
  if (lod >= static_cast<float>(last)) return sampleAt(last);
  const int finer = static_cast<int>(std::floor(lod));
  const float toCoarser = lod - static_cast<float>(finer);
  if (toCoarser == 0) return sampleAt(finer);
  return sampleAt(finer) * (1 - toCoarser) + sampleAt(finer + 1) * toCoarser;
}

Float3 TextureImage::Sample(float u, float v, float lod) const {
  if (AtFullImage(lod)) return Sample(u, v);
  return Trilinear<Float3>(lod, [&](int level) { return SampleLevel(level, u, v, Texture::Filter::kLinear); });
}

float TextureImage::SampleAlpha(float u, float v, float lod) const {
  if (AtFullImage(lod)) return SampleAlpha(u, v);
  return Trilinear<float>(lod, [&](int level) { return SampleAlphaLevel(level, u, v, Texture::Filter::kLinear); });
}

}  // namespace tcfarm
