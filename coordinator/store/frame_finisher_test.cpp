// A job's frames, written fast while it rendered, are finished (compressed, previewed)
// only while the farm is idle, bit for bit the same.
#include "coordinator/store/frame_finisher.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <thread>

#include "proto/frame/frame_io.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

constexpr std::chrono::milliseconds kNoGrace{0};

bool WaitFor(const std::function<bool()>& condition) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

class FrameFinisherTest : public testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("tcfarm_frame_finisher_test_" + std::to_string(::getpid()));
    store_ = FrameStore(root_);
    fs::create_directories(store_.JobFolder(7));
    for (int frame = 10; frame <= 12; ++frame) {
      // Values whose low bits a lossy step would lose.
      Image image{5, 3, std::vector<float>(45)};
      for (size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = 0.1234567f * float(i + frame);
      images_.push_back(image);
      WriteExr(store_.FramePath(7, frame, "exr"), image, "none");
    }
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path root_;
  FrameStore store_{""};
  std::vector<Image> images_;
};

TEST_F(FrameFinisherTest, WaitsForTheFarmThenCompressesAndPreviewsBitForBit) {
  FrameWriterOptions stored;  // zip:1 and previews
  EXPECT_EQ(WhileRendering(stored).exrCompression, "none");
  EXPECT_FALSE(WhileRendering(stored).writePng);
  FrameFinisher finisher(store_, stored, kNoGrace);
  finisher.SetFarmBusy(true);
  finisher.Add(7, 10, 13);  // frame 13 was never written (a failed job): skipped
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(finisher.FramesFinished(), 0u);  // a job renders: nothing is encoded
  EXPECT_FALSE(FrameFinisher::IsFinished(store_, 7));
  finisher.SetFarmBusy(false);
  ASSERT_TRUE(WaitFor([&] { return finisher.Idle() && FrameFinisher::IsFinished(store_, 7); }));
  for (int frame = 10; frame <= 12; ++frame) {
    EXPECT_EQ(ExrCompressionOf(store_.FramePath(7, frame, "exr")), "zip");
    EXPECT_EQ(ReadImage(store_.FramePath(7, frame, "exr")).rgb, images_[frame - 10].rgb);
    EXPECT_TRUE(fs::exists(store_.FramePath(7, frame, "png")));
  }
  EXPECT_FALSE(fs::exists(store_.FramePath(7, 13, "png")));
}

// The next job of a batch is submitted as the last one completes: the finisher lets the
// farm stay idle for its grace before it starts a frame, and a job that comes within the
// grace keeps it waiting.
TEST_F(FrameFinisherTest, WaitsForTheFarmToStayIdleForItsGrace) {
  FrameWriterOptions stored;
  constexpr std::chrono::milliseconds kGrace{1500};
  FrameFinisher finisher(store_, stored, kGrace);
  finisher.SetFarmBusy(true);
  finisher.Add(7, 10, 12);
  finisher.SetFarmBusy(false);
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  finisher.SetFarmBusy(true);  // the next job, within the grace
  finisher.SetFarmBusy(false);
  const auto idle = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  EXPECT_EQ(finisher.FramesFinished(), 0u);  // 1.7 s since the first idle, 0.7 s since the last
  ASSERT_TRUE(WaitFor([&] { return finisher.Idle() && FrameFinisher::IsFinished(store_, 7); }));
  EXPECT_GE(std::chrono::steady_clock::now() - idle, kGrace);
  EXPECT_EQ(finisher.FramesFinished(), 3u);
}

// A job deleted while it is finished: the finisher stops after the frame at hand, and once
// Drop returns it writes nothing more into the folder, marker included.
TEST_F(FrameFinisherTest, ADroppedJobIsLeftAloneOnceDropReturns) {
  FrameWriterOptions stored;
  FrameFinisher finisher(store_, stored, kNoGrace);
  finisher.SetFarmBusy(true);
  finisher.Add(7, 10, 12);
  finisher.Add(8, 0, 0);  // never written: only its marker would appear
  fs::create_directories(store_.JobFolder(8));
  ASSERT_TRUE(WaitFor([&] { return !finisher.Idle(); }));
  finisher.Drop(7);  // queued, or waiting for an idle farm before its first frame
  fs::remove_all(store_.JobFolder(7));
  finisher.SetFarmBusy(false);
  ASSERT_TRUE(WaitFor([&] { return finisher.Idle(); }));
  EXPECT_FALSE(fs::exists(store_.JobFolder(7)));  // nothing resurrected it
  EXPECT_TRUE(FrameFinisher::IsFinished(store_, 8));
  // Queued, not started: it simply leaves the queue.
  finisher.SetFarmBusy(true);
  finisher.Add(8, 0, 0);
  finisher.Add(9, 0, 0);
  finisher.Drop(9);
  finisher.Drop(8);
  fs::remove_all(store_.JobFolder(8));
  finisher.SetFarmBusy(false);
  ASSERT_TRUE(WaitFor([&] { return finisher.Idle(); }));
  EXPECT_FALSE(fs::exists(store_.JobFolder(8)));
  EXPECT_FALSE(fs::exists(store_.JobFolder(9)));
}

// Dropped while it encodes frames as fast as it can: many times, at random moments.
TEST_F(FrameFinisherTest, DroppingDuringEncodingNeverLeavesAFolderBehind) {
  FrameWriterOptions stored;
  for (int round = 0; round < 20; ++round) {
    const uint64_t job = 100 + round;
    fs::create_directories(store_.JobFolder(job));
    for (int frame = 0; frame < 6; ++frame) WriteExr(store_.FramePath(job, frame, "exr"), images_[0], "none");
    FrameFinisher finisher(store_, stored, kNoGrace);
    finisher.Add(job, 0, 5);
    std::this_thread::sleep_for(std::chrono::microseconds(500 * round));
    finisher.Drop(job);
    fs::remove_all(store_.JobFolder(job));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_FALSE(fs::exists(store_.JobFolder(job))) << "round " << round;
  }
}

// The previews, whether the finisher makes them or the API on request, show the frames
// through the job's view; the EXR master stays the traced values.
TEST_F(FrameFinisherTest, PreviewsGoThroughTheJobsView) {
  const ViewTransform neutral{View::kKhrPbrNeutral, 1.5};
  FrameFinisher finisher(store_, FrameWriterOptions{}, kNoGrace);
  finisher.Add(7, 10, 11, neutral);
  ASSERT_TRUE(WaitFor([&] { return finisher.Idle() && FrameFinisher::IsFinished(store_, 7); }));
  for (int frame = 10; frame <= 11; ++frame) {
    std::ifstream file(store_.FramePath(7, frame, "png"), std::ios::binary);
    const std::string written{std::istreambuf_iterator<char>(file), {}};
    EXPECT_EQ(written, EncodePng(images_[frame - 10], neutral)) << frame;
    EXPECT_NE(written, EncodePng(images_[frame - 10])) << frame;
    EXPECT_EQ(ReadImage(store_.FramePath(7, frame, "exr")).rgb, images_[frame - 10].rgb);
  }
  EXPECT_EQ(EncodePreview(store_, 7, 12, neutral), EncodePng(images_[2], neutral));
  EXPECT_EQ(EncodePreview(store_, 7, 12), EncodePng(images_[2]));
}

// A job's view lives in its options, only when it is not the default: jobs stored before
// views existed, and jobs submitted without one, read as standard.
TEST(JobPreviewViewTest, IsKeptInTheJobsOptionsWhenNotTheDefault) {
  JobSpec spec;
  spec.options = {{"verify", {{"frames", "all"}}}};
  EXPECT_EQ(JobPreviewView(spec), ViewTransform{});
  SetJobPreviewView(spec, {View::kKhrPbrNeutral, -0.5});
  EXPECT_EQ(spec.options, nlohmann::json({{"verify", {{"frames", "all"}}}, {"view", "khr-pbr-neutral"}, {"exposure", -0.5}}));
  EXPECT_EQ(JobPreviewView(spec), (ViewTransform{View::kKhrPbrNeutral, -0.5}));
  SetJobPreviewView(spec, {});
  EXPECT_EQ(spec.options, nlohmann::json({{"verify", {{"frames", "all"}}}}));
  spec.options["view"] = "from a later version";  // unknown: shown as the standard view
  EXPECT_EQ(JobPreviewView(spec).view, View::kStandard);
}

TEST_F(FrameFinisherTest, AStoreWithoutExrsHasNothingToFinish) {
  FrameWriterOptions pngOnly;
  pngOnly.writeExr = false;
  EXPECT_TRUE(WhileRendering(pngOnly).writePng);  // the PNG is the only copy: written at once
  FrameFinisher finisher(store_, pngOnly, kNoGrace);
  finisher.Add(7, 10, 12);
  EXPECT_TRUE(finisher.Idle());
  EXPECT_FALSE(fs::exists(store_.FramePath(7, 10, "png")));
}

}  // namespace
}  // namespace tcfarm
