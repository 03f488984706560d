// Textured surfaces: the texels of an image show at the pixels its texture coordinates
// put them, linear after sRGB decoding, in every wrap and filter mode; vertex colours
// multiply the diffuse colour, textured or not.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tests/support/cpp/checker_png_for_tests.h"
#include "worker/trace/tracer.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

constexpr int kSize = 9;

class TextureTest : public testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_texture_test_" + std::to_string(::getpid()));
    fs::create_directories(folder_);
    WriteCheckerPng(folder_ / "checker.png");
  }
  void TearDown() override { fs::remove_all(folder_); }

  // A square facing the camera that fills the image, its texture coordinates spanning
  // [0, span] from the top left.
  Scene TexturedSquare(const std::string& texture, double span = 1) {
    const std::string s = std::to_string(span);
    return ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
      "lights": [{"type": "directional", "direction": [0, 0, -1], "intensity": [1, 1, 1]}],
      "materials": {"printed": {"diffuse": [1, 1, 1], "diffuse_texture": )" + texture + R"(}},
      "shapes": [{"type": "mesh", "material": "printed",
                  "vertices": [[-4, 4, 0], [4, 4, 0], [4, -4, 0], [-4, -4, 0]],
                  "uvs": [[0, 0], [)" + s + R"(, 0], [)" + s + ", " + s + R"(], [0, )" + s + R"(]],
                  "triangles": [[0, 3, 2], [0, 2, 1]]}],
      "render": {"width": 9, "height": 9}})",
                      folder_);
  }

  static std::vector<float> Render(const Scene& scene) {
    EmbreeDevice device;
    TracingThreads threads(2);
    Tracer tracer(device, scene, threads);
    std::vector<float> rgb(kSize * kSize * 3);
    tracer.TraceFrame(0, rgb.data());
    return rgb;
  }

  static Float3 At(const std::vector<float>& rgb, int x, int y) {
    const float* p = &rgb[3 * (y * kSize + x)];
    return {p[0], p[1], p[2]};
  }

  fs::path folder_;
};

// Lit head-on with unit irradiance: (cosine 1 + ambient 0.05) times the texel.
void ExpectTexel(Float3 pixel, Float3 texel, const std::string& where) {
  EXPECT_NEAR(pixel.x, 1.05f * texel.x, 1e-5f) << where;
  EXPECT_NEAR(pixel.y, 1.05f * texel.y, 1e-5f) << where;
  EXPECT_NEAR(pixel.z, 1.05f * texel.z, 1e-5f) << where;
}

TEST_F(TextureTest, TexelsShowWhereTheirCoordinatesPutThem) {
  auto rgb = Render(TexturedSquare(R"({"image": "checker.png", "filter": "nearest"})"));
  ExpectTexel(At(rgb, 2, 2), {1, 0, 0}, "top left");
  ExpectTexel(At(rgb, 6, 2), {0, 1, 0}, "top right");
  ExpectTexel(At(rgb, 2, 6), {0, 0, 1}, "bottom left");
  ExpectTexel(At(rgb, 6, 6), {1, 1, 1}, "bottom right");
}

TEST_F(TextureTest, CodesAreDecodedFromSrgb) {
  // Bilinear at the image's centre: the mean of the four linear texels.
  auto rgb = Render(TexturedSquare(R"({"image": "checker.png", "filter": "linear"})"));
  ExpectTexel(At(rgb, 4, 4), {0.5f, 0.5f, 0.5f}, "centre");
}

TEST_F(TextureTest, WrapModesRepeatClampAndMirror) {
  // Coordinates over [0, 2] across the square; the view shows its middle, so the pixel
  // at the lower right samples about (1.46, 1.46), texel (2, 2) before wrapping, and the
  // pixel at (5, 5) about (1.12, 1.12), texel (2, 2) as well.
  auto repeat = Render(TexturedSquare(R"({"image": "checker.png", "filter": "nearest"})", 2));
  auto clamp = Render(TexturedSquare(R"({"image": "checker.png", "filter": "nearest", "wrap_s": "clamp_to_edge",
                                         "wrap_t": "clamp_to_edge"})", 2));
  auto mirror = Render(TexturedSquare(R"({"image": "checker.png", "filter": "nearest", "wrap_s": "mirrored_repeat",
                                          "wrap_t": "mirrored_repeat"})", 2));
  ExpectTexel(At(repeat, 8, 8), {1, 0, 0}, "repeat");  // the next tile's first texel
  ExpectTexel(At(clamp, 8, 8), {1, 1, 1}, "clamp");    // held at the edge texel
  ExpectTexel(At(mirror, 8, 8), {1, 1, 1}, "mirror");  // folded back onto the last texel
  ExpectTexel(At(repeat, 5, 5), {1, 0, 0}, "repeat, second tile's first texel");
  ExpectTexel(At(clamp, 5, 5), {1, 1, 1}, "clamp past the edge");
}

TEST_F(TextureTest, BadTexturesAreRefusedWithTheirPointer) {
  auto failsAt = [&](const std::string& texture, const std::optional<fs::path>& folder, const std::string& pointer) {
    try {
      ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
        "materials": {"printed": {"diffuse_texture": )" + texture + R"(}}, "render": {"width": 4, "height": 4}})", folder);
    } catch (const SceneError& error) {
      EXPECT_EQ(error.pointer(), pointer) << error.what();
      return;
    }
    ADD_FAILURE() << texture << " was accepted";
  };
  failsAt(R"({"image": "missing.png"})", folder_, "/materials/printed/diffuse_texture/image");
  failsAt(R"({"image": "../checker.png"})", folder_, "/materials/printed/diffuse_texture/image");
  failsAt(R"({"image": "checker.png"})", std::nullopt, "/materials/printed/diffuse_texture/image");
  failsAt(R"({"image": "checker.png", "wrap_s": "tile"})", folder_, "/materials/printed/diffuse_texture/wrap_s");
  failsAt(R"({"image": "checker.png", "filter": "cubic"})", folder_, "/materials/printed/diffuse_texture/filter");
  failsAt(R"({"asset": "ABC"})", folder_, "/materials/printed/diffuse_texture/asset");
  failsAt(R"({"asset": ")" + std::string(64, 'a') + R"(", "image": "checker.png"})", folder_,
          "/materials/printed/diffuse_texture");
  failsAt(R"({"filter": "nearest"})", folder_, "/materials/printed/diffuse_texture");
}

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// A texture named by hash renders the same as the file it names, whether a worker's cache
// holds the image under its hash (no extension) or an imported glTF holds it in memory.
TEST_F(TextureTest, AnAssetRendersLikeItsFileFromDiskOrMemory) {
  const std::string texture = R"({"image": "checker.png", "filter": "nearest"})";
  const std::vector<float> expected = Render(TexturedSquare(texture));
  const std::string hash(64, 'a');
  Scene cached = TexturedSquare(R"({"asset": ")" + hash + R"(", "filter": "nearest"})");
  EXPECT_THROW(Render(cached), TextureError);  // not fetched yet
  fs::copy_file(folder_ / "checker.png", folder_ / hash);
  cached.materials[1].As<Phong>().diffuseTexture->file = folder_ / hash;
  EXPECT_EQ(Render(cached), expected);
  Scene inMemory = TexturedSquare(R"({"asset": ")" + hash + R"(", "filter": "nearest"})");
  inMemory.materials[1].As<Phong>().diffuseTexture->bytes = std::make_shared<const std::string>(ReadBytes(folder_ / "checker.png"));
  EXPECT_EQ(Render(inMemory), expected);
  EXPECT_EQ(SerializeScene(inMemory).find("checker"), std::string::npos);
  EXPECT_NE(SerializeScene(inMemory).find(R"("asset":")" + hash), std::string::npos);
}

TEST_F(TextureTest, AFileThatIsNoImageIsAClearError) {
  std::ofstream(folder_ / "notes.png") << "not an image";
  EXPECT_THROW(Render(TexturedSquare(R"({"image": "notes.png"})")), TextureError);
}

// The square with a colour per corner (red, green, blue, white from the top left, clockwise
// to the bottom left), textured or plain.
Scene ColouredSquare(const std::string& texture, const fs::path& folder) {
  const std::string material = texture.empty() ? "" : R"(, "diffuse_texture": )" + texture;
  return ParseScene(R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
      "lights": [{"type": "directional", "direction": [0, 0, -1], "intensity": [1, 1, 1]}],
      "materials": {"painted": {"diffuse": [1, 1, 1])" + material + R"(}},
      "shapes": [{"type": "mesh", "material": "painted",
                  "vertices": [[-4, 4, 0], [4, 4, 0], [4, -4, 0], [-4, -4, 0]],
                  "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]],
                  "colors": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]],
                  "triangles": [[0, 3, 2], [0, 2, 1]]}],
      "render": {"width": 9, "height": 9}})",
                    folder);
}

TEST_F(TextureTest, VertexColoursMultiplyTheDiffuseColourTexturedOrNot) {
  // The centre pixel lies on the diagonal from the top left to the bottom right: half the
  // top left's colour and half the bottom right's, red and blue.
  auto plain = Render(ColouredSquare("", folder_));
  ExpectTexel(At(plain, 4, 4), {0.5f, 0, 0.5f}, "centre, plain");
  // Above the centre, in the triangle of the red, blue and green corners: half red, then
  // blue, then a little green (the nearer the top right, the more). Below left, in the
  // triangle of the red, white and blue corners: green only from the white corner.
  Float3 above = At(plain, 4, 2), belowLeft = At(plain, 2, 6);
  EXPECT_NEAR(above.x, 0.5f * 1.05f, 1e-5f);
  EXPECT_GT(above.z, above.y);
  EXPECT_GT(above.y, 0.0f);
  EXPECT_GT(belowLeft.y, 0.0f);
  EXPECT_GT(belowLeft.x, belowLeft.y);
  EXPECT_GT(belowLeft.z, belowLeft.y);
  // Textured: the texel times the corner colour. The top left texel is red, the top
  // right green: each under its own corner's colour keeps most of its channel.
  auto textured = Render(ColouredSquare(R"({"image": "checker.png", "filter": "nearest"})", folder_));
  Float3 topLeft = At(textured, 1, 1), bottomLeft = At(textured, 1, 7);
  EXPECT_GT(topLeft.x, 0.5f);
  EXPECT_EQ(topLeft.y, 0.0f);
  EXPECT_EQ(topLeft.z, 0.0f);
  EXPECT_EQ(bottomLeft.x, 0.0f);  // the blue texel under the white corner and the blue one
  EXPECT_GT(bottomLeft.z, 0.5f);
  // Without colours the same square shows the plain diffuse (1.05 lit head-on).
  Scene uncoloured = ColouredSquare("", folder_);
  uncoloured.shapes[0].mesh.colors.clear();
  ExpectTexel(At(Render(uncoloured), 4, 4), {1, 1, 1}, "centre, uncoloured");
}

}  // namespace
}  // namespace tcfarm
