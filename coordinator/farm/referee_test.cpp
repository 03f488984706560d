// The referee's values are the bits a worker returns: the same scene JSON, the texture
// read from the store by its hash, traced with the workers' tracer.
#include "coordinator/farm/referee.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <thread>

#include "worker/tracing.h"
#include "proto/scene/import/import_budget.h"
#include "proto/scene/scene.h"
#include "tests/support/cpp/checker_png_for_tests.h"

namespace tcfarm {
namespace {

namespace fs = std::filesystem;

const std::string kHash(64, 'e');

std::string TexturedScene() {
  return R"({"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": {"keyframes": [{"frame": 0, "value": [0, 0, 4]},
                                                       {"frame": 9, "value": [3, 0, 4]}]},
                "intensity": [20, 20, 20]}],
    "materials": {"printed": {"diffuse": [1, 1, 1], "diffuse_texture": {"asset": ")" + kHash + R"("}}},
    "shapes": [{"type": "mesh", "material": "printed",
                "vertices": [[-4, 4, 0], [4, 4, 0], [4, -4, 0], [-4, -4, 0]],
                "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]], "triangles": [[0, 3, 2], [0, 2, 1]]}],
    "render": {"width": 16, "height": 12, "frames": {"start": 0, "count": 10}}})";
}

std::vector<Referee::Answer> WaitForAnswers(Referee& referee, uint64_t job, size_t count) {
  std::vector<Referee::Answer> answers;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (answers.size() < count && std::chrono::steady_clock::now() < deadline) {
    for (Referee::Answer& a : referee.TakeAnswers(job)) answers.push_back(std::move(a));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return answers;
}

class RefereeTest : public testing::Test {
 protected:
  void SetUp() override {
    assets_ = fs::temp_directory_path() / ("tcfarm_referee_test_" + std::to_string(::getpid()));
    fs::create_directories(assets_);
    WriteCheckerPng(assets_ / "checker.png");
    fs::rename(assets_ / "checker.png", assets_ / kHash);  // as STORE/assets holds an uploaded image
  }
  void TearDown() override { fs::remove_all(assets_); }
  fs::path assets_;
};

TEST_F(RefereeTest, TracesTheBitsAWorkerReturns) {
  Scene scene = ParseScene(TexturedScene());
  scene.materials[1].As<Phong>().diffuseTexture->file = assets_ / kHash;  // as a worker's cache holds it
  PrepareForTracing(scene);
  EmbreeDevice device;
  TracingThreads threads(2);
  Tracer tracer(device, scene, threads);
  const std::vector<uint32_t> pixels = {0, 17, 90, 191};
  std::vector<float> expected(3 * pixels.size());
  tracer.TracePixels(7, pixels.data(), pixels.size(), expected.data());

  TracingReferee referee(assets_);
  referee.Ask({1, 41, "hash-a", TexturedScene(), 7, pixels});
  referee.Ask({2, 42, "hash-a", TexturedScene(), 0, pixels});  // another job, the scene kept
  const std::vector<Referee::Answer> first = WaitForAnswers(referee, 1, 1);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].id, 41u);
  EXPECT_EQ(first[0].error, "");
  EXPECT_EQ(first[0].rgb, expected);
  const std::vector<Referee::Answer> second = WaitForAnswers(referee, 2, 1);
  ASSERT_EQ(second.size(), 1u);
  EXPECT_NE(second[0].rgb, expected);  // frame 0: the light is elsewhere
  EXPECT_TRUE(referee.TakeAnswers(1).empty());
}

TEST_F(RefereeTest, ASceneItCannotBuildIsAnAnswerThatSaysWhy) {
  TracingReferee referee(assets_);
  std::string missingTexture = TexturedScene();
  missingTexture.replace(missingTexture.find(kHash), kHash.size(), std::string(64, 'f'));
  referee.Ask({3, 1, "hash-b", missingTexture, 0, {0}});
  referee.Ask({3, 2, "hash-c", "{not json", 0, {0}});
  referee.Ask({3, 3, "hash-a", TexturedScene(), 0, {0}});  // and it recovers
  const std::vector<Referee::Answer> answers = WaitForAnswers(referee, 3, 3);
  ASSERT_EQ(answers.size(), 3u);
  EXPECT_NE(answers[0].error, "");
  EXPECT_TRUE(answers[0].rgb.empty());
  EXPECT_NE(answers[1].error, "");
  EXPECT_EQ(answers[2].error, "");
  EXPECT_EQ(answers[2].rgb.size(), 3u);
}

// The referee's scene shares the coordinator's import budget: while other imports fill it,
// the question waits (it is not failed), and is answered once they give the room back;
// the scene it keeps built holds its share.
TEST_F(RefereeTest, ItsSceneWaitsForRoomInTheImportBudget) {
  const std::string json = TexturedScene();
  constexpr uint64_t kBudget = 1 << 20;  // room for the scene, parsed, many times over
  const auto budget = std::make_shared<ImportBudget>(kBudget, std::chrono::milliseconds(20));
  TracingReferee referee(assets_, budget);
  std::optional<ImportReservation> other = budget->Reserve(kBudget);  // a scene check, say
  referee.Ask({4, 1, "hash-a", json, 3, {0, 5}});
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_TRUE(referee.TakeAnswers(4).empty());  // postponed, not failed
  other.reset();
  const std::vector<Referee::Answer> answers = WaitForAnswers(referee, 4, 1);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].error, "");
  EXPECT_EQ(answers[0].rgb.size(), 6u);
  EXPECT_GE(budget->Stats().reservedBytes, json.size());  // the scene kept built
}

// A scene larger than the whole budget can never be built: an answer that says so.
TEST_F(RefereeTest, ASceneLargerThanTheImportBudgetIsAnAnswerThatSaysWhy) {
  TracingReferee referee(assets_, std::make_shared<ImportBudget>(16));
  referee.Ask({5, 1, "hash-a", TexturedScene(), 0, {0}});
  const std::vector<Referee::Answer> answers = WaitForAnswers(referee, 5, 1);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_NE(answers[0].error, "");
  EXPECT_TRUE(answers[0].rgb.empty());
}

}  // namespace
}  // namespace tcfarm
