#include "coordinator/farm/verification.h"

#include "coordinator/farm/referee.h"

#include <gtest/gtest.h>

#include <set>

namespace tcfarm {
namespace {

constexpr int kWidth = 40, kHeight = 30;
constexpr size_t kPixels = kWidth * kHeight;

// A frame whose pixel p is p / 1000 in every channel, with every tenth pixel traced.
std::pair<std::vector<float>, std::vector<uint8_t>> Frame() {
  std::vector<float> rgb(kPixels * 3);
  std::vector<uint8_t> traced(kPixels);
  for (size_t p = 0; p < kPixels; ++p) {
    rgb[3 * p] = rgb[3 * p + 1] = rgb[3 * p + 2] = p / 1000.0f;
    traced[p] = p % 10 == 0;
  }
  return {rgb, traced};
}

// Answers every request with the true frame, except pixels in `wrong`.
void Answer(Verification& verification, const std::set<uint32_t>& wrong = {}) {
  auto [truth, traced] = Frame();
  for (const auto& request : verification.TakeRequests()) {
    std::vector<float> rgb;
    request.pixels.ForEach([&](uint32_t p) {
      float v = wrong.count(p) ? -1.0f : truth[3 * p];
      rgb.insert(rgb.end(), {v, v, v});
    });
    EXPECT_TRUE(verification.OnResult(request.id, rgb.data(), rgb.size()));
  }
}

TEST(VerificationTest, FramesToVerifySpreadEvenly) {
  EXPECT_EQ(FramesToVerify(60, true, 0).size(), 60u);
  EXPECT_EQ(FramesToVerify(60, false, 3), (std::vector<int>{0, 30, 59}));
  EXPECT_EQ(FramesToVerify(60, false, 1), (std::vector<int>{30}));
  EXPECT_TRUE(FramesToVerify(60, false, 0).empty());
  EXPECT_EQ(FramesToVerify(5, false, 50).size(), 5u);
}

TEST(VerificationTest, SpotChecksStayWithinTwoPercentAndFindNothingWhenCopiesAreRight) {
  VerificationOptions options{{}, 0.5 /* clamped to 2 % */, 1};
  Verification verification(kWidth, kHeight, 4, options);
  for (int frame = 0; frame < 4; ++frame) {
    auto [rgb, traced] = Frame();
    verification.OnFrameFinished(frame, rgb, traced);
  }
  EXPECT_TRUE(verification.Pending());
  EXPECT_LE(verification.ExtraPixels(), static_cast<uint64_t>(0.02 * kPixels * 4) + 4);
  EXPECT_GT(verification.ExtraPixels(), 0u);
  Answer(verification);
  EXPECT_FALSE(verification.Pending());
  auto report = verification.Report()["spot_checks"];
  EXPECT_EQ(report["mismatches"], 0);
  EXPECT_EQ(report["estimated_error_percent"], 0.0);
  EXPECT_GT(report["ci95_percent"][1].get<double>(), 0.0);  // zero seen is not zero proven
}

TEST(VerificationTest, SpotChecksEstimateTheShareOfWrongCopies) {
  // Every copied pixel wrong: the estimate is the copied share, 90 %.
  Verification verification(kWidth, kHeight, 1, {{}, 0.02, 3});
  auto [rgb, traced] = Frame();
  verification.OnFrameFinished(0, rgb, traced);
  std::set<uint32_t> all;
  for (uint32_t p = 0; p < kPixels; ++p) all.insert(p);
  Answer(verification, all);
  auto report = verification.Report()["spot_checks"];
  EXPECT_EQ(report["mismatches"], report["pixels_checked"]);
  EXPECT_NEAR(report["estimated_error_percent"].get<double>(), 90.0, 1e-9);
  EXPECT_LE(report["ci95_percent"][0].get<double>(), 90.0);
}

TEST(VerificationTest, ReferenceFramesAreComparedInFull) {
  Verification verification(kWidth, kHeight, 3, {{1}, 0.01, 1});
  for (int frame = 0; frame < 3; ++frame) {
    auto [rgb, traced] = Frame();
    verification.OnFrameFinished(frame, rgb, traced);
  }
  Answer(verification, {5, 6, 7});  // the reference differs from the job's frame in 3 pixels
  auto reference = verification.Report()["reference"];
  EXPECT_EQ(reference["frames_compared"], 1);
  EXPECT_EQ(reference["pixels_differing"], 3);
  EXPECT_LT(reference["ssim"].get<double>(), 1.0);
  EXPECT_FALSE(verification.OnResult(12345, nullptr, 0));
  EXPECT_THROW(Verification(kWidth, kHeight, 3, {{7}, 0.01, 1}), std::invalid_argument);
}

}  // namespace
}  // namespace tcfarm

namespace tcfarm {
namespace {

// exact and brute promise 0 wrong pixels: a spot check or a reference that disagrees marks
// the job suspect, naming the frames; a strategy that allows error is only measured.
TEST(VerificationTest, ADisagreementMarksAJobThatPromisesExactnessSuspect) {
  for (const bool promisesExact : {true, false}) {
    VerificationOptions options;
    options.spotCheckShare = 0.02;
    options.referenceFrames = {1};
    options.promisesExact = promisesExact;
    Verification verification(kWidth, kHeight, 2, options);
    auto [rgb, traced] = Frame();
    verification.OnFrameFinished(0, rgb, traced);
    verification.OnFrameFinished(1, rgb, traced);
    std::set<uint32_t> wrong;
    for (uint32_t p = 0; p < kPixels; ++p) wrong.insert(p);  // a worker that lies everywhere
    Answer(verification, wrong);
    const nlohmann::json report = verification.Report();
    EXPECT_EQ(verification.Suspect(), promisesExact);
    EXPECT_EQ(report.contains("suspect"), promisesExact) << report.dump();
    if (!promisesExact) continue;
    EXPECT_EQ(report["suspect"]["frames"]["1"], kPixels);  // the reference differs everywhere
    EXPECT_EQ(report["suspect"]["frames"]["0"], report["spot_checks"]["mismatches"].get<uint64_t>());
  }
}

// Spot checks sample copies alone (traced values are the referee sample's): a copy that
// disagrees is disputed where the strategy promises exactness, and is only measured where
// it is the strategy's approximation. The report says who traced the checks.
TEST(VerificationTest, SpotChecksSampleCopiesAndDisputeThemOnlyWhereExactnessIsPromised) {
  for (const bool promisesExact : {true, false}) {
    VerificationOptions options;
    options.promisesExact = promisesExact;
    Verification verification(kWidth, kHeight, 1, options);
    const auto frame = Frame();
    const std::vector<float>& rgb = frame.first;
    const std::vector<uint8_t>& traced = frame.second;
    verification.OnFrameFinished(0, rgb, traced);
    const std::vector<Verification::Request> requests = verification.TakeRequests();
    ASSERT_FALSE(requests.empty());
    for (const Verification::Request& request : requests) {
      request.pixels.ForEach([&](uint32_t p) { EXPECT_FALSE(traced[p]) << p; });
      std::vector<float> values;
      request.pixels.ForEach([&](uint32_t p) { values.insert(values.end(), 3, rgb[3 * p] + 1.0f); });
      EXPECT_TRUE(verification.OnResult(request.id, values.data(), values.size(), Referee::kName));
    }
    const std::vector<Dispute> disputes = verification.TakeDisputes();
    EXPECT_EQ(disputes.size(), promisesExact ? 1u : 0u);
    const nlohmann::json report = verification.Report();
    EXPECT_GT(report["spot_checks"]["mismatches"].get<uint64_t>(), 0u);
    EXPECT_FALSE(report.contains("trace_checks")) << report.dump();
    EXPECT_EQ(report["checked_by"]["referee_pixels"], verification.ExtraPixels());
    EXPECT_EQ(report["checked_by"]["worker_pixels"], 0);
  }
}

// Values the referee's unseen sample found wrong make a job that promises exactness
// suspect, as a check that disagreed would; for search they are only repaired.
TEST(VerificationTest, WrongValuesTheSampleFoundMakeAnExactJobSuspect) {
  for (const bool promisesExact : {true, false}) {
    VerificationOptions options;
    options.promisesExact = promisesExact;
    Verification verification(kWidth, kHeight, 3, options);
    verification.OnWrongValues(2, 5);
    verification.OnWrongValues(1, 0);
    EXPECT_EQ(verification.Suspect(), promisesExact);
    if (!promisesExact) continue;
    const nlohmann::json suspect = verification.Report()["suspect"];
    EXPECT_EQ(suspect["pixels_disagreeing"], 5);
    EXPECT_EQ(suspect["frames"], nlohmann::json({{"2", 5}}));
  }
}

// A reference traced by a worker later found wrong says nothing: it is forgotten, and the
// frame is compared again with a reference traced anew. A frame rewritten by a repair is
// compared as it shows now.
TEST(VerificationTest, AReferenceByAWorkerFoundWrongIsTracedAgain) {
  VerificationOptions options;
  options.spotCheckShare = 0;
  options.referenceFrames = {0};
  Verification verification(kWidth, kHeight, 1, options);
  const auto frame = Frame();
  verification.OnFrameFinished(0, frame.first, frame.second);
  std::vector<Verification::Request> requests = verification.TakeRequests();
  ASSERT_EQ(requests.size(), 1u);
  const std::vector<float> grey(3 * kPixels, 7.0f);  // no pixel of Frame() is 7
  ASSERT_TRUE(verification.OnResult(requests[0].id, grey.data(), grey.size(), "liar"));
  EXPECT_GT(verification.Report()["reference"]["pixels_differing"].get<uint64_t>(), 0u);
  EXPECT_TRUE(verification.ForgetReferencesBy("honest").empty());
  EXPECT_EQ(verification.ForgetReferencesBy("liar"), std::vector<int>{0});
  EXPECT_EQ(verification.Report()["reference"]["frames_compared"], 0);
  verification.Reverify(0, frame.first);
  requests = verification.TakeRequests();
  ASSERT_EQ(requests.size(), 1u);
  ASSERT_TRUE(verification.OnResult(requests[0].id, frame.first.data(), frame.first.size(), "honest"));
  EXPECT_EQ(verification.Report()["reference"]["frames_compared"], 1);
  EXPECT_EQ(verification.Report()["reference"]["pixels_differing"], 0);
  // A repair rewrote the frame with other values: it is compared again, as it shows now.
  verification.Reverify(0, grey);
  requests = verification.TakeRequests();
  ASSERT_EQ(requests.size(), 1u);
  ASSERT_TRUE(verification.OnResult(requests[0].id, frame.first.data(), frame.first.size(), "honest"));
  EXPECT_EQ(verification.Report()["reference"]["pixels_differing"], kPixels);
  // A frame with no reference asked for is left alone.
  Verification none(kWidth, kHeight, 2, VerificationOptions{});
  none.Reverify(1, grey);
  EXPECT_TRUE(none.TakeRequests().empty());
}

// A spot check the referee cannot trace is given up: the job is no longer waiting for it,
// and the report says how many pixels went unchecked and why.
TEST(VerificationTest, AnAbandonedSpotCheckIsReportedAndNotWaitedFor) {
  Verification verification(kWidth, kHeight, 1, VerificationOptions{});
  const auto frame = Frame();
  verification.OnFrameFinished(0, frame.first, frame.second);
  const std::vector<Verification::Request> requests = verification.TakeRequests();
  ASSERT_EQ(requests.size(), 1u);
  EXPECT_TRUE(verification.Pending());
  verification.Abandon(requests[0].id, "the scene no longer builds");
  verification.Abandon(12345, "unknown: ignored");
  EXPECT_FALSE(verification.Pending());
  const nlohmann::json spot = verification.Report()["spot_checks"];
  EXPECT_EQ(spot["pixels_abandoned"], requests[0].pixels.size());
  EXPECT_EQ(spot["abandoned_why"], "the scene no longer builds");
  EXPECT_EQ(spot["pixels_checked"], 0);
}

TEST(VerificationTest, AJobWhoseChecksAgreeIsNotSuspect) {
  VerificationOptions options;
  options.referenceFrames = {0};
  options.promisesExact = true;
  Verification verification(kWidth, kHeight, 1, options);
  auto [rgb, traced] = Frame();
  verification.OnFrameFinished(0, rgb, traced);
  Answer(verification);
  EXPECT_FALSE(verification.Suspect());
  EXPECT_FALSE(verification.Report().contains("suspect"));
}

}  // namespace
}  // namespace tcfarm
