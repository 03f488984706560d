// The image formats a glTF texture may embed, decoded from memory as workers get them: PNG,
// JPEG and WebP (EXT_texture_webp), the format known by its bytes' signature alone.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>

#include "proto/frame/encoded_image.h"
#include "worker/trace/textures.h"

namespace tcfarm {
namespace {

// The same 2x2 texels (top row red and green, bottom row blue and white) as PNG and as
// lossless WebP, written by Pillow.
const std::string kCheckerPng(
    "\x89\x50\x4E\x47\x0D\x0A\x1A\x0A\x00\x00\x00\x0D\x49\x48\x44\x52\x00\x00\x00\x02\x00\x00\x00\x02"
    "\x08\x02\x00\x00\x00\xFD\xD4\x9A\x73\x00\x00\x00\x16\x49\x44\x41\x54\x78\x9C\x63\xF8\xCF\xC0\xC0"
    "\xF0\x9F\x81\x91\x81\xE1\xFF\xFF\xFF\x0C\x00\x1E\xF6\x04\xFD\x09\xED\x34\x3E\x00\x00\x00\x00\x49"
    "\x45\x4E\x44\xAE\x42\x60\x82",
    79);
const std::string kCheckerLosslessWebp(
    "\x52\x49\x46\x46\x2C\x00\x00\x00\x57\x45\x42\x50\x56\x50\x38\x4C\x1F\x00\x00\x00\x2F\x01\x40\x00"
    "\x00\x1F\x20\x10\x48\xDE\x1F\x3A\x8D\xF9\x17\x10\x14\xFC\x1F\xDD\xFC\x47\x64\x0F\xE0\x06\x0C\x11"
    "\xFD\x0F\x01\x00",
    52);

Texture InMemory(const std::string& bytes) {
  Texture texture;
  texture.image = "test image";
  texture.bytes = std::make_shared<const std::string>(bytes);
  texture.mipmaps = false;
  texture.filter = Texture::Filter::kNearest;
  return texture;
}

void ExpectSameTexels(const TextureImage& a, const TextureImage& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  for (float v : {0.25f, 0.75f}) {
    for (float u : {0.25f, 0.75f}) {
      const Float3 x = a.Sample(u, v), y = b.Sample(u, v);
      EXPECT_EQ(x.x, y.x) << u << " " << v;
      EXPECT_EQ(x.y, y.y) << u << " " << v;
      EXPECT_EQ(x.z, y.z) << u << " " << v;
    }
  }
}

TEST(TextureFormatsTest, LosslessWebpDecodesToThePngsTexels) {
  const std::string webp = kCheckerLosslessWebp;
  EXPECT_EQ(ReaderNameFor(webp), "image.webp");
  EXPECT_EQ(EncodedImageProblem(webp), std::nullopt);
  const TextureImage png(InMemory(kCheckerPng));
  ExpectSameTexels(TextureImage(InMemory(webp)), png);
  EXPECT_EQ(png.Sample(0.25f, 0.25f).x, 1.0f);  // red, top left
  EXPECT_EQ(png.Sample(0.25f, 0.25f).y, 0.0f);
}

TEST(TextureFormatsTest, JpegDecodesFromMemory) {
  // 16 x 16 of one orange, at JPEG's best quality: within a code of it everywhere.
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("tcfarm_texture_formats_" + std::to_string(::getpid()) + ".jpg");
  OIIO::ImageSpec spec(16, 16, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("CompressionQuality", 100);
  std::string codes(3 * 16 * 16, '\0');
  for (size_t i = 0; i < codes.size(); i += 3) codes.replace(i, 3, "\xF0\x80\x20");
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out && out->open(path.string(), spec) && out->write_image(OIIO::TypeDesc::UINT8, codes.data()));
  out->close();
  std::ifstream in(path, std::ios::binary);
  const std::string jpeg((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::filesystem::remove(path);
  EXPECT_EQ(ReaderNameFor(jpeg), "image.jpg");
  const TextureImage image(InMemory(jpeg), TextureImage::Encoding::kLinear);
  ASSERT_EQ(image.width(), 16);
  const Float3 texel = image.Sample(0.5f, 0.5f);
  EXPECT_NEAR(texel.x, 0xF0 / 255.0, 1.5 / 255);
  EXPECT_NEAR(texel.y, 0x80 / 255.0, 1.5 / 255);
  EXPECT_NEAR(texel.z, 0x20 / 255.0, 1.5 / 255);
}

}  // namespace
}  // namespace tcfarm
