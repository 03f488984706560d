#include "coordinator/farm/price_book.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "coordinator/jobs/job_store.h"

namespace tcfarm {
namespace {

TEST(PriceBook, AnUnseenSceneOfAnUnseenKindGetsThePriors) {
  PriceBook book;
  const SegmentPrices prices = book.Quote("a", false);
  EXPECT_EQ(prices.source, PriceSource::kPrior);
  EXPECT_DOUBLE_EQ(prices.startPrice, SegmentPrices{}.startPrice);
  EXPECT_DOUBLE_EQ(prices.framePrice, SegmentPrices{}.framePrice);
}

TEST(PriceBook, ASceneGetsItsOwnPricesNotAnotherScenes) {
  PriceBook book;
  book.Record("skinned", true, {3.0, 1.2});
  book.Record("other skinned", true, {2.0, 0.1});  // the farm's last of the kind
  const SegmentPrices own = book.Quote("skinned", true);
  EXPECT_EQ(own.source, PriceSource::kScene);
  EXPECT_DOUBLE_EQ(own.framePrice, 1.2);
  const SegmentPrices other = book.Quote("other skinned", true);
  EXPECT_EQ(other.source, PriceSource::kScene);
  EXPECT_DOUBLE_EQ(other.framePrice, 0.1);
}

TEST(PriceBook, AnUnseenSceneGetsTheLastOfItsKind) {
  PriceBook book;
  book.Record("skinned", true, {3.0, 1.2});
  book.Record("rigid", false, {2.5, 0.2});
  const SegmentPrices deforming = book.Quote("new skinned", true);
  EXPECT_EQ(deforming.source, PriceSource::kFarm);
  EXPECT_DOUBLE_EQ(deforming.framePrice, 1.2);
  const SegmentPrices rigid = book.Quote("new rigid", false);
  EXPECT_EQ(rigid.source, PriceSource::kFarm);
  EXPECT_DOUBLE_EQ(rigid.framePrice, 0.2);
  EXPECT_DOUBLE_EQ(book.Quote("kind unknown", std::nullopt).framePrice, 0.2);  // the last of any
  // A kind the farm never measured gets the priors, not the other kind's prices.
  PriceBook rigidOnly;
  rigidOnly.Record("rigid", false, {2.5, 0.2});
  EXPECT_EQ(rigidOnly.Quote("skinned", true).source, PriceSource::kPrior);
}

TEST(PriceBook, OutliersAreKeptWithinWhatASegmentCanCost) {
  PriceBook book;
  const SegmentPrices kept = book.Record("a", false, {0.2, 9.0});
  EXPECT_DOUBLE_EQ(kept.startPrice, 1.0);
  EXPECT_DOUBLE_EQ(kept.framePrice, 5.0);
  EXPECT_DOUBLE_EQ(book.Quote("a", false).framePrice, 5.0);
}

TEST(PriceBook, TheSceneLongestUnusedIsForgottenFirst) {
  PriceBook book(2);
  book.Record("a", false, {3.0, 0.1});
  book.Record("b", false, {3.0, 0.2});
  EXPECT_EQ(book.Quote("a", false).source, PriceSource::kScene);  // a is now the most recent
  book.Record("c", false, {3.0, 0.3});
  EXPECT_EQ(book.Scenes(), 2u);
  EXPECT_EQ(book.Quote("b", false).source, PriceSource::kFarm);
  EXPECT_EQ(book.Quote("a", false).source, PriceSource::kScene);
  EXPECT_EQ(book.Quote("c", false).source, PriceSource::kScene);
  book.Record("a", false, {3.0, 0.4});  // measured again: replaced, not added
  EXPECT_EQ(book.Scenes(), 2u);
  EXPECT_DOUBLE_EQ(book.Quote("a", false).framePrice, 0.4);
}

}  // namespace
}  // namespace tcfarm

namespace tcfarm {
namespace {

// The job store keeps the last prices of the scenes measured most lately, oldest first,
// so that a PriceBook filled from them in order ends with the newest as its kinds' last.
TEST(ScenePricesInTheStore, TheNewestSurviveAReopenOldestFirst) {
  const std::filesystem::path folder =
      std::filesystem::temp_directory_path() / ("tcfarm_scene_prices_" + std::to_string(::getpid()));
  std::filesystem::create_directories(folder);
  int64_t now = 1000;
  {
    JobStore store(folder / "jobs.sqlite", [&] { return now++; });
    store.SaveScenePrices({"a", true, 3.0, 1.2}, 2);
    store.SaveScenePrices({"b", std::nullopt, 2.0, 0.2}, 2);
    store.SaveScenePrices({"c", false, 4.0, 0.3}, 2);  // a, the oldest, goes
    store.SaveScenePrices({"b", false, 2.5, 0.25}, 2);  // measured again: now the newest
  }
  JobStore store(folder / "jobs.sqlite", [&] { return now++; });
  const std::vector<JobStore::ScenePrices> rows = store.LoadScenePrices(10);
  std::filesystem::remove_all(folder);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].sceneHash, "c");
  EXPECT_EQ(rows[0].deforming, std::optional<bool>(false));
  EXPECT_EQ(rows[1].sceneHash, "b");
  EXPECT_DOUBLE_EQ(rows[1].framePrice, 0.25);
  EXPECT_EQ(store.LoadScenePrices(1).at(0).sceneHash, "b");  // the newest, within a limit
}

}  // namespace
}  // namespace tcfarm
