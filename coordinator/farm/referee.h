// The coordinator's own tracer: the one party every job trusts. When a check of a job
// that promises exactness disagrees with the job, two workers returned different bits
// for the same pixels and neither can be believed over the other (farm/dispute.h). The
// referee traces those pixels itself, with the tracer the workers run and the scene and
// texture bytes the workers were sent, so its values are the bits an honest worker
// returns.
//
// Disputes are small (kMaxDisputedPixels), and checks and the unseen sample a small share
// of a job's pixels (farm/referee_sample.h), so the referee builds a scene only when a
// question on it arrives, keeps the last one it built (taking questions on it first), and
// traces on its own threads: a scene build never stalls the farm loop.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <chrono>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace tcfarm {

class ImportBudget;

// Settles disputes: the pixels' true values. The farm's is a TracingReferee.
//
// It also traces the checks that no connected worker may trace (a check is never done by
// the worker whose values it checks): on a one-worker farm, every check of a job.
class Referee {
 public:
  // Why a question is asked (a dispute, a check no worker may trace, the unseen sample);
  // each asker takes only the answers to its own.
  enum class Purpose { kDispute, kCheck, kSample };
  struct Question {
    uint64_t jobId = 0;
    uint64_t id = 0;  // the asker's, returned with the answer
    std::string sceneHash;
    std::string sceneJson;
    int frame = 0;  // the scene's numbering
    std::vector<uint32_t> pixels;
    Purpose purpose = Purpose::kDispute;
  };
  struct Answer {
    uint64_t id = 0;
    std::vector<float> rgb;  // 3 per pixel, in the question's order; empty on error
    std::string error;       // why the pixels could not be traced (a scene that no longer builds)
    double seconds = 0;      // tracing time, scene build excluded
    double cpuSeconds = 0;   // CPU time of the tracing threads, summed
  };

  // How the farm names the referee where it names who traced or checked pixels: no
  // worker's principal (dispatch/dispatcher.h PrincipalOf) can be this.
  static constexpr const char* kName = "referee";

  virtual ~Referee() = default;
  virtual void Ask(Question question) = 0;
  // Answers for the job's questions of that purpose that are ready; never waits.
  virtual std::vector<Answer> TakeAnswers(uint64_t jobId, Purpose purpose = Purpose::kDispute) = 0;
};

class TracingReferee : public Referee {
 public:
  // assetRoot: the store's assets (STORE/assets), where the scene's textures are by hash.
  // importBudget: the coordinator's one budget for importing scenes (none: unbounded); the
  // scene the referee keeps built holds its share of it.
  explicit TracingReferee(std::filesystem::path assetRoot, std::shared_ptr<ImportBudget> importBudget = nullptr);
  ~TracingReferee() override;
  TracingReferee(const TracingReferee&) = delete;
  TracingReferee& operator=(const TracingReferee&) = delete;

  void Ask(Question question) override;
  std::vector<Answer> TakeAnswers(uint64_t jobId, Purpose purpose = Purpose::kDispute) override;

 private:
  class Tracing;  // Embree and the scene it last built; lives on the referee's thread
  void Serve();
  // The question to trace next (under mutex_, questions_ not empty).
  Question TakeNextQuestion();
  static constexpr int kSameSceneRun = 64;
  // nullopt while the import budget has no room for the question's scene.
  std::optional<Answer> Trace(const Question& question);
  static constexpr std::chrono::milliseconds kBusyPause{250};

  std::filesystem::path assetRoot_;
  std::shared_ptr<ImportBudget> importBudget_;
  std::unique_ptr<Tracing> tracing_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Question> questions_;
  std::string lastSceneHash_;  // of the question traced last
  int sameSceneRun_ = 0;       // questions on it traced in a row
  std::map<std::pair<uint64_t, Purpose>, std::vector<Answer>> answers_;  // by job and purpose
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace tcfarm
