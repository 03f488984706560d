#include "proto/curve/curve_keys.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <string>

namespace tcfarm::curve {
namespace {

class CurveKeysTest : public ::testing::Test {
 protected:
  CurveKeysTest()
      : directory_(std::filesystem::temp_directory_path() /
                   ("curve_keys_test_" + std::to_string(::getpid()) + "_" +
                    ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    std::filesystem::remove_all(directory_);
  }
  ~CurveKeysTest() override { std::filesystem::remove_all(directory_); }
  std::filesystem::path Write(const std::string& name, const std::string& text) {
    std::filesystem::create_directories(directory_);
    std::ofstream(directory_ / name) << text;
    return directory_ / name;
  }
  std::filesystem::path directory_;
};

TEST_F(CurveKeysTest, WhatIsWrittenReadsBack) {
  const KeyPair keys = GenerateKeyPair();
  EXPECT_TRUE(IsKeyText(keys.publicKey));
  EXPECT_EQ(PublicKeyOf(keys.secretKey), keys.publicKey);
  const auto [secretFile, publicFile] = WriteKeyPair(directory_, "worker-1", keys);
  EXPECT_EQ(ReadSecretKeyFile(secretFile).publicKey, keys.publicKey);
  EXPECT_EQ(ReadKeyFile(publicFile), keys.publicKey);
  struct stat info {};
  ASSERT_EQ(::stat(secretFile.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0600u);
  EXPECT_EQ(ReadPublicKeys(directory_), (std::map<std::string, std::string>{{keys.publicKey, "worker-1.pub"}}));
}

TEST_F(CurveKeysTest, ExistingFilesAreKeptUnlessOverwriting) {
  WriteKeyPair(directory_, "c", GenerateKeyPair());
  EXPECT_THROW(WriteKeyPair(directory_, "c", GenerateKeyPair()), std::runtime_error);
  const KeyPair replacement = GenerateKeyPair();
  WriteKeyPair(directory_, "c", replacement, /*overwrite=*/true);
  EXPECT_EQ(ReadKeyFile(directory_ / "c.pub"), replacement.publicKey);
}

TEST_F(CurveKeysTest, BadFilesAreNamedWithTheirLine) {
  const std::string key = GenerateKeyPair().publicKey;
  const auto expectError = [](const std::filesystem::path& file, const std::string& part) {
    try {
      ReadKeyFile(file);
      ADD_FAILURE() << file << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    }
  };
  expectError(Write("short.pub", "# comment\nabc\n"), "line 2: expected a CURVE key");
  expectError(Write("two.pub", key + "\n" + key + "\n"), "line 2: a second key");
  expectError(Write("none.pub", "# only a comment\n\n"), "no key in it");
  expectError(Write("badchar.pub", std::string(39, 'a') + "~\n"), "expected a CURVE key");
  expectError(directory_ / "missing.pub", "cannot read");
  EXPECT_EQ(ReadKeyFile(Write("spaced.pub", "  " + key + " \r\n")), key);
}

TEST_F(CurveKeysTest, TheAllowListSkipsBadFilesAndOtherNames) {
  const KeyPair keys = GenerateKeyPair();
  Write("good.pub", keys.publicKey + "\n");
  Write("bad.pub", "not a key\n");
  Write("notes.txt", GenerateKeyPair().publicKey + "\n");
  std::map<std::string, std::string> skipped;
  const auto allowed = ReadPublicKeys(directory_, &skipped);
  EXPECT_EQ(allowed, (std::map<std::string, std::string>{{keys.publicKey, "good.pub"}}));
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_NE(skipped.begin()->first.find("bad.pub"), std::string::npos);
  EXPECT_THROW(ReadPublicKeys(directory_ / "nowhere"), std::invalid_argument);
}

}  // namespace
}  // namespace tcfarm::curve
