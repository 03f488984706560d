// Bans outlive the coordinator: they are read back from the store's file.
#include "coordinator/farm/worker_bans.h"

#include <gtest/gtest.h>

#include <fstream>
#include <unistd.h>

namespace tcfarm {
namespace {

bool Banned(const WorkerBans& bans, const std::string& principal) {
  for (const WorkerBan& ban : bans.List()) {
    if (ban.principal == principal) return true;
  }
  return false;
}

class WorkerBansTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("tcfarm_worker_bans_test_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path File() const { return dir_ / "worker_bans.json"; }
  std::filesystem::path dir_;
};

TEST_F(WorkerBansTest, ABanIsReadBackAndCanBeLifted) {
  {
    WorkerBans bans(File());
    EXPECT_TRUE(bans.List().empty());
    bans.Add({"key:abc", "liar", "grey pixels", 1714566896789});
    bans.Add({"name:other@127.0.0.1", "other", "wrong check", 1});
  }
  WorkerBans reread(File());
  ASSERT_EQ(reread.List().size(), 2u);
  EXPECT_TRUE(Banned(reread, "key:abc"));
  EXPECT_EQ(reread.List()[0].name, "liar");
  EXPECT_EQ(reread.List()[0].bannedMs, 1714566896789);
  EXPECT_TRUE(reread.Remove("key:abc"));
  EXPECT_FALSE(reread.Remove("key:abc"));
  EXPECT_FALSE(Banned(WorkerBans(File()), "key:abc"));
  EXPECT_TRUE(Banned(WorkerBans(File()), "name:other@127.0.0.1"));
}

// A coordinator that cannot read its bans must not start trusting the banned.
TEST_F(WorkerBansTest, AnUnreadableFileIsRefusedNamingIt) {
  std::ofstream(File()) << "{\"bans\": [{\"name\": \"no principal\"}]}";
  try {
    WorkerBans bans(File());
    FAIL() << "a list of bans without principals was taken";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(File().string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace tcfarm
