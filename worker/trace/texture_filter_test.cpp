// glTF textures filtered by the pixel's own ray cone: each image keeps a mip pyramid of box
// averages, sampled trilinearly at the level the footprint asks for; a fine checker far
// away shows its average while near it shows its texels, and a pixel traced alone has the
// bits it has in the whole frame.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "worker/trace/textures.h"
#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

// A grey 8-bit PNG whose texel (x, y) has code code(x, y).
void WriteGreyPng(const fs::path& path, int width, int height, const std::function<int(int, int)>& code) {
  std::vector<unsigned char> texels;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) texels.push_back(static_cast<unsigned char>(code(x, y)));
  }
  auto out = OIIO::ImageOutput::create(path.string());
  const OIIO::ImageSpec spec(width, height, 1, OIIO::TypeDesc::UINT8);
  ASSERT_TRUE(out && out->open(path.string(), spec) && out->write_image(OIIO::TypeDesc::UINT8, texels.data()));
  out->close();
}

int Checker(int x, int y) { return (x + y) % 2 ? 255 : 0; }

class TextureFilterTest : public testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_texture_filter_test_" + std::to_string(::getpid()));
    fs::create_directories(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  TextureImage Load(const std::string& name) {
    Texture texture;
    texture.image = name;
    texture.file = folder_ / name;
    return TextureImage(texture, TextureImage::Encoding::kLinear);
  }

  // An unlit glTF panel 2 x 2 facing a camera `distance` away, its base colour a checker
  // of 64 x 64 single texels: each pixel shows the filtered texture alone.
  Scene CheckerPanel(double distance, int samples = 1, bool mipmaps = true) {
    WriteGreyPng(folder_ / "fine.png", 64, 64, Checker);
    const std::string d = std::to_string(distance);
    return ParseScene(R"({"camera": {"position": [0, 0, )" + d + R"(], "look_at": [0, 0, 0], "fov_degrees": 60},
      "materials": {"fine": {"pbr": {"base_color_texture": {"image": "fine.png", "mipmaps": )" +
                          (mipmaps ? "true" : "false") + R"(}, "unlit": true}}},
      "shapes": [{"type": "mesh", "material": "fine",
                  "vertices": [[-1, 1, 0], [1, 1, 0], [1, -1, 0], [-1, -1, 0]],
                  "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]],
                  "triangles": [[0, 3, 2], [0, 2, 1]]}],
      "render": {"width": 96, "height": 96, "samples_per_pixel": )" + std::to_string(samples) + "}}",
                      folder_);
  }

  static std::vector<float> Render(const Scene& scene) {
    EmbreeDevice device;
    TracingThreads threads(2);
    Tracer tracer(device, scene, threads);
    std::vector<float> rgb(static_cast<size_t>(scene.render.width) * scene.render.height * 3);
    tracer.TraceFrame(0, rgb.data());
    return rgb;
  }

  // The smallest and largest red of the pixels within `half` of the image's centre.
  static std::pair<float, float> RangeAroundCentre(const std::vector<float>& rgb, int half) {
    float low = 1e9f, high = -1e9f;
    for (int y = 48 - half; y < 48 + half; ++y) {
      for (int x = 48 - half; x < 48 + half; ++x) {
        low = std::min(low, rgb[3 * (y * 96 + x)]);
        high = std::max(high, rgb[3 * (y * 96 + x)]);
      }
    }
    return {low, high};
  }

  fs::path folder_;
};

TEST_F(TextureFilterTest, LevelsAverageTheTexelsTheyCover) {
  WriteGreyPng(folder_ / "checker.png", 8, 8, Checker);
  const TextureImage image = Load("checker.png");
  ASSERT_EQ(image.Levels(), 4);  // 8, 4, 2, 1
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 4; ++x) EXPECT_FLOAT_EQ(image.LevelTexel(1, x, y).x, 0.5f) << x << "," << y;
  }
  EXPECT_FLOAT_EQ(image.LevelTexel(3, 0, 0).y, 0.5f);
  EXPECT_FLOAT_EQ(image.LevelAlpha(1, 0, 0), 1.0f);  // no alpha: opaque at every level
}

TEST_F(TextureFilterTest, OddSidesFoldTheirLastTexelIntoTheLastAverage) {
  // 5 x 3, codes 10 x column: level 1 is 2 x 1, columns {0, 1} and {2, 3, 4}
  // over all 3 rows; level 2 is 1 x 1, their average.
  WriteGreyPng(folder_ / "ramp.png", 5, 3, [](int x, int) { return 10 * x; });
  const TextureImage image = Load("ramp.png");
  ASSERT_EQ(image.Levels(), 3);
  EXPECT_NEAR(image.LevelTexel(1, 0, 0).x, 5 / 255.0f, 1e-6f);
  EXPECT_NEAR(image.LevelTexel(1, 1, 0).x, 30 / 255.0f, 1e-6f);
  EXPECT_NEAR(image.LevelTexel(2, 0, 0).x, 17.5f / 255.0f, 1e-6f);  // the average of level 1
}

TEST_F(TextureFilterTest, LodZeroOrBelowIsTheBilinearSampleToTheBit) {
  WriteGreyPng(folder_ / "ramp.png", 7, 5, [](int x, int y) { return 30 * x + 7 * y; });
  const TextureImage image = Load("ramp.png");
  for (float u : {0.0f, 0.13f, 0.5f, 0.77f, 1.4f}) {
    for (float v : {0.0f, 0.31f, 0.9f}) {
      const Float3 bilinear = image.Sample(u, v);
      for (float lod : {0.0f, -1.0f, -100.0f}) {
        const Float3 at = image.Sample(u, v, lod);
        EXPECT_EQ(0, std::memcmp(&at, &bilinear, sizeof at)) << u << "," << v << " at lod " << lod;
      }
    }
  }
}

TEST_F(TextureFilterTest, BetweenLevelsItBlendsThem) {
  WriteGreyPng(folder_ / "checker.png", 8, 8, Checker);
  const TextureImage image = Load("checker.png");
  // At a texel centre level 0 reads that texel (black), level 1 reads 0.5.
  const float u = 0.5f / 8, v = 0.5f / 8;
  EXPECT_FLOAT_EQ(image.Sample(u, v, 0.0f).x, 0.0f);
  EXPECT_FLOAT_EQ(image.Sample(u, v, 0.5f).x, 0.25f);
  EXPECT_FLOAT_EQ(image.Sample(u, v, 1.0f).x, 0.5f);
  EXPECT_FLOAT_EQ(image.Sample(u, v, 50.0f).x, 0.5f);  // beyond the last level: the last
}

TEST_F(TextureFilterTest, AFarCheckerShowsItsAverageANearOneItsTexels) {
  // Far: the panel covers about 12 pixels across, 5 texels a pixel.
  const auto far = RangeAroundCentre(Render(CheckerPanel(14)), 4);
  EXPECT_NEAR(far.first, 0.5f, 0.02f);
  EXPECT_NEAR(far.second, 0.5f, 0.02f);
  // Near: the panel fills the image, under a texel a pixel.
  const auto near = RangeAroundCentre(Render(CheckerPanel(1.5)), 40);
  EXPECT_LT(near.first, 0.1f);
  EXPECT_GT(near.second, 0.9f);
}

TEST_F(TextureFilterTest, ATextureWithoutMipmapsReadsTheFullImageAtAnyDistance) {
  const Scene scene = CheckerPanel(14, 1, false);
  // Kept through the scene's JSON, which names it only when off.
  EXPECT_NE(SerializeScene(scene).find(R"("mipmaps":false)"), std::string::npos);
  EXPECT_EQ(SerializeScene(CheckerPanel(14)).find("mipmaps"), std::string::npos);
  const auto far = RangeAroundCentre(Render(scene), 4);
  EXPECT_GT(far.second - far.first, 0.5f);  // the checker's texels, aliasing
}

TEST_F(TextureFilterTest, APixelTracedAloneHasItsBitsInTheFrame) {
  for (int samples : {1, 4}) {
    const Scene scene = CheckerPanel(6, samples);
    const std::vector<float> full = Render(scene);
    EmbreeDevice device;
    TracingThreads threads(1);
    Tracer tracer(device, scene, threads);
    for (uint32_t pixel : {0u, 96u * 40 + 41, 96u * 48 + 48, 96u * 55 + 30, 96u * 96 - 1}) {
      float rgb[3];
      tracer.TracePixels(0, &pixel, 1, rgb);
      EXPECT_EQ(0, std::memcmp(rgb, &full[3 * pixel], sizeof rgb)) << "pixel " << pixel << ", " << samples << " samples";
    }
  }
}

}  // namespace
}  // namespace tcfarm
