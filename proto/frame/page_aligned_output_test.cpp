#include "proto/frame/page_aligned_output.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

class PageAlignedOutputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = std::filesystem::temp_directory_path() /
                 ("tcfarm_page_aligned_" + std::to_string(::getpid()) + "_" +
                  ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(directory_);
  }
  void TearDown() override { std::filesystem::remove_all(directory_); }

  static std::string ReadBack(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  static std::string RandomBytes(size_t size, unsigned seed) {
    std::mt19937 random(seed);
    std::string bytes(size, '\0');
    for (char& byte : bytes) byte = static_cast<char>(random());
    return bytes;
  }

  std::filesystem::path directory_;
};

// Sizes around page boundaries: the file holds exactly the bytes written, not the padding
// a direct write rounds up to.
TEST_F(PageAlignedOutputTest, FileHoldsExactlyTheBytesWrittenAtEverySize) {
  PageAlignedOutput output;
  for (size_t size : {size_t{0}, size_t{1}, kDirectIoAlignment - 1, kDirectIoAlignment, kDirectIoAlignment + 1,
                      size_t{3} * 1024 * 1024 + 17}) {
    output.Reset();
    const std::string bytes = RandomBytes(size, static_cast<unsigned>(size));
    // Written in uneven pieces, as an encoder writes blocks.
    for (size_t at = 0; at < size; at += 1000) output.write(bytes.data() + at, std::min<size_t>(1000, size - at));
    const std::filesystem::path file = directory_ / ("out_" + std::to_string(size));
    WriteFileAroundCache(file, output);
    EXPECT_EQ(std::filesystem::file_size(file), size);
    EXPECT_EQ(ReadBack(file), bytes) << size << " bytes";
  }
}

// An encoder seeks back to patch a header or an offset table, and may seek past the end.
TEST_F(PageAlignedOutputTest, SeeksBackPatchAndSeeksPastTheEndLeavesZeros) {
  PageAlignedOutput output;
  output.write("abcdefgh", 8);
  output.seek(2);
  output.write("XY", 2);
  EXPECT_EQ(output.tell(), 4);
  output.pwrite("!", 1, 12);  // a hole of zeros from 8 to 12
  EXPECT_EQ(output.size(), 13u);
  EXPECT_EQ(output.tell(), 4);  // pwrite leaves the position
  WriteFileAroundCache(directory_ / "patched", output);
  EXPECT_EQ(ReadBack(directory_ / "patched"), std::string("abXYefgh\0\0\0\0!", 13));
}

// Reset keeps the buffer's pages: a shorter image after a longer one leaves nothing of it.
TEST_F(PageAlignedOutputTest, ResetForgetsTheLastImage) {
  PageAlignedOutput output;
  const std::string first = RandomBytes(100000, 1), second = RandomBytes(5000, 2);
  output.write(first.data(), first.size());
  output.Reset();
  output.write(second.data(), second.size());
  WriteFileAroundCache(directory_ / "second", output);
  EXPECT_EQ(ReadBack(directory_ / "second"), second);
}

// tmpfs refuses O_DIRECT before Linux 6.6 and takes it after: the file is the same either
// way, written buffered or direct.
TEST_F(PageAlignedOutputTest, TmpfsGetsTheSameFile) {
  const std::filesystem::path shm = "/dev/shm";
  if (!std::filesystem::is_directory(shm)) GTEST_SKIP() << "no /dev/shm here";
  const std::filesystem::path file = shm / ("tcfarm_page_aligned_" + std::to_string(::getpid()));
  PageAlignedOutput output;
  const std::string bytes = RandomBytes(10000, 3);
  output.write(bytes.data(), bytes.size());
  WriteFileAroundCache(file, output);
  EXPECT_EQ(ReadBack(file), bytes);
  std::filesystem::remove(file);
}

TEST_F(PageAlignedOutputTest, UnwritablePlaceIsAnErrorNamingThePath) {
  PageAlignedOutput output;
  output.write("x", 1);
  const std::filesystem::path file = directory_ / "missing_folder" / "frame.exr";
  try {
    WriteFileAroundCache(file, output);
    FAIL() << "expected FrameIoError";
  } catch (const FrameIoError& error) {
    EXPECT_NE(std::string(error.what()).find(file.string()), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("No such file"), std::string::npos) << error.what();
  }
}

// A frame written through the buffer reads back bit for bit, EXR and PNG alike.
TEST_F(PageAlignedOutputTest, FramesWrittenThroughItReadBackBitForBit) {
  Image image{67, 45, {}};
  std::mt19937 random(7);
  std::uniform_real_distribution<float> value(0.0f, 4.0f);
  image.rgb.resize(image.PixelCount() * 3);
  for (float& channel : image.rgb) channel = value(random);
  for (const char* compression : {"none", "zip:1"}) {
    const std::filesystem::path exr = directory_ / (std::string("frame_") + compression[0] + ".exr");
    WriteExr(exr, image, compression);
    EXPECT_EQ(ReadImage(exr).rgb, image.rgb) << compression;
  }
  std::vector<uint8_t> mask(image.PixelCount());
  for (size_t i = 0; i < mask.size(); ++i) mask[i] = (i % 3) == 0;
  WriteMaskPng(directory_ / "mask.png", image.width, image.height, mask);
  const Image back = ReadImage(directory_ / "mask.png");
  ASSERT_EQ(back.PixelCount(), mask.size());
  for (size_t i = 0; i < mask.size(); ++i) ASSERT_EQ(back.rgb[3 * i], mask[i] ? 1.0f : 0.0f) << "pixel " << i;
}

}  // namespace
}  // namespace tcfarm
