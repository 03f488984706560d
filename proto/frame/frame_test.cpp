#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <cstring>
#include <limits>
#include <thread>
#include <unistd.h>

#include "proto/frame/coherence.h"
#include "proto/frame/sequence_analysis.h"
#include "proto/frame/compare.h"
#include "proto/frame/frame_io.h"
#include "proto/frame/frame_writer.h"

namespace tcfarm {
namespace {

std::filesystem::path FreshFolder(const std::string& name) {
  auto path = std::filesystem::temp_directory_path() /
              ("tcfarm_frame_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(path);
  std::filesystem::create_directories(path);
  return path;
}

Image Gradient(int width, int height) {
  Image image{width, height, std::vector<float>(static_cast<size_t>(width) * height * 3)};
  for (size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = std::sqrt(i * 0.001f) * 0.37f;
  return image;
}

TEST(FrameIoTest, ExrKeepsEveryFloatBit) {
  auto folder = FreshFolder("exr");
  Image image = Gradient(13, 7);
  image.rgb[5] = 1e-30f;  // subnormal-adjacent and large values survive too
  image.rgb[6] = 3e8f;
  WriteExr(folder / "a.exr", image);
  Image back = ReadImage(folder / "a.exr");
  EXPECT_EQ(back.width, 13);
  EXPECT_EQ(back.height, 7);
  EXPECT_EQ(back.rgb, image.rgb);
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    EXPECT_NE(entry.path().extension(), ".partial") << entry.path();  // renamed into place
  }
}

// Two writers of one file at once (a frame rendered again while the finisher compresses
// it) each write a temporary of their own: whichever renames last, the file is whole.
TEST(FrameIoTest, WritersOfOneFileAtOnceNeverMixTheirBytes) {
  auto folder = FreshFolder("writers");
  const Image image = Gradient(640, 480);
  EXPECT_NE(PartialPathFor(folder / "a.exr"), PartialPathFor(folder / "a.exr"));
  std::vector<std::thread> writers;
  std::atomic<int> failures{0};
  for (int writer = 0; writer < 4; ++writer) {
    writers.emplace_back([&, writer] {
      for (int round = 0; round < 5; ++round) {
        try {
          WriteExr(folder / "a.exr", image, writer % 2 ? "zip:9" : "none");
        } catch (const FrameIoError&) {
          ++failures;
        }
      }
    });
  }
  for (std::thread& writer : writers) writer.join();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(ReadImage(folder / "a.exr").rgb, image.rgb);
}

TEST(FrameIoTest, PngIsSrgbEncoded) {
  EXPECT_EQ(LinearToSrgb8(0.0f), 0);
  EXPECT_EQ(LinearToSrgb8(1.0f), 255);
  EXPECT_EQ(LinearToSrgb8(7.0f), 255);
  EXPECT_EQ(LinearToSrgb8(-1.0f), 0);
  EXPECT_EQ(LinearToSrgb8(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(LinearToSrgb8(0.21586f), 128);  // sRGB code 128 is linear 0.21586
  auto folder = FreshFolder("png");
  Image image = Gradient(9, 4);
  WritePng(folder / "a.png", image);
  Image back = ReadImage(folder / "a.png");
  ASSERT_EQ(back.rgb.size(), image.rgb.size());
  for (size_t i = 0; i < image.rgb.size(); ++i) {
    EXPECT_EQ(LinearToSrgb8(back.rgb[i]), LinearToSrgb8(image.rgb[i])) << i;
  }
}

TEST(FrameIoTest, FastSrgbAgreesWithTheFormulaEverywhere) {
  // Every float in [0, 1.5] at a stride.
  for (uint32_t bits = 0; bits <= 0x3fc00000; bits += 997) {
    float v;
    std::memcpy(&v, &bits, sizeof v);
    ASSERT_EQ(LinearToSrgb8Fast(v), LinearToSrgb8(v)) << v;
  }
  // Each code's first float, found by bisection against the formula, and the float below.
  for (int code = 1; code < 256; ++code) {
    uint32_t lo = 0, hi = 0x3f800000;
    while (lo < hi) {
      uint32_t mid = lo + (hi - lo) / 2;
      float v;
      std::memcpy(&v, &mid, sizeof v);
      if (LinearToSrgb8(v) >= code) hi = mid; else lo = mid + 1;
    }
    for (uint32_t bits : {lo - 1, lo}) {
      float v;
      std::memcpy(&v, &bits, sizeof v);
      ASSERT_EQ(LinearToSrgb8Fast(v), LinearToSrgb8(v)) << v << " near code " << code;
    }
  }
  EXPECT_EQ(LinearToSrgb8Fast(-1.0f), 0);
  EXPECT_EQ(LinearToSrgb8Fast(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(LinearToSrgb8Fast(std::numeric_limits<float>::infinity()), 255);
}

TEST(FrameIoTest, ExrCompressionMustBeLossless) {
  auto folder = FreshFolder("compression");
  Image image = Gradient(6, 5);
  for (const char* compression : {"none", "zip", "zip:1", "piz"}) {
    WriteExr(folder / "a.exr", image, compression);
    EXPECT_EQ(ReadImage(folder / "a.exr").rgb, image.rgb) << compression;
  }
  EXPECT_THROW(WriteExr(folder / "b.exr", image, "b44"), FrameIoError);
  EXPECT_THROW(WriteExr(folder / "b.exr", image, "zip:0"), FrameIoError);
  EXPECT_THROW(WriteExr(folder / "b.exr", image, "zip:12"), FrameIoError);
}

TEST(FrameIoTest, ErrorsNameTheFile) {
  Image bad{4, 4, std::vector<float>(5)};
  try {
    WriteExr("/tmp/never.exr", bad);
    FAIL();
  } catch (const FrameIoError& e) {
    EXPECT_NE(std::string(e.what()).find("/tmp/never.exr"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("expected 48"), std::string::npos);
  }
  EXPECT_THROW(ReadImage("/nonexistent/frame.exr"), FrameIoError);
}

TEST(FrameWriterTest, WritesEveryQueuedFrame) {
  auto folder = FreshFolder("writer");
  {
    FrameWriter writer(folder, {true, true, "zip", 3, 2});
    for (int frame = 0; frame < 6; ++frame) writer.Write(frame, Gradient(8, 8));
    writer.Finish();
  }
  for (int frame = 0; frame < 6; ++frame) {
    EXPECT_TRUE(std::filesystem::exists(folder / (FrameFileStem(frame) + ".exr")));
    EXPECT_TRUE(std::filesystem::exists(folder / (FrameFileStem(frame) + ".png")));
  }
  EXPECT_EQ(FrameFileStem(42), "frame_0042");
}

// A written frame's buffer goes to the pool, as many as it keeps, and the file is the
// frame as it was given.
TEST(FrameWriterTest, HandsWrittenFramesBuffersBack) {
  auto folder = FreshFolder("recycle");
  auto pool = std::make_shared<FrameBufferPool>(2);
  {
    FrameWriterOptions options;
    options.recycle = pool;
    FrameWriter writer(folder, options);
    for (int frame = 0; frame < 3; ++frame) writer.Write(frame, Gradient(8, 8));
    writer.WriteMask("mask.png", 8, 8, std::vector<uint8_t>(64, 1));  // masks are not frames' buffers
    writer.Finish();
  }
  EXPECT_EQ(pool->Held(), 2u);
  EXPECT_GE(pool->Take(8 * 8 * 3).capacity(), 8u * 8 * 3);
  EXPECT_TRUE(pool->Take(8 * 8 * 3 + 1).empty());  // none large enough
  EXPECT_EQ(ReadImage(folder / (FrameFileStem(2) + ".exr")).rgb, Gradient(8, 8).rgb);
}

TEST(FrameWriterTest, WritesMasksAsGreyscalePngs) {
  auto folder = FreshFolder("masks");
  std::vector<uint8_t> mask(6 * 4, 0);
  mask[0] = 1;
  mask[6 * 4 - 1] = 7;  // any non-zero is white
  {
    FrameWriter writer(folder, {true, true, "zip", 1, 1});
    writer.Write(3, Gradient(6, 4));
    writer.WriteMask(MaskFileStem("mask", 3) + ".png", 6, 4, mask);
    writer.Finish();
  }
  EXPECT_EQ(MaskFileStem("change", 42), "change_0042");
  const Image read = ReadImage(folder / "mask_0003.png");
  ASSERT_EQ(read.width, 6);
  ASSERT_EQ(read.height, 4);
  for (size_t pixel = 0; pixel < mask.size(); ++pixel) {
    EXPECT_EQ(read.rgb[pixel * 3], mask[pixel] ? 1.0f : 0.0f) << pixel;
  }
  EXPECT_THROW(WriteMaskPng(folder / "bad.png", 6, 4, std::vector<uint8_t>(5)), FrameIoError);
}

TEST(FrameWriterTest, RefusesLossyCompression) {
  EXPECT_THROW(FrameWriter("/tmp", {true, true, "dwaa"}), FrameIoError);
}

TEST(FrameWriterTest, FinishReportsAWriteError) {
  FrameWriter writer("/nonexistent/folder", {true, false});
  writer.Write(0, Gradient(4, 4));
  EXPECT_THROW(writer.Finish(), FrameIoError);
}

TEST(CoherenceTest, CountsBitwiseEqualPixels) {
  Image a = Gradient(10, 10), b = a;
  b.rgb[0] = 5;       // pixel 0 changes
  b.rgb[3 * 7 + 2] = -0.0f;  // pixel 7: 0.0 vs -0.0 differ bitwise
  a.rgb[3 * 7 + 2] = 0.0f;
  EXPECT_DOUBLE_EQ(Coherence(a, b), 98.0 / 100.0);
  Image other = Gradient(5, 5);
  EXPECT_THROW(Coherence(a, other), std::invalid_argument);

  SequenceAnalyzer running;
  running.Add(a);
  running.Add(b);
  running.Add(a);
  EXPECT_EQ(running.frameToFrame().count, 2u);
  EXPECT_DOUBLE_EQ(running.frameToFrame().Mean(), 0.98);
  EXPECT_DOUBLE_EQ(running.longTerm().min, 0.98);
  EXPECT_DOUBLE_EQ(running.longTerm().max, 1.0);
  const std::string summary = CoherenceSummary(running.frameToFrame(), running.longTerm());
  EXPECT_NE(summary.find("frame-to-frame mean 98.00%"), std::string::npos);
  EXPECT_NE(summary.find("long-term mean 99.00% (min 98.00%, max 100.00%)"), std::string::npos);
  EXPECT_EQ(CoherenceSummary({}, {}), "coherence: needs at least two frames");
}

TEST(CompareTest, CountsDifferingPixelsAndTheirSize) {
  Image reference = Gradient(4, 4), test = reference;
  FrameError same = CompareImages(reference, test);
  EXPECT_EQ(same.differingPixels, 0u);
  EXPECT_TRUE(std::isinf(same.Psnr()));
  test.rgb[3 * 5 + 1] += 0.25f;
  test.rgb[3 * 9 + 0] = -0.0f;  // differs in bits only where the reference has +0
  reference.rgb[3 * 9 + 0] = 0.0f;
  FrameError error = CompareImages(reference, test);
  EXPECT_EQ(error.pixels, 16u);
  EXPECT_EQ(error.differingPixels, 2u);
  EXPECT_NEAR(error.maxAbsError, 0.25, 1e-6);
  EXPECT_DOUBLE_EQ(error.DifferingShare(), 2.0 / 16);
  EXPECT_GT(error.Psnr(), 10);
  FrameError total;
  total += error;
  total += same;
  EXPECT_EQ(total.pixels, 32u);
  EXPECT_EQ(total.differingPixels, 2u);
  EXPECT_THROW(CompareImages(reference, Gradient(2, 2)), std::invalid_argument);
}

}  // namespace
}  // namespace tcfarm
