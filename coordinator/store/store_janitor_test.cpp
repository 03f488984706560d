// Deleting jobs with their files, the store's size, and the retention, against a real job
// store and real folders; the farm's part is a recorded callback, the clock a counter.
#include "coordinator/store/store_janitor.h"

#include <gtest/gtest.h>
#include <prometheus/registry.h>
#include <prometheus/text_serializer.h>

#include <atomic>
#include <fstream>
#include <random>
#include <regex>
#include <thread>

#include <fcntl.h>
#include <sys/stat.h>

#include "coordinator/store/asset_store.h"
#include "coordinator/store/frame_store.h"
#include "proto/wire/content_hash.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kDayMs = 24 * 3600 * 1000LL;

class StoreJanitorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() /
              ("tcfarm_janitor_" + std::to_string(std::random_device()()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    root_ = folder_ / "store";
    fs::create_directories(root_);
    // The database beside the store, not in it, so the store's size is the test's files only.
    jobs_ = std::make_unique<JobStore>(folder_ / "jobs.db", [this] { return nowMs_.load(); });
    registry_ = std::make_shared<prometheus::Registry>();
  }
  void TearDown() override {
    janitor_.reset();
    jobs_.reset();
    fs::remove_all(folder_);
  }

  StoreJanitor& Janitor(RetentionPolicy policy = {}) {
    janitor_ = std::make_unique<StoreJanitor>(
        *jobs_, root_,
        [this](uint64_t id) {
          released_.push_back(id);
          return farmRunning_.load();
        },
        registry_.get(), policy, [this] { return nowMs_.load(); });
    return *janitor_;
  }

  // A job of `frames` frames that finished at nowMs_, its folder holding `bytes` bytes.
  uint64_t FinishedJob(uint64_t bytes, const std::vector<std::string>& assets = {}) {
    JobSpec spec;
    spec.sceneJson = "{}";
    spec.sceneHash = std::string(64, 'b');
    spec.lastFrame = 3;
    spec.frameSize = {4, 3};
    spec.assetHashes = assets;
    const uint64_t id = jobs_->Submit(spec);
    EXPECT_TRUE(jobs_->Cancel(id));
    WriteFile(FrameStore(root_).FramePath(id, 0, "exr"), bytes);
    return id;
  }
  static void WriteFile(const fs::path& path, uint64_t bytes) {
    fs::create_directories(path.parent_path());
    std::ofstream(path, std::ios::binary) << std::string(bytes, 'x');
  }
  std::string Asset(const std::string& bytes) {
    const std::string hash = wire::Sha256Hex(bytes);
    AssetStore(root_ / "assets").Put(hash, bytes);
    return hash;
  }
  bool HasAsset(const std::string& hash) const { return AssetStore(root_ / "assets").Has(hash); }
  double Metric(const std::string& name) const {
    const std::string text = prometheus::TextSerializer().Serialize(registry_->Collect());
    std::smatch match;
    if (!std::regex_search(text, match, std::regex("\n" + name + " (\\S+)"))) return -1;
    return std::stod(match[1]);
  }

  fs::path folder_, root_;
  std::atomic<int64_t> nowMs_{10 * kDayMs};
  std::unique_ptr<JobStore> jobs_;
  std::shared_ptr<prometheus::Registry> registry_;
  std::unique_ptr<StoreJanitor> janitor_;
  std::vector<uint64_t> released_;
  std::atomic<bool> farmRunning_{true};
};

TEST_F(StoreJanitorTest, DeleteRemovesTheJobItsFolderAndTheAssetsNoOtherJobNames) {
  const std::string mine = Asset("only mine"), shared = Asset("shared by both");
  const uint64_t id = FinishedJob(1000, {mine, shared});
  WriteFile(FrameStore(root_).MaskPath(id, MaskKind::kTraced, 0), 24);
  const uint64_t other = FinishedJob(500, {shared});
  StoreJanitor& janitor = Janitor();
  janitor.RunDue();
  const uint64_t before = janitor.StoreBytes();

  const StoreJanitor::Deletion deletion = janitor.Delete(id);
  EXPECT_EQ(deletion.outcome, DeletedJob::Outcome::kDeleted);
  EXPECT_EQ(deletion.state, JobState::kCanceled);
  EXPECT_EQ(deletion.freedBytes, 1000u + 24u + std::string("only mine").size());
  EXPECT_FALSE(fs::exists(FrameStore(root_).JobFolder(id)));
  EXPECT_FALSE(jobs_->Get(id).has_value());
  EXPECT_FALSE(HasAsset(mine));
  EXPECT_TRUE(HasAsset(shared));
  EXPECT_TRUE(fs::exists(FrameStore(root_).JobFolder(other)));
  // The farm let go of the job before anything changed, and again before the folder went.
  EXPECT_EQ(released_, (std::vector<uint64_t>{id, id}));
  EXPECT_TRUE(jobs_->PendingDeletions().empty());
  const std::vector<JobEvent> events = jobs_->Events({id, 0, 10});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, "deleted");
  EXPECT_EQ(events[0].fields["freed_bytes"], deletion.freedBytes);
  EXPECT_EQ(events[0].message, "deleted on request; 1.0 KiB freed");
  // The store's size falls at once, without a walk; the counter counts it.
  EXPECT_EQ(janitor.StoreBytes(), before - deletion.freedBytes);
  EXPECT_EQ(Metric("tcfarm_store_bytes"), static_cast<double>(before - deletion.freedBytes));
  EXPECT_EQ(Metric("tcfarm_jobs_deleted_total"), 1);

  EXPECT_EQ(janitor.Delete(id).outcome, DeletedJob::Outcome::kNotFound);
  EXPECT_EQ(janitor.Delete(other).freedBytes, 500u + std::string("shared by both").size());
  EXPECT_FALSE(HasAsset(shared));
}

TEST_F(StoreJanitorTest, QueuedAndRunningJobsAreNotDeleted) {
  JobSpec spec;
  spec.sceneJson = "{}";
  spec.sceneHash = std::string(64, 'b');
  spec.frameSize = {4, 3};
  const uint64_t running = jobs_->Submit(spec);
  const uint64_t queued = jobs_->Submit(spec);
  ASSERT_EQ(jobs_->ClaimNext()->id, running);
  WriteFile(FrameStore(root_).FramePath(running, 0, "exr"), 10);
  StoreJanitor& janitor = Janitor();
  StoreJanitor::Deletion deletion = janitor.Delete(running);
  EXPECT_EQ(deletion.outcome, DeletedJob::Outcome::kActive);
  EXPECT_EQ(deletion.state, JobState::kRunning);
  EXPECT_EQ(janitor.Delete(queued).state, JobState::kQueued);
  EXPECT_TRUE(released_.empty());
  EXPECT_TRUE(fs::exists(FrameStore(root_).FramePath(running, 0, "exr")));
  EXPECT_EQ(janitor.JobsDeleted(), 0u);
}

TEST_F(StoreJanitorTest, AStoppedFarmLeavesEverythingAsItWas) {
  const uint64_t id = FinishedJob(100);
  farmRunning_ = false;
  EXPECT_THROW(Janitor().Delete(id), FarmStoppingError);
  EXPECT_TRUE(jobs_->Get(id).has_value());
  EXPECT_TRUE(fs::exists(FrameStore(root_).JobFolder(id)));
}

// The record went, the process died before the folder did: the next start finishes it.
TEST_F(StoreJanitorTest, DeletionsLeftHalfDoneAreFinishedAtStart) {
  const uint64_t id = FinishedJob(300);
  ASSERT_EQ(jobs_->Delete(id).outcome, DeletedJob::Outcome::kDeleted);
  StoreJanitor& janitor = Janitor();
  janitor.RunDue();
  EXPECT_FALSE(fs::exists(FrameStore(root_).JobFolder(id)));
  EXPECT_TRUE(jobs_->PendingDeletions().empty());
  EXPECT_EQ(jobs_->Events({id, 0, 10}).at(0).fields["freed_bytes"], 300);
  EXPECT_EQ(janitor.StoreBytes(), 0u);
}

TEST_F(StoreJanitorTest, KeepDaysDeletesJobsFinishedLongerAgoAtStartAndEveryMinute) {
  nowMs_ = 1 * kDayMs;
  const uint64_t oldest = FinishedJob(10);
  nowMs_ = 3 * kDayMs;
  const uint64_t older = FinishedJob(10);
  nowMs_ = 4 * kDayMs + 1;
  const uint64_t recent = FinishedJob(10);
  RetentionPolicy keepTwoDays;
  keepTwoDays.keepMs = 2 * kDayMs;
  StoreJanitor& janitor = Janitor(keepTwoDays);
  nowMs_ = 5 * kDayMs - 10'000;  // `older` is ten seconds short of two days old
  janitor.RunDue();  // at start
  EXPECT_FALSE(jobs_->Get(oldest).has_value());
  EXPECT_TRUE(jobs_->Get(older).has_value());
  nowMs_ += 30'000;  // `older` is over two days old now, but the minute has not passed
  janitor.RunDue();
  EXPECT_TRUE(jobs_->Get(older).has_value());
  nowMs_ += StoreJanitor::kRetentionIntervalMs - 30'000;
  janitor.RunDue();
  EXPECT_FALSE(jobs_->Get(older).has_value());
  EXPECT_FALSE(fs::exists(FrameStore(root_).JobFolder(older)));
  EXPECT_TRUE(jobs_->Get(recent).has_value());
  EXPECT_EQ(jobs_->Events({older, 0, 10}).at(0).fields["reason"],
            "by the retention: finished more than 2 days ago (--keep-days)");
  EXPECT_EQ(janitor.JobsDeleted(), 2u);
}

TEST_F(StoreJanitorTest, ABudgetDeletesTheEarliestFinishedJobsUntilTheStoreFits) {
  const uint64_t first = FinishedJob(40'000);
  nowMs_ += 1000;
  const uint64_t second = FinishedJob(40'000);
  nowMs_ += 1000;
  const uint64_t third = FinishedJob(40'000);
  JobSpec spec;
  spec.sceneJson = "{}";
  spec.sceneHash = std::string(64, 'b');
  spec.frameSize = {4, 3};
  const uint64_t running = jobs_->Submit(spec);
  ASSERT_EQ(jobs_->ClaimNext()->id, running);
  WriteFile(FrameStore(root_).FramePath(running, 0, "exr"), 100'000);
  RetentionPolicy budget;
  budget.budgetBytes = 190'000;
  StoreJanitor& janitor = Janitor(budget);
  janitor.RunDue();
  // 220 kB: the earliest finished goes, and 180 kB fits.
  EXPECT_FALSE(jobs_->Get(first).has_value());
  EXPECT_TRUE(jobs_->Get(second).has_value());
  EXPECT_LE(janitor.StoreBytes(), 190'000u);
  // The running job grows past the budget: every finished job goes, never the running one.
  WriteFile(FrameStore(root_).FramePath(running, 1, "exr"), 100'000);
  nowMs_ += StoreJanitor::kRetentionIntervalMs;
  janitor.RunDue();
  EXPECT_FALSE(jobs_->Get(second).has_value());
  EXPECT_FALSE(jobs_->Get(third).has_value());
  EXPECT_EQ(jobs_->StateOf(running), JobState::kRunning);
  EXPECT_TRUE(fs::exists(FrameStore(root_).FramePath(running, 1, "exr")));
}

TEST_F(StoreJanitorTest, TheStoresSizeIsMeasuredAtMostEveryTenSeconds) {
  WriteFile(root_ / "assets" / "a", 1000);
  StoreJanitor& janitor = Janitor();
  EXPECT_EQ(Metric("tcfarm_store_bytes"), 0);
  janitor.RunDue();
  EXPECT_EQ(Metric("tcfarm_store_bytes"), 1000);
  WriteFile(root_ / "7" / "frame_0000.exr", 500);
  nowMs_ += StoreJanitor::kUsageIntervalMs - 1;
  janitor.RunDue();
  EXPECT_EQ(janitor.StoreBytes(), 1000u);  // not walked again yet
  nowMs_ += 1;
  janitor.RunDue();
  EXPECT_EQ(janitor.StoreBytes(), 1500u);
}

// A submission between checking its assets and storing its job holds them: a deletion
// that would remove one waits until the job that names it is stored.
TEST_F(StoreJanitorTest, ADeletionWaitsForSubmissionsHoldingTheAssets) {
  const std::string asset = Asset("texture");
  const uint64_t id = FinishedJob(10, {asset});
  StoreJanitor& janitor = Janitor();
  std::atomic<bool> deleted{false};
  std::thread deleter;
  {
    auto hold = janitor.HoldAssets();
    deleter = std::thread([&] {
      janitor.Delete(id);
      deleted = true;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_FALSE(deleted);
    JobSpec spec;  // the submission's job, naming the asset, stored while it holds them
    spec.sceneJson = "{}";
    spec.sceneHash = std::string(64, 'b');
    spec.frameSize = {4, 3};
    spec.assetHashes = {asset};
    jobs_->Submit(spec);
  }
  deleter.join();
  EXPECT_TRUE(deleted);
  EXPECT_FALSE(jobs_->Get(id).has_value());
  EXPECT_TRUE(HasAsset(asset));  // named by the new job: kept
}

TEST(ByteSizeTest, ParsesSizesInPowersOf1024) {
  EXPECT_EQ(ParseByteSize("500M"), 500ull << 20);
  EXPECT_EQ(ParseByteSize("50G"), 50ull << 30);
  EXPECT_EQ(ParseByteSize("50g"), 50ull << 30);
  EXPECT_EQ(ParseByteSize("2GiB"), 2ull << 30);
  EXPECT_EQ(ParseByteSize("1.5T"), 3ull << 39);
  EXPECT_EQ(ParseByteSize("1024"), 1024u);
  EXPECT_EQ(ParseByteSize("64K"), 64u << 10);
  EXPECT_EQ(ParseByteSize("0"), 0u);
  for (const char* bad : {"", "G", "-5G", "5X", "5GG", " 5G", "5 G", "nan", "inf", "1e30"}) {
    EXPECT_THROW(ParseByteSize(bad), std::invalid_argument) << bad;
  }
  EXPECT_EQ(ShowBytes(1536), "1.5 KiB");
  EXPECT_EQ(ShowBytes(12), "12 B");
}

}  // namespace
}  // namespace tcfarm

namespace tcfarm {
namespace {

// An asset's age is its file's modification time; the test clock is unix milliseconds.
void SetAssetTime(const fs::path& root, const std::string& hash, int64_t unixMs) {
  const timespec when{static_cast<time_t>(unixMs / 1000), static_cast<long>(unixMs % 1000) * 1'000'000};
  const timespec times[2] = {when, when};
  ASSERT_EQ(::utimensat(AT_FDCWD, AssetStore(root / "assets").PathOf(hash).c_str(), times, 0), 0);
}

// Uploads no job names go once older than the grace period; those a job names stay, and
// one freshened (asked about, uploaded again) has its grace period anew.
TEST_F(StoreJanitorTest, OrphanAssetsGoAfterTheirGracePeriodNamedOnesStay) {
  constexpr int64_t kGraceMs = 3600 * 1000;
  const std::string orphan = Asset("uploaded, never submitted");
  const std::string named = Asset("named by a job");
  const std::string young = Asset("uploaded a moment ago");
  const std::string freshened = Asset("asked about again");
  FinishedJob(10, {named});
  for (const std::string& hash : {orphan, named, freshened}) SetAssetTime(root_, hash, nowMs_ - kGraceMs - 1);
  SetAssetTime(root_, young, nowMs_ - kGraceMs + 1000);
  AssetStore(root_ / "assets").Freshen({freshened});  // real time: far younger than the test clock
  RetentionPolicy policy;
  policy.orphanAssetGraceMs = kGraceMs;
  StoreJanitor& janitor = Janitor(policy);
  janitor.RunDue();
  EXPECT_FALSE(HasAsset(orphan));
  EXPECT_TRUE(HasAsset(named));
  EXPECT_TRUE(HasAsset(young));
  EXPECT_TRUE(HasAsset(freshened));
  EXPECT_EQ(janitor.OrphanAssetsRemoved(), 1u);
  EXPECT_EQ(Metric("tcfarm_store_orphan_assets_removed_total"), 1);
  EXPECT_EQ(Metric("tcfarm_store_orphan_asset_bytes_removed_total"), std::string("uploaded, never submitted").size());
  // The young one is swept once it is old too, at the next round (a minute on).
  nowMs_ += StoreJanitor::kOrphanIntervalMs - 1;
  janitor.RunDue();
  EXPECT_TRUE(HasAsset(young));
  nowMs_ += 1;
  janitor.RunDue();
  EXPECT_FALSE(HasAsset(young));
  EXPECT_TRUE(HasAsset(named));
  EXPECT_EQ(Metric("tcfarm_store_orphan_assets_removed_total"), 2);
}

}  // namespace
}  // namespace tcfarm
