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

// A frame's checks avoid every worker whose values it may show: traced there, or copied
// from an earlier frame whose window reaches it.
TEST(TracerLedgerTest, TheWorkersReachingAFrameIncludeThoseItCopiesFrom) {
  TracerLedger ledger;
  ledger.Record(2, "a", 3);
  ledger.Record(4, "b", 0);
  ledger.Record(6, "c", 1);
  EXPECT_EQ(ledger.WorkersReaching(4), (std::set<std::string>{"a", "b"}));
  EXPECT_EQ(ledger.WorkersReaching(5), (std::set<std::string>{"a"}));
  EXPECT_EQ(ledger.WorkersReaching(6), (std::set<std::string>{"c"}));
  EXPECT_EQ(ledger.WorkersReaching(7), (std::set<std::string>{"c"}));
  EXPECT_TRUE(ledger.WorkersReaching(8).empty());
  EXPECT_TRUE(ledger.WorkersReaching(1).empty());
  EXPECT_EQ(ledger.WorkersOf(4), (std::set<std::string>{"b"}));
}

TEST(TracerLedgerTest, AWorkersValuesReachItsFramesAndTheirWindows) {
  TracerLedger ledger;
  ledger.Record(2, "a", 2);
  ledger.Record(8, "a", 3);
  ledger.Record(5, "b", 0);
  ledger.Record(5, "b", 1);  // the longest window counts
  EXPECT_EQ(ledger.FramesReachedBy("a", kFrames), (std::set<int>{2, 3, 4, 8, 9}));
  EXPECT_EQ(ledger.FramesReachedBy("b", kFrames), (std::set<int>{5, 6}));
  EXPECT_TRUE(ledger.FramesReachedBy("c", kFrames).empty());
}

// The job shows wrong values at frame 5, traced or copied there. The job's side of a
// dispute is no value any one worker is known to have sent for that pixel of that frame
// (a copy, a value traced before a restart, one rewritten since it was captured): nobody
// is named, the frame is repaired, and the workers whose values it may show become
// suspects. Once the farm distrusts one on other evidence, the frames its values reached
// are repaired too.
TEST(ExactnessAuditTest, AWrongJobValueIsRepairedAndMakesSuspectsButNamesNobody) {
  TableReferee referee;
  ExactnessAudit audit(7, 100, kFrames, &referee);
  audit.OnTraced(3, "liar", 2);
  audit.OnTraced(5, "honest", 2);
  audit.Open({DisputeOver(5, {10}, 0.5f, 1.0f)}, Scene);
  ASSERT_EQ(referee.questions.size(), 1u);
  EXPECT_EQ(referee.questions[0].frame, 105);  // the scene's numbering
  EXPECT_TRUE(audit.HearReferee().empty());
  EXPECT_EQ(audit.TakeSuspects(), (std::set<std::string>{"liar", "honest"}));
  EXPECT_TRUE(audit.TakeSuspects().empty());
  EXPECT_TRUE(audit.Pending());  // frame 5 shows a wrong value: owed a repair
  EXPECT_EQ(Repairs(audit), (std::vector<int>{5}));
  audit.OnWorkerDistrusted("liar", "liar's name");
  EXPECT_EQ(Repairs(audit), (std::vector<int>{3, 4}));  // 5 is in repair already
  audit.OnRepaired(3, "honest", 0);
  audit.OnRepaired(4, "honest", 2);
  audit.OnRepaired(5, "honest", 1);
  // Frame 5 was in repair when the liar was distrusted: it is repaired once more, as every
  // frame the liar's values reached is.
  EXPECT_EQ(Repairs(audit), (std::vector<int>{5}));
  audit.OnRepaired(5, "honest", 0);
  EXPECT_FALSE(audit.Pending());
  const nlohmann::json report = audit.Report();
  EXPECT_EQ(report["workers_distrusted"], nlohmann::json::array({"liar's name"}));
  EXPECT_EQ(report["job_values_wrong"], 1);
  EXPECT_EQ(report["checks_wrong"], 0);
  EXPECT_EQ(report["frames_retraced"], 3);
  EXPECT_EQ(report["frames_rewritten"], 2);
  EXPECT_EQ(report["pixels_rewritten"], 3);
}

// A repair rewrote the disputed frame while the referee traced: the honest repairer is
// never named for the values it replaced (the farm once banned it for them).
TEST(ExactnessAuditTest, ARepairWhileADisputeIsOpenIsNotBlamedForTheValuesDisputed) {
  TableReferee referee;
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.OnTraced(1, "liar", 1);
  audit.Open({DisputeOver(1, {34}, 0.5f, 1.0f)}, Scene);
  audit.OnRepaired(1, "honest", 1);
  EXPECT_TRUE(audit.HearReferee().empty());
  EXPECT_EQ(audit.TakeSuspects(), (std::set<std::string>{"liar", "honest"}));
}

TEST(ExactnessAuditTest, ALyingCheckerIsNamedAndTheJobKeepsItsValues) {
  TableReferee referee;
  ExactnessAudit audit(7, 0, kFrames, &referee);
  audit.OnTraced(1, "honest", 3);
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
  audit.OnTraced(6, "liar", 0);
  audit.OnWorkerDistrusted("liar", "liar");
  EXPECT_TRUE(audit.TakeFramesToRepair([](int) { return false; }).empty());
  EXPECT_TRUE(audit.Pending());
  EXPECT_EQ(Repairs(audit), std::vector<int>{6});
  EXPECT_TRUE(Repairs(audit).empty());  // in repair already
  audit.OnRepaired(6, "second", 16);
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
