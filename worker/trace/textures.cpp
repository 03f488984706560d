#include "worker/trace/textures.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>

#include <algorithm>
#include <cmath>
#include <memory>
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
  width_ = roi.width();
  height_ = roi.height();
  const int channels = image.nchannels();
  if (width_ <= 0 || height_ <= 0 || channels <= 0) throw TextureError("texture image " + name + " is empty");
  std::vector<float> pixels(static_cast<size_t>(width_) * height_ * channels);
  image.get_pixels(roi, OIIO::TypeDesc::FLOAT, pixels.data());
  texels_.reserve(static_cast<size_t>(width_) * height_);
  // Grey and alpha, or RGB and alpha: the last channel is coverage (glTF's base colour alpha).
  const bool hasAlpha = channels == 2 || channels >= 4;
  if (hasAlpha) alpha_.reserve(static_cast<size_t>(width_) * height_);
  for (size_t i = 0; i < static_cast<size_t>(width_) * height_; ++i) {
    const float* p = &pixels[i * channels];
    if (hasAlpha) alpha_.push_back(p[channels == 2 ? 1 : 3]);
    // Grey images repeat their one channel.
    const float r = p[0], g = channels >= 3 ? p[1] : p[0], b = channels >= 3 ? p[2] : p[0];
    texels_.push_back(encoding == Encoding::kSrgb ? Float3{LinearFromSrgb(r), LinearFromSrgb(g), LinearFromSrgb(b)}
                                                  : Float3{r, g, b});
  }
}

TextureImage::Footprint TextureImage::Locate(float u, float v) const {
  // Coordinates far out (or not numbers) would overflow the texel index: they sample the
  // image's origin instead, which no sensible mesh asks for.
  float x = u * width_, y = v * height_;
  if (!(std::fabs(x) < 1e8f)) x = 0;
  if (!(std::fabs(y) < 1e8f)) y = 0;
  if (filter_ == Texture::Filter::kNearest) {
    const int ix = WrapIndex(static_cast<int>(std::floor(x)), width_, wrapS_);
    const int iy = WrapIndex(static_cast<int>(std::floor(y)), height_, wrapT_);
    return {{ix, ix}, {iy, iy}, 0, 0};
  }
  // Bilinear between the four texel centres around the point.
  const float fx = x - 0.5f, fy = y - 0.5f;
  const float x0 = std::floor(fx), y0 = std::floor(fy);
  const int ix = static_cast<int>(x0), iy = static_cast<int>(y0);
  return {{WrapIndex(ix, width_, wrapS_), WrapIndex(ix + 1, width_, wrapS_)},
          {WrapIndex(iy, height_, wrapT_), WrapIndex(iy + 1, height_, wrapT_)},
          fx - x0,
          fy - y0};
}

Float3 TextureImage::Sample(float u, float v) const {
  const Footprint at = Locate(u, v);
  if (filter_ == Texture::Filter::kNearest) return Texel(at.x[0], at.y[0]);
  const Float3 upper = Texel(at.x[0], at.y[0]) * (1 - at.wx) + Texel(at.x[1], at.y[0]) * at.wx;
  const Float3 lower = Texel(at.x[0], at.y[1]) * (1 - at.wx) + Texel(at.x[1], at.y[1]) * at.wx;
  return upper * (1 - at.wy) + lower * at.wy;
}

float TextureImage::SampleAlpha(float u, float v) const {
  if (alpha_.empty()) return 1.0f;
  const Footprint at = Locate(u, v);
  auto texel = [&](int x, int y) { return alpha_[static_cast<size_t>(y) * width_ + x]; };
  if (filter_ == Texture::Filter::kNearest) return texel(at.x[0], at.y[0]);
  const float upper = texel(at.x[0], at.y[0]) * (1 - at.wx) + texel(at.x[1], at.y[0]) * at.wx;
  const float lower = texel(at.x[0], at.y[1]) * (1 - at.wx) + texel(at.x[1], at.y[1]) * at.wx;
  return upper * (1 - at.wy) + lower * at.wy;
}

}  // namespace tcfarm
