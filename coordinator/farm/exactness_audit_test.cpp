// Disputes settled by a referee, workers traced back through the ledger, frames repaired.
// The referee here is a stand-in that answers from a table of true values: the tracing
// one is tested in referee_test.cpp.
#include "coordinator/farm/exactness_audit.h"

#include <gtest/gtest.h>

namespace tcfarm {
namespace {

constexpr int kFrames = 10;

// Answers every question with `truth` for every channel, or with `error`.
class TableReferee : public Referee {
 public:
  void Ask(Question question) override { questions.push_back(std::move(question)); }
  std::vector<Answer> TakeAnswers(uint64_t jobId, Purpose purpose) override {
    std::vector<Answer> answers;
    for (const Question& q : questions) {
      if (q.jobId != jobId || q.purpose != purpose) continue;
      Answer answer{q.id, {}, error, 0, 0};
      if (error.empty()) answer.rgb.assign(3 * q.pixels.size(), truth);
      answers.push_back(std::move(answer));
    }
    questions.clear();
    return answers;
  }
  std::vector<Question> questions;
  float truth = 1.0f;
  std::string error;
};

Dispute DisputeOver(int frame, std::vector<uint32_t> pixels, float job, float check) {
  Dispute d{frame, "checker", std::move(pixels), {}, {}};
  d.jobValues.assign(3 * d.pixels.size(), job);
  d.checkerValues.assign(3 * d.pixels.size(), check);
  return d;
}

ExactnessAudit::SceneRef Scene() { return {std::string(64, 'c'), "{}"}; }

std::vector<int> Repairs(ExactnessAudit& audit) {
  return audit.TakeFramesToRepair([](int) { return true; });
}

TEST(SettleTest, TheTruthSaysWhichSideIsWrong) {
  EXPECT_TRUE(Settle(DisputeOver(0, {4, 9}, 1, 2), std::vector<float>(6, 1.0f)).checkerWrong);
  EXPECT_TRUE(Settle(DisputeOver(0, {4, 9}, 1, 2), std::vector<float>(6, 1.0f)).jobWrong.empty());
  const Ruling jobWrong = Settle(DisputeOver(0, {4, 9}, 3, 2), std::vector<float>(6, 2.0f));
  EXPECT_FALSE(jobWrong.checkerWrong);
  EXPECT_EQ(jobWrong.jobWrong, (std::vector<uint32_t>{4, 9}));
  const Ruling both = Settle(DisputeOver(0, {4}, 3, 2), std::vector<float>(3, 1.0f));
  EXPECT_TRUE(both.checkerWrong);
  EXPECT_EQ(both.jobWrong.size(), 1u);
  EXPECT_THROW(Settle(DisputeOver(0, {4}, 3, 2), std::vector<float>(2, 1.0f)), std::invalid_argument);
}

// -0 and +0 compare equal as numbers but not as bits: exactness is about bits.
TEST(SettleTest, BitsNotNumbers) {
  Dispute d = DisputeOver(0, {1}, 0.0f, 0.0f);
  d.jobValues[0] = -0.0f;
  EXPECT_EQ(Settle(d, std::vector<float>(3, 0.0f)).jobWrong.size(), 1u);
}

// The worker whose value a frame shows where the frame's own task traced it; a copy, or a
// pixel two workers' tasks traced, names nobody.
TEST(TracerLedgerTest, NamesTheOneWorkerThatSentTheValueAFrameShows) {
  TracerLedger ledger;
  ledger.Record(2, "a", PixelSet::FromSortedIndices({5, 6}), 3);
  ledger.Record(3, "b", PixelSet::FromSortedIndices({6}), 3);
  ledger.Record(3, "c", PixelSet::FromSortedIndices({6, 8}), 3);
  EXPECT_EQ(ledger.TracerAt(2, 5), "a");
  EXPECT_EQ(ledger.TracerAt(2, 6), "a");
  EXPECT_FALSE(ledger.TracerAt(4, 5));  // a copy of frame 2's value
  EXPECT_FALSE(ledger.TracerAt(3, 5));
  EXPECT_FALSE(ledger.TracerAt(3, 6));  // b and c both sent a value: which one it shows is not known
  EXPECT_EQ(ledger.TracerAt(3, 8), "c");
  EXPECT_EQ(ledger.WorkersOf(3), (std::set<std::string>{"b", "c"}));
}

// A frame's checks avoid every worker whose values it may show: traced there, or copied
// from an earlier frame whose window reaches it.
TEST(TracerLedgerTest, TheWorkersReachingAFrameIncludeThoseItCopiesFrom) {
  TracerLedger ledger;
  ledger.Record(2, "a", PixelSet::Full(4), 3);
  ledger.Record(4, "b", PixelSet::Full(4), 0);
  ledger.Record(6, "c", PixelSet(), 1);
  EXPECT_EQ(ledger.WorkersReaching(4), (std::set<std::string>{"a", "b"}));
  EXPECT_EQ(ledger.WorkersReaching(5), (std::set<std::string>{"a"}));
  EXPECT_EQ(ledger.WorkersReaching(6), (std::set<std::string>{"c"}));
  EXPECT_EQ(ledger.WorkersReaching(7), (std::set<std::string>{"c"}));
  EXPECT_TRUE(ledger.WorkersReaching(8).empty());
  EXPECT_TRUE(ledger.WorkersReaching(1).empty());
}

TEST(TracerLedgerTest, AWorkersValuesReachItsFramesAndTheirWindows) {
  TracerLedger ledger;
  ledger.Record(2, "a", PixelSet::Full(4), 2);
  ledger.Record(8, "a", PixelSet::Full(4), 3);
  ledger.Record(5, "b", PixelSet::Full(4), 0);
  EXPECT_EQ(ledger.FramesReachedBy("a", kFrames), (std::set<int>{2, 3, 4, 8, 9}));
  EXPECT_EQ(ledger.FramesReachedBy("b", kFrames), (std::set<int>{5}));
  EXPECT_TRUE(ledger.FramesReachedBy("c", kFrames).empty());
}

// What no dispute can need any more is forgotten: pixels of frames whose copies cannot
// reach the lowest frame still checked. Who traced a frame is kept, for repairs.
TEST(TracerLedgerTest, ForgetsThePixelsNoDisputeCanNeed) {
  TracerLedger ledger;
  ledger.Record(0, "a", PixelSet::FromSortedIndices({5}), 1);  // copies reach frame 1
  ledger.Record(1, "b", PixelSet::FromSortedIndices({6}), 4);  // copies reach frame 5
  ledger.Record(3, "a", PixelSet::FromSortedIndices({7}), 0);
  EXPECT_EQ(ledger.PixelSetsHeld(), 3u);
  ledger.ForgetPixelsBefore(2);
  EXPECT_EQ(ledger.PixelSetsHeld(), 2u);                 // frame 0's: nothing reaches frame 2
  EXPECT_FALSE(ledger.TracerAt(0, 5).has_value());
  EXPECT_EQ(ledger.TracerAt(1, 6), "b");                 // frame 1's copies may reach 4
  ledger.ForgetPixelsBefore(6);
  EXPECT_EQ(ledger.PixelSetsHeld(), 0u);
  EXPECT_EQ(ledger.FramesReachedBy("a", kFrames), (std::set<int>{0, 1, 3}));  // repairs still find them
  EXPECT_EQ(ledger.WorkersOf(1), (std::set<std::string>{"b"}));
}

// An open dispute keeps what it needs to find its source.
TEST(ExactnessAuditTest, AnOpenDisputeKeepsItsSourcesPixels) {
  TableReferee referee;
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.OnTraced(5, "liar", PixelSet::FromSortedIndices({10}), 2);
  audit.Open({DisputeOver(5, {10}, 0.5f, 1.0f)}, Scene);
  audit.ForgetBefore(9);  // every check answered, but the dispute is open
  EXPECT_EQ(audit.PixelSetsHeld(), 1u);
  const std::vector<ExactnessAudit::Verdict> verdicts = audit.HearReferee();
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].worker, "liar");
  audit.ForgetBefore(9);
  EXPECT_EQ(audit.PixelSetsHeld(), 0u);
}

// A repair rewrites the disputed frame while the referee is still tracing: the values
// disputed are the liar's, traced before the repair, so the liar is named, never the
// worker that repaired the frame meanwhile (which the farm once banned for them).
TEST(ExactnessAuditTest, ARepairWhileADisputeIsOpenIsNotBlamedForTheValuesDisputed) {
  TableReferee referee;
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.OnTraced(1, "liar", PixelSet::FromSortedIndices({34}), 1);
  audit.Open({DisputeOver(1, {34}, 0.5f, 1.0f)}, Scene);
  audit.OnRepaired(1, "honest", PixelSet::Full(64), 1);
  const std::vector<ExactnessAudit::Verdict> verdicts = audit.HearReferee();
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].worker, "liar");
}

// The job shows a wrong copy of a value traced two frames before. A copy is no value a
// worker sent for that frame: nobody is named (whoever traced it may have sent the truth
// for its own frame), but the frame is repaired. Once the farm distrusts the worker on
// other evidence, the frames its values reached are repaired too.
TEST(ExactnessAuditTest, AWrongCopyIsRepairedAndIsNoEvidenceAgainstAnyone) {
  TableReferee referee;
  ExactnessAudit audit(7, 100, kFrames, &referee);
  audit.OnTraced(3, "liar", PixelSet::FromSortedIndices({10, 11}), 2);
  audit.OnTraced(5, "honest", PixelSet::FromSortedIndices({12}), 2);
  audit.Open({DisputeOver(5, {10}, 0.5f, 1.0f)}, Scene);
  ASSERT_EQ(referee.questions.size(), 1u);
  EXPECT_EQ(referee.questions[0].frame, 105);  // the scene's numbering
  EXPECT_TRUE(audit.HearReferee().empty());
  EXPECT_TRUE(audit.Pending());  // frame 5 shows a wrong value: owed a repair
  EXPECT_EQ(Repairs(audit), (std::vector<int>{5}));
  audit.OnWorkerDistrusted("liar", "liar's name");
  EXPECT_EQ(Repairs(audit), (std::vector<int>{3, 4}));  // 5 is in repair already
  audit.OnRepaired(3, "honest", PixelSet::Full(16), 0);
  audit.OnRepaired(4, "honest", PixelSet::Full(16), 2);
  audit.OnRepaired(5, "honest", PixelSet::Full(16), 1);
  // Frame 5 was in repair when the liar was distrusted: it is repaired once more, as every
  // frame the liar's values reached is.
  EXPECT_EQ(Repairs(audit), (std::vector<int>{5}));
  audit.OnRepaired(5, "honest", PixelSet::Full(16), 0);
  EXPECT_FALSE(audit.Pending());
  const nlohmann::json report = audit.Report();
  EXPECT_EQ(report["workers_distrusted"], nlohmann::json::array({"liar's name"}));
  EXPECT_EQ(report["job_values_wrong"], 1);
  EXPECT_EQ(report["checks_wrong"], 0);
  EXPECT_EQ(report["frames_retraced"], 3);
  EXPECT_EQ(report["frames_rewritten"], 2);
  EXPECT_EQ(report["pixels_rewritten"], 3);
}

// A frame kept from before a restart shows values sent to the run before; a worker of this
// run that traced the same pixels again (its bin was in progress) sent values the frame
// does not show, and is never held to them.
TEST(ExactnessAuditTest, AFrameKeptFromBeforeARestartNamesNobody) {
  TableReferee referee;
  std::vector<bool> kept(kFrames, false);
  kept[4] = true;
  ExactnessAudit audit(7, 0, kFrames, &referee, kept);
  audit.OnTraced(4, "honest", PixelSet::FromSortedIndices({10}), 0);
  audit.OnTraced(6, "liar", PixelSet::FromSortedIndices({10}), 0);
  audit.Open({DisputeOver(4, {10}, 0.5f, 1.0f), DisputeOver(6, {10}, 0.5f, 1.0f)}, Scene);
  const std::vector<ExactnessAudit::Verdict> verdicts = audit.HearReferee();
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].worker, "liar");
  EXPECT_EQ(Repairs(audit), (std::vector<int>{4, 6}));
}

TEST(ExactnessAuditTest, ALyingCheckerIsNamedAndTheJobKeepsItsValues) {
  TableReferee referee;
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.OnTraced(1, "honest", PixelSet::Full(16), 3);
  audit.Open({DisputeOver(2, {3, 4}, 1.0f, 0.5f)}, Scene);
  const std::vector<ExactnessAudit::Verdict> verdicts = audit.HearReferee();
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].worker, "checker");
  EXPECT_FALSE(audit.Pending());  // nothing of the job is wrong
  audit.OnWorkerDistrusted("checker", "checker");
  EXPECT_TRUE(Repairs(audit).empty());  // it traced none of the job's values
  EXPECT_EQ(audit.Report()["checks_wrong"], 1);
}

TEST(ExactnessAuditTest, RepairsWaitForTheFrameToBeWrittenAndARepairerFoundWrongRepairsAgain) {
  TableReferee referee;
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.OnTraced(6, "liar", PixelSet::Full(16), 0);
  audit.OnWorkerDistrusted("liar", "liar");
  EXPECT_TRUE(audit.TakeFramesToRepair([](int) { return false; }).empty());
  EXPECT_TRUE(audit.Pending());
  EXPECT_EQ(Repairs(audit), std::vector<int>{6});
  EXPECT_TRUE(Repairs(audit).empty());  // in repair already
  audit.OnRepaired(6, "second", PixelSet::Full(16), 16);
  audit.OnWorkerDistrusted("second", "second");
  EXPECT_EQ(Repairs(audit), std::vector<int>{6});
}

TEST(ExactnessAuditTest, AnUnansweredDisputeIsReportedUnsettled) {
  TableReferee referee;
  referee.error = "the scene no longer parses";
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.Open({DisputeOver(2, {3}, 1.0f, 0.5f)}, Scene);
  EXPECT_TRUE(audit.Pending());
  EXPECT_TRUE(audit.HearReferee().empty());
  EXPECT_FALSE(audit.Pending());
  EXPECT_NE(audit.Report()["unsettled"][0].get<std::string>().find("no longer parses"), std::string::npos);

  ExactnessAudit withoutReferee(8, 0, kFrames, nullptr);
  withoutReferee.Open({DisputeOver(2, {3}, 1.0f, 0.5f)}, Scene);
  EXPECT_FALSE(withoutReferee.Pending());
  EXPECT_EQ(withoutReferee.Report()["unsettled"].size(), 1u);
}

}  // namespace
}  // namespace tcfarm
