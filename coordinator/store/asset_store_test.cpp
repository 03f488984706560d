#include "coordinator/store/asset_store.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

#include "proto/wire/content_hash.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

size_t FilesUnder(const fs::path& folder) {
  std::error_code error;
  if (!fs::exists(folder, error)) return 0;
  size_t count = 0;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) count += entry.is_regular_file() ? 1 : 0;
  return count;
}

class AssetStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    folder_ = fs::temp_directory_path() / ("tcfarm_assets_" + std::to_string(std::random_device()()));
    store_ = std::make_unique<AssetStore>(folder_ / "assets");
  }
  void TearDown() override { fs::remove_all(folder_); }

  fs::path folder_;
  std::unique_ptr<AssetStore> store_;
};

TEST(AssetHash, OnlySixtyFourLowercaseHexCharacters) {
  EXPECT_TRUE(IsAssetHash(wire::Sha256Hex("x")));
  EXPECT_FALSE(IsAssetHash(""));
  EXPECT_FALSE(IsAssetHash(std::string(63, 'a')));
  EXPECT_FALSE(IsAssetHash(std::string(65, 'a')));
  EXPECT_FALSE(IsAssetHash(std::string(64, 'A')));  // one spelling per hash, so one file
  EXPECT_FALSE(IsAssetHash(std::string(63, 'a') + "g"));
  EXPECT_FALSE(IsAssetHash("../" + std::string(61, 'a')));
}

TEST(AssetPath, CanonicalRelativePathsOnly) {
  for (const char* good : {"a.obj", "meshes/tri.obj", "x/y/z/w.png", "with space.mtl", "..hidden", "a..b"}) {
    EXPECT_EQ(AssetPathProblem(good), std::nullopt) << good;
  }
  const std::vector<std::pair<std::string, std::string>> bad{
      {"", "empty"},
      {"/etc/passwd", "absolute"},
      {"../x.obj", "\"..\""},
      {"a/../../x.obj", "\"..\""},
      {"a/..", "\"..\""},
      {"./a.obj", "\".\""},
      {"a//b.obj", "empty component"},
      {"a/", "empty component"},
      {std::string("a\0b", 3), "NUL"},
      {"a\nb", "control"},
      {"a\\b.obj", "backslash"},
      {std::string(kMaxAssetPathBytes + 1, 'a'), "bytes long"},
      {std::string(kMaxAssetPathComponentBytes + 1, 'a') + "/b", "longer than 255"},
  };
  for (const auto& [path, problem] : bad) {
    const std::optional<std::string> found = AssetPathProblem(path);
    ASSERT_TRUE(found.has_value()) << path;
    EXPECT_NE(found->find(problem), std::string::npos) << path << ": " << *found;
  }
}

TEST_F(AssetStoreTest, PutStoresVerifiedBytesUnderTheirHashOnce) {
  const std::string bytes = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string hash = wire::Sha256Hex(bytes);
  EXPECT_FALSE(store_->Has(hash));
  EXPECT_EQ(store_->Put(hash, bytes), AssetStore::CommitResult::kCreated);
  EXPECT_TRUE(store_->Has(hash));
  EXPECT_EQ(store_->PathOf(hash), folder_ / "assets" / hash);
  EXPECT_EQ(ReadFile(store_->PathOf(hash)), bytes);
  EXPECT_EQ(store_->SizeOf(hash), bytes.size());
  EXPECT_EQ(store_->Put(hash, bytes), AssetStore::CommitResult::kAlreadyThere);
  // No temp file is left behind, whatever the outcome.
  EXPECT_EQ(FilesUnder(folder_ / "assets" / ".incoming"), 0u);
}

TEST_F(AssetStoreTest, BytesThatDoNotHashToTheNameAreDropped) {
  const std::string claimed = wire::Sha256Hex("the real bytes");
  std::unique_ptr<AssetStore::Upload> upload = store_->BeginUpload();
  upload->Write("other ");
  upload->Write("bytes");
  EXPECT_EQ(upload->size(), 11u);
  std::string actual;
  EXPECT_EQ(store_->Commit(*upload, claimed, &actual), AssetStore::CommitResult::kHashMismatch);
  EXPECT_EQ(actual, wire::Sha256Hex("other bytes"));
  upload.reset();
  EXPECT_FALSE(store_->Has(claimed));
  EXPECT_FALSE(store_->Has(actual));
  EXPECT_EQ(FilesUnder(folder_ / "assets"), 0u);
}

TEST_F(AssetStoreTest, AnAbandonedUploadLeavesNothing) {
  {
    std::unique_ptr<AssetStore::Upload> upload = store_->BeginUpload();
    upload->Write("half an upload");
    EXPECT_EQ(FilesUnder(folder_ / "assets"), 1u);
  }
  EXPECT_EQ(FilesUnder(folder_ / "assets"), 0u);
}

TEST_F(AssetStoreTest, MissingListsEachAbsentHashOnceInOrder) {
  const std::string have = wire::Sha256Hex("have");
  store_->Put(have, "have");
  const std::string a = wire::Sha256Hex("a");
  const std::string b = wire::Sha256Hex("b");
  EXPECT_EQ(store_->Missing({b, have, a, b}), (std::vector<std::string>{b, a}));
  EXPECT_TRUE(store_->Missing({have}).empty());
  EXPECT_TRUE(store_->Missing({}).empty());
}

TEST_F(AssetStoreTest, MaterialiseLaysOutFilesUnderTheirPathsAndRemovesThemAfter) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string mtl = "newmtl red\nKd 1 0 0\n";
  store_->Put(wire::Sha256Hex(obj), obj);
  store_->Put(wire::Sha256Hex(mtl), mtl);
  fs::path laidOut;
  {
    std::unique_ptr<AssetStore::Folder> folder = store_->Materialise(
        {{"scene.obj", wire::Sha256Hex(obj)}, {"lib/red.mtl", wire::Sha256Hex(mtl)},
         {"copy/of/scene.obj", wire::Sha256Hex(obj)}});
    laidOut = folder->path();
    EXPECT_EQ(laidOut.parent_path(), folder_ / "assets" / ".submissions");
    EXPECT_EQ(ReadFile(laidOut / "scene.obj"), obj);
    EXPECT_EQ(ReadFile(laidOut / "lib" / "red.mtl"), mtl);
    EXPECT_EQ(ReadFile(laidOut / "copy" / "of" / "scene.obj"), obj);
    EXPECT_EQ(FilesUnder(laidOut), 3u);
  }
  EXPECT_FALSE(fs::exists(laidOut));
  // The stored assets stay.
  EXPECT_EQ(ReadFile(store_->PathOf(wire::Sha256Hex(obj))), obj);
}

TEST_F(AssetStoreTest, MaterialiseRefusesWhatItCannotLayOutAndLeavesNothing) {
  const std::string hash = wire::Sha256Hex("x");
  store_->Put(hash, "x");
  const fs::path submissions = folder_ / "assets" / ".submissions";
  EXPECT_THROW(store_->Materialise({{"a", hash}, {"a/b", hash}}), std::invalid_argument);
  EXPECT_THROW(store_->Materialise({{"ok", hash}, {"../escape", hash}}), std::invalid_argument);
  EXPECT_THROW(store_->Materialise({{"ok", hash}, {"missing", wire::Sha256Hex("y")}}), std::invalid_argument);
  EXPECT_TRUE(fs::is_empty(submissions));
}

TEST_F(AssetStoreTest, LeftoversOfAnAbruptStopAreRemovedAndAssetsKept) {
  const std::string hash = wire::Sha256Hex("kept");
  store_->Put(hash, "kept");
  std::unique_ptr<AssetStore::Upload> upload = store_->BeginUpload();
  upload->Write("interrupted");
  std::unique_ptr<AssetStore::Folder> folder = store_->Materialise({{"a/kept.bin", hash}});
  EXPECT_EQ(FilesUnder(folder_ / "assets"), 3u);
  store_->RemoveLeftovers();
  EXPECT_EQ(FilesUnder(folder_ / "assets"), 1u);
  EXPECT_TRUE(store_->Has(hash));
  // A store that was never used has nothing to remove.
  AssetStore("/nonexistent/tcfarm/assets").RemoveLeftovers();
}

}  // namespace
}  // namespace tcfarm
