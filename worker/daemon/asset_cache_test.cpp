// The worker's asset cache: an asset appears under its hash only whole, in order and
// verified; anything else is dropped with the reason.
#include "worker/daemon/asset_cache.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <string>

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

class AssetCacheTest : public testing::Test {
 protected:
  void SetUp() override { dir_ = fs::temp_directory_path() / ("tcfarm_asset_cache_test_" + std::to_string(getpid())); }
  void TearDown() override { fs::remove_all(dir_); }

  // The bytes in pieces of `pieceBytes`, as the coordinator sends them.
  static std::vector<wire::AssetPiece> Pieces(const std::string& bytes, size_t pieceBytes) {
    const std::string hash = wire::Sha256Hex(bytes);
    std::vector<wire::AssetPiece> pieces;
    for (size_t offset = 0; offset < bytes.size() || pieces.empty(); offset += pieceBytes) {
      pieces.push_back({hash, offset, bytes.size(), bytes.substr(offset, pieceBytes)});
    }
    return pieces;
  }

  static std::string Contents(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }

  fs::path dir_;
};

TEST_F(AssetCacheTest, PiecesInOrderMakeTheFileUnderItsHash) {
  AssetCache cache(dir_, 1 << 20);
  const std::string bytes = "an image of eleven pieces, more or less";
  const auto pieces = Pieces(bytes, 4);
  const std::string hash = pieces[0].assetHash;
  EXPECT_FALSE(cache.Find(hash));
  cache.Expect(hash);
  std::string problem;
  for (size_t i = 0; i + 1 < pieces.size(); ++i) {
    EXPECT_EQ(cache.Accept(pieces[i], &problem), AssetCache::Outcome::kIncomplete);
    EXPECT_FALSE(cache.Find(hash));  // never seen half-written
  }
  EXPECT_EQ(cache.Accept(pieces.back(), &problem), AssetCache::Outcome::kComplete) << problem;
  ASSERT_TRUE(cache.Find(hash));
  EXPECT_EQ(Contents(*cache.Find(hash)), bytes);
  EXPECT_FALSE(cache.IsExpected(hash));
  // A second cache over the same folder (another worker on this machine) finds it too.
  EXPECT_TRUE(AssetCache(dir_, 1 << 20).Find(hash));
}

TEST_F(AssetCacheTest, AnEmptyFileIsOneEmptyPiece) {
  AssetCache cache(dir_, 1 << 20);
  const auto pieces = Pieces("", 4);
  cache.Expect(pieces[0].assetHash);
  std::string problem;
  EXPECT_EQ(cache.Accept(pieces[0], &problem), AssetCache::Outcome::kComplete) << problem;
  EXPECT_TRUE(cache.Find(pieces[0].assetHash));
}

TEST_F(AssetCacheTest, WhatWasNotAskedForIsIgnored) {
  AssetCache cache(dir_, 1 << 20);
  const auto pieces = Pieces("unrequested", 64);
  std::string problem;
  EXPECT_EQ(cache.Accept(pieces[0], &problem), AssetCache::Outcome::kIgnored);
  EXPECT_FALSE(cache.Find(pieces[0].assetHash));
}

TEST_F(AssetCacheTest, AGapWrongBytesOrTooLargeAnAssetIsDropped) {
  AssetCache cache(dir_, 16);
  std::string problem;

  auto gap = Pieces("0123456789abcdef", 4);
  cache.Expect(gap[0].assetHash);
  // The rest of an earlier, dropped download of the same asset: not this one's start.
  EXPECT_EQ(cache.Accept(gap[1], &problem), AssetCache::Outcome::kIgnored);
  EXPECT_TRUE(cache.IsExpected(gap[0].assetHash));
  EXPECT_EQ(cache.Accept(gap[0], &problem), AssetCache::Outcome::kIncomplete);
  EXPECT_EQ(cache.Accept(gap[2], &problem), AssetCache::Outcome::kFailed);
  EXPECT_NE(problem.find("a piece at byte 8 where byte 4 was due"), std::string::npos) << problem;
  EXPECT_FALSE(cache.IsExpected(gap[0].assetHash));
  EXPECT_EQ(cache.Accept(gap[3], &problem), AssetCache::Outcome::kIgnored);  // the rest is not wanted now

  auto forged = Pieces("the real bytes", 64);
  forged[0].bytes = "forged  bytes!";
  cache.Expect(forged[0].assetHash);
  EXPECT_EQ(cache.Accept(forged[0], &problem), AssetCache::Outcome::kFailed);
  EXPECT_NE(problem.find("its bytes hash to " + wire::Sha256Hex("forged  bytes!")), std::string::npos) << problem;
  EXPECT_FALSE(cache.Find(forged[0].assetHash));

  auto large = Pieces("seventeen bytes!!", 4);
  cache.Expect(large[0].assetHash);
  EXPECT_EQ(cache.Accept(large[0], &problem), AssetCache::Outcome::kFailed);
  EXPECT_NE(problem.find("more than this worker's limit of 16"), std::string::npos) << problem;

  EXPECT_TRUE(fs::is_empty(dir_ / ".incoming"));  // no temp file left behind
}

}  // namespace
}  // namespace tcfarm
