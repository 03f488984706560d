// The farm loop driven step by step: a real job store and dispatcher socket, fake workers
// in this process (dispatch/fake_worker.h) and a fake clock, so that a worker's silence
// lasts as long as the test says without the test sleeping through it.
#include "farm/farm.h"
#include "store/frame_finisher.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "dispatch/fake_worker.h"
#include "frame/frame_io.h"
#include "store/frame_store.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

// Each turn waits at most this long for messages; they cross loopback in microseconds.
constexpr Milliseconds kTurnPoll{5};
// Turns before a test gives up: seconds of polling at most, never a hang.
constexpr int kMaxTurns = 400;

class FarmTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() /
              ("tcfarm_farm_" + std::to_string(std::random_device()()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(folder_);
    store_ = std::make_unique<JobStore>(folder_ / "jobs.db");
    FarmOptions options;
    options.endpoint = "tcp://127.0.0.1:*";
    options.storeRoot = folder_ / "store";
    options.output.threads = 1;
    farm_ = std::make_unique<Farm>(*store_, options, clock_);
    clock_.Advance(Milliseconds(1000));  // past the first look for new jobs
  }
  void TearDown() override {
    farm_.reset();
    fs::remove_all(folder_);
  }

  // A brute-force job of `frames` frames of 4x3 pixels.
  uint64_t Submit(int frames) {
    JobSpec spec;
    spec.sceneJson = "{}";  // the fake workers never ask for it
    spec.sceneHash = std::string(64, 'b');
    spec.lastFrame = frames - 1;
    spec.strategy = Strategy::kBrute;
    spec.frameSize = {4, 3};
    spec.cameraOrLightsChange = false;
    return store_->Submit(spec);
  }
  JobState StateOf(uint64_t id) const { return store_->Get(id)->state; }

  // Steps the farm, calling `afterTurn` after each step, until it returns true.
  bool TurnUntil(const std::function<bool()>& afterTurn) {
    for (int turn = 0; turn < kMaxTurns; ++turn) {
      farm_->Step(kTurnPoll);
      if (afterTurn()) return true;
    }
    return false;
  }
  // Steps until `id` completes, `worker` answering every task it gets with `value`.
  bool ServeUntilComplete(FakeWorker& worker, uint64_t id, float value = 0.5f) {
    return TurnUntil([&] {
      for (const wire::Task& task : worker.Tasks()) worker.Answer(task, value);
      return StateOf(id) == JobState::kCompleted;
    });
  }

  fs::path folder_;
  FakeClock clock_;
  zmq::context_t context_;
  std::unique_ptr<JobStore> store_;
  std::unique_ptr<Farm> farm_;
};

TEST_F(FarmTest, ASmallJobCompletesAndItsFramesAreWritten) {
  FakeWorker worker(context_, farm_->BoundEndpoint(), 4);
  const uint64_t id = Submit(3);
  ASSERT_TRUE(ServeUntilComplete(worker, id, 0.25f)) << ToString(StateOf(id));

  const JobRecord record = *store_->Get(id);
  EXPECT_EQ(record.framesDone, 3);
  EXPECT_EQ(record.tracedPixels, 3u * 12u);  // brute force traces every pixel
  EXPECT_EQ(record.stats["strategy"]["name"], "brute");
  const FrameStore files(folder_ / "store");
  // While the job rendered its frames were written uncompressed and without previews;
  // once no job renders, the finisher compresses them and makes the previews.
  ASSERT_TRUE(TurnUntil([&] { return FrameFinisher::IsFinished(files, id); }));
  for (int frame = 0; frame < 3; ++frame) {
    EXPECT_TRUE(fs::exists(files.FramePath(id, frame, "png"))) << frame;
    EXPECT_EQ(ExrCompressionOf(files.FramePath(id, frame, "exr")), "zip") << frame;
    EXPECT_TRUE(fs::exists(files.MaskPath(id, MaskKind::kTraced, frame))) << frame;
    EXPECT_TRUE(fs::exists(files.MaskPath(id, MaskKind::kChange, frame))) << frame;
    const Image image = ReadImage(files.FramePath(id, frame, "exr"));
    EXPECT_EQ(image.rgb, std::vector<float>(12 * 3, 0.25f)) << frame;  // the worker's values, bit for bit
  }
  EXPECT_EQ(farm_->metrics().framesWritten.Value(), 3);
  EXPECT_EQ(farm_->metrics().tasksRequeued.Value(), 0);
}

TEST_F(FarmTest, ASilentWorkersTasksAreRequeuedAfterTheTimeout) {
  FakeWorker silent(context_, farm_->BoundEndpoint(), 4);
  const uint64_t id = Submit(2);
  size_t held = 0;
  ASSERT_TRUE(TurnUntil([&] {
    held += silent.Tasks().size();  // taken, never answered
    // Every task sent has arrived: one still in the socket would be requeued unseen.
    return held > 0 && farm_->metrics().queueDepth.Value() == 0 &&
           static_cast<double>(held) == farm_->metrics().tasksInFlight.Value();
  }));
  FakeWorker rescuer(context_, farm_->BoundEndpoint(), 4);
  ASSERT_TRUE(TurnUntil([&] { return farm_->metrics().liveWorkers.Value() == 2; }));
  EXPECT_TRUE(rescuer.Tasks().empty());  // nothing left for it while the silent one holds all

  // Just short of the timeout nothing is taken back; just past it, the silent worker's
  // tasks go to the worker that kept talking.
  const Milliseconds timeout = HeartbeatPolicy{}.timeout;
  clock_.Advance(timeout - Milliseconds(1));
  rescuer.Send(wire::Heartbeat{});
  farm_->Step(Milliseconds(1000));  // returns as soon as the heartbeat is in
  EXPECT_EQ(farm_->metrics().tasksRequeued.Value(), 0);
  clock_.Advance(Milliseconds(2));
  rescuer.Send(wire::Heartbeat{});
  farm_->Step(Milliseconds(1000));
  EXPECT_EQ(farm_->metrics().tasksRequeued.Value(), static_cast<double>(held));
  EXPECT_EQ(farm_->metrics().liveWorkers.Value(), 1);

  ASSERT_TRUE(ServeUntilComplete(rescuer, id)) << ToString(StateOf(id));
  EXPECT_EQ(store_->Get(id)->framesDone, 2);
}

}  // namespace
}  // namespace tcfarm
