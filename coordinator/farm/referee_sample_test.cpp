// The referee's unseen sample: what it draws, whom its answers name, and what it costs.
// The referee here answers from a table of true values; the tracing one is tested in
// referee_test.cpp.
#include "coordinator/farm/referee_sample.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tcfarm {
namespace {

constexpr uint32_t kPixels = 4096;

// Answers every pixel p with the value p, in every channel.
class TableReferee : public Referee {
 public:
  void Ask(Question question) override { questions.push_back(std::move(question)); }
  std::vector<Answer> TakeAnswers(uint64_t jobId, Purpose purpose) override {
    std::vector<Answer> answers;
    for (const Question& q : questions) {
      if (q.jobId != jobId || q.purpose != purpose) continue;
      Answer answer{q.id, {}, "", 0, 0.25};
      for (uint32_t p : q.pixels) answer.rgb.insert(answer.rgb.end(), 3, float(p));
      answers.push_back(std::move(answer));
    }
    questions.clear();
    return answers;
  }
  std::vector<Question> questions;
};

// The true values of `pixels`, with the pixels in `altered` made wrong.
std::vector<float> Values(const PixelSet& pixels, const std::set<uint32_t>& altered = {}) {
  std::vector<float> rgb;
  pixels.ForEach([&](uint32_t p) { rgb.insert(rgb.end(), 3, altered.count(p) ? -1.0f : float(p)); });
  return rgb;
}

const std::string& SceneJson() {
  static const std::string json = "{}";
  return json;
}

TEST(RefereeSampleTest, ItsShareCatchesSixteenPixelsAFrameAlmostSurely) {
  for (int frames : {16, 40, 60}) {
    const double share = RefereeSample::ShareFor(frames);
    EXPECT_GE(RefereeSample::CatchProbability(share, 16, frames), 1 - 1.0001e-6) << frames;
  }
  // Bounded both ways: a one-frame job pays a tenth, a long one a hundredth.
  EXPECT_EQ(RefereeSample::ShareFor(1), RefereeSample::kMaxShare);
  EXPECT_EQ(RefereeSample::ShareFor(10000), RefereeSample::kMinShare);
  EXPECT_NEAR(RefereeSample::CatchProbability(0.01, 1, 100), 1 - std::pow(0.99, 100), 1e-12);
  EXPECT_EQ(RefereeSample::CatchProbability(0.5, 1, 0), 0);
}

TEST(RefereeSampleTest, DrawsItsShareOfEveryWorkersPixels) {
  TableReferee referee;
  RefereeSample sample(7, 0, 40, &referee, 12345);
  const PixelSet all = PixelSet::Full(kPixels);
  const std::vector<float> rgb = Values(all);
  for (int frame = 0; frame < 40; ++frame) sample.OnValues(frame, frame % 2 ? "a" : "b", all, rgb.data());
  sample.Ask(std::string(64, 'c'), SceneJson);
  ASSERT_EQ(referee.questions.size(), 40u);  // one question a frame
  size_t drawn = 0;
  for (const Referee::Question& q : referee.questions) {
    EXPECT_EQ(q.purpose, Referee::Purpose::kSample);
    for (uint32_t p : q.pixels) EXPECT_LT(p, kPixels);
    drawn += q.pixels.size();
  }
  const double expected = sample.share() * 40 * kPixels;
  EXPECT_NEAR(double(drawn), expected, 5 * std::sqrt(expected));
  EXPECT_TRUE(sample.Pending());
  EXPECT_TRUE(sample.HearReferee().empty());  // every value was the truth
  EXPECT_FALSE(sample.Pending());
  const nlohmann::json report = sample.Report();
  EXPECT_EQ(report["pixels_sampled"], drawn);
  EXPECT_EQ(report["referee_traces"], drawn);
  EXPECT_EQ(report["horizon_checks"], 0);
  EXPECT_EQ(report["pixels_wrong"], 0);
  EXPECT_EQ(report["pixels_sent"], 40 * kPixels);
  EXPECT_DOUBLE_EQ(report["referee_cpu_seconds"].get<double>(), 0.25 * 40);
}

// The drawn pixels are a different secret for every job: no worker can learn which of its
// pixels are watched from another job.
TEST(RefereeSampleTest, EveryJobDrawsItsOwnPixels) {
  TableReferee one, two;
  RefereeSample first(1, 0, 40, &one), second(2, 0, 40, &two);
  const PixelSet all = PixelSet::Full(kPixels);
  const std::vector<float> rgb = Values(all);
  first.OnValues(0, "a", all, rgb.data());
  second.OnValues(0, "a", all, rgb.data());
  first.Ask("h", SceneJson);
  second.Ask("h", SceneJson);
  ASSERT_EQ(one.questions.size(), 1u);
  ASSERT_EQ(two.questions.size(), 1u);
  EXPECT_NE(one.questions[0].pixels, two.questions[0].pixels);
}

// A worker that alters a few pixels of every task is named by the values it sent, and an
// honest worker beside it never is; the referee's own values and a distrusted worker's
// are not drawn.
TEST(RefereeSampleTest, NamesTheWorkerThatSentAWrongValueAndNobodyElse) {
  TableReferee referee;
  RefereeSample sample(7, 100, 40, &referee, 99);
  for (int frame = 0; frame < 40; ++frame) {
    // Tasks of 64 pixels, side by side; the liar alters 3 pixels of each of its tasks.
    for (uint32_t begin = 0; begin < kPixels; begin += 64) {
      const PixelSet task = PixelSet::FromSpans({{begin, begin + 64}}, kPixels);
      const bool liar = (begin / 64) % 2 == 1;
      sample.OnValues(frame, liar ? "liar" : "honest", task,
                      Values(task, liar ? std::set<uint32_t>{begin, begin + 20, begin + 40} : std::set<uint32_t>{})
                          .data());
    }
  }
  sample.OnValues(0, Referee::kName, PixelSet::Full(kPixels), Values(PixelSet::Full(kPixels), {1, 2, 3}).data());
  sample.Ask("h", SceneJson);
  const std::vector<Verdict> verdicts = sample.HearReferee();
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].worker, "liar");
  EXPECT_NE(verdicts[0].why.find("unseen sample"), std::string::npos) << verdicts[0].why;
  const std::map<int, uint64_t> wrong = sample.TakeWrongPixels();
  uint64_t wrongPixels = 0;
  for (const auto& [frame, pixels] : wrong) {
    EXPECT_GE(frame, 0);
    EXPECT_LT(frame, 40);
    wrongPixels += pixels;
  }
  EXPECT_EQ(sample.Report()["pixels_wrong"], wrongPixels);
  EXPECT_GT(wrongPixels, 0u);
  EXPECT_TRUE(sample.TakeWrongPixels().empty());  // each told once
  // Once distrusted, its values are retraced in full by others: none is drawn.
  sample.OnWorkerDistrusted("liar");
  sample.OnValues(0, "liar", PixelSet::Full(kPixels), Values(PixelSet::Full(kPixels), {5}).data());
  sample.Ask("h", SceneJson);
  EXPECT_TRUE(referee.questions.empty());
}

// A horizon vouches for the value through later frames: the referee traces the drawn pixel
// at the last frame the horizon vouches for (within the job), and a value that differs
// there names the worker that sent the horizon.
TEST(RefereeSampleTest, AHorizonIsCheckedAtTheLastFrameItVouchesFor) {
  // Answers pixel p of frame f with p + 1000 f: every pixel changes every frame.
  class ChangingReferee : public TableReferee {
   public:
    std::vector<Answer> TakeAnswers(uint64_t jobId, Purpose purpose) override {
      std::vector<Answer> answers;
      for (const Question& q : questions) {
        if (q.jobId != jobId || q.purpose != purpose) continue;
        asked.push_back(q.frame);
        Answer answer{q.id, {}, "", 0, 0};
        for (uint32_t p : q.pixels) answer.rgb.insert(answer.rgb.end(), 3, float(p) + 1000.0f * float(q.frame));
        answers.push_back(std::move(answer));
      }
      questions.clear();
      return answers;
    }
    std::vector<int> asked;
  } referee;
  RefereeSample sample(7, 100, 10, &referee, 3);
  const PixelSet all = PixelSet::Full(kPixels);
  std::vector<float> rgb;
  all.ForEach([&](uint32_t p) { rgb.insert(rgb.end(), 3, float(p) + 1000.0f * 102); });
  const std::vector<int32_t> honest(kPixels, 103), lying(kPixels, 120);  // 120: past the job's end
  sample.OnValues(2, "honest", all, rgb.data(), honest.data());
  sample.Ask("h", SceneJson);
  EXPECT_TRUE(sample.HearReferee().empty());
  EXPECT_EQ(referee.asked, std::vector<int>{102});  // horizon 103 vouches for frame 102 alone
  EXPECT_EQ(sample.Report()["horizon_checks"], 0);
  sample.OnValues(2, "liar", all, rgb.data(), lying.data());
  sample.Ask("h", SceneJson);
  const std::vector<Verdict> verdicts = sample.HearReferee();
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].worker, "liar");
  EXPECT_NE(verdicts[0].why.find("through frame 109"), std::string::npos) << verdicts[0].why;
  EXPECT_GT(sample.Report()["horizon_checks"].get<int>(), 0);
}

// A suspect (its values may show in a frame a check found wrong) and a worker on probation
// have more of their values drawn; nothing they are sent changes.
TEST(RefereeSampleTest, SuspectsAndNewWorkersAreDrawnMoreOften) {
  TableReferee referee;
  RefereeSample sample(7, 0, 40, &referee, 11);
  const PixelSet all = PixelSet::Full(kPixels);
  const std::vector<float> rgb = Values(all);
  auto drawnFrom = [&](const std::string& worker, bool probation) {
    for (int frame = 0; frame < 10; ++frame) sample.OnValues(frame, worker, all, rgb.data(), nullptr, probation);
    sample.Ask("h", SceneJson);
    size_t drawn = 0;
    for (const Referee::Question& q : referee.questions) drawn += q.pixels.size();
    sample.HearReferee();
    return drawn;
  };
  const size_t usual = drawnFrom("a", false);
  const size_t probation = drawnFrom("b", true);
  sample.Suspect("a");
  const size_t suspect = drawnFrom("a", false);
  EXPECT_GT(probation, 3 * usual);
  EXPECT_GT(suspect, 3 * usual);
  EXPECT_NEAR(sample.Report()["share_on_probation"].get<double>(), 4 * sample.share(), 1e-12);
}

// A frame kept from before a restart is drawn from again: a wrong value there owes the
// frame a repair and names nobody (no worker of this run sent it).
TEST(RefereeSampleTest, AFrameKeptFromBeforeARestartIsDrawnAgainAndNamesNobody) {
  TableReferee referee;
  RefereeSample sample(7, 0, 10, &referee, 21);
  const PixelSet all = PixelSet::Full(kPixels);
  std::set<uint32_t> everyPixel;
  for (uint32_t p = 0; p < kPixels; ++p) everyPixel.insert(p);
  sample.OnKeptValues(3, Values(all));
  sample.OnKeptValues(4, Values(all, everyPixel));  // a liar's values, sent to the run before
  sample.OnValues(5, "honest", all, Values(all).data());
  sample.Ask("h", SceneJson);
  EXPECT_TRUE(sample.HearReferee().empty());
  EXPECT_EQ(sample.TakeKeptFramesWrong(), std::set<int>{4});
  EXPECT_TRUE(sample.TakeKeptFramesWrong().empty());
  const nlohmann::json report = sample.Report();
  EXPECT_GT(report["kept_pixels_sampled"].get<uint64_t>(), 0u);
  EXPECT_EQ(report["kept_frames_wrong"], 1);
  EXPECT_EQ(report["workers_caught"], 0);
}

TEST(RefereeSampleTest, AJobWaitsWhileTheRefereeOwesItTooMuch) {
  TableReferee referee;
  RefereeSample sample(7, 0, 1, &referee, 5);
  const PixelSet all = PixelSet::Full(16384);
  const std::vector<float> rgb = Values(all);
  int sends = 0;
  while (!sample.Behind() && sends < 100000) {
    sample.OnValues(0, "a", all, rgb.data());
    ++sends;
  }
  EXPECT_TRUE(sample.Behind());
  sample.Ask("h", SceneJson);
  sample.HearReferee();
  EXPECT_FALSE(sample.Behind());
  EXPECT_FALSE(sample.Pending());
}

TEST(RefereeSampleTest, WithoutARefereeNothingIsDrawn) {
  RefereeSample sample(7, 0, 10, nullptr);
  const PixelSet all = PixelSet::Full(kPixels);
  sample.OnValues(0, "a", all, Values(all).data());
  EXPECT_FALSE(sample.Pending());
  EXPECT_EQ(sample.Report()["pixels_sampled"], 0);
}

}  // namespace
}  // namespace tcfarm
