#include "coordinator/farm/referee.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <optional>

#include "worker/tracing.h"
#include "proto/scene/import/import_budget.h"
#include "proto/scene/scene.h"

namespace tcfarm {

// Built on the first question (every job's unseen sample asks some): a coordinator with no
// job never starts Embree.
class TracingReferee::Tracing {
 public:
  // Throws ImportBudgetBusyError while the farm's import budget has no room for the scene.
  Tracer& TracerFor(const std::string& hash, const std::string& sceneJson, const std::filesystem::path& assetRoot,
                    ImportBudget* budget) {
    if (tracer_ && hash == hash_) return *tracer_;
    tracer_.reset();
    scene_.reset();
    reservation_ = ImportReservation();
    // The scene is held for as long as it is the last one built: so is its memory, from the
    // budget every import on the coordinator shares.
    if (budget) reservation_ = budget->Reserve(sceneJson.size());
    {
      const ImportMemoryScope scope(reservation_);
      scene_ = std::make_unique<Scene>(ParseScene(sceneJson));
    }
    // Textures are named by hash at submit; the store holds every one a job's scene names.
    for (Material& material : scene_->materials) {
      material.ForEachTexture([&](Texture& texture, const std::string&) {
        if (!texture.asset.empty()) texture.file = assetRoot / texture.asset;
      });
    }
    PrepareForTracing(*scene_);  // as the workers do: the same bits
    tracer_ = std::make_unique<Tracer>(device_, *scene_, threads_);
    hash_ = hash;
    return *tracer_;
  }

 private:
  EmbreeDevice device_;
  // A check can be a whole reference frame: every core, as a worker would use. The farm
  // loop's own work is short and waits on its socket most of the time.
  TracingThreads threads_{std::max(1u, std::thread::hardware_concurrency())};
  std::string hash_;
  ImportReservation reservation_;  // declared before the scene: given back after it is freed
  std::unique_ptr<Scene> scene_;
  std::unique_ptr<Tracer> tracer_;  // refers to scene_
};

TracingReferee::TracingReferee(std::filesystem::path assetRoot, std::shared_ptr<ImportBudget> importBudget)
    : assetRoot_(std::move(assetRoot)), importBudget_(std::move(importBudget)), thread_([this] { Serve(); }) {}

TracingReferee::~TracingReferee() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void TracingReferee::Ask(Question question) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    questions_.push_back(std::move(question));
  }
  wake_.notify_all();
}

std::vector<Referee::Answer> TracingReferee::TakeAnswers(uint64_t jobId, Purpose purpose) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto found = answers_.find({jobId, purpose});
  if (found == answers_.end()) return {};
  std::vector<Answer> answers = std::move(found->second);
  answers_.erase(found);
  return answers;
}

void TracingReferee::Serve() {
  for (;;) {
    Question question;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !questions_.empty(); });
      if (stopping_) return;
      question = TakeNextQuestion();
    }
    std::optional<Answer> answer = Trace(question);
    std::unique_lock<std::mutex> lock(mutex_);
    if (!answer) {
      // No room in the import budget for its scene: asked again after the others, and
      // after a pause, so that the imports holding the room can finish.
      questions_.push_back(std::move(question));
      wake_.wait_for(lock, kBusyPause, [this] { return stopping_; });
      continue;
    }
    answers_[{question.jobId, question.purpose}].push_back(std::move(*answer));
  }
}

Referee::Question TracingReferee::TakeNextQuestion() {
  // Jobs of different scenes ask at once (every job has its unseen sample), and a build
  // can take seconds: questions on the scene built last go first, up to kSameSceneRun in a
  // row, so that no job's questions wait for ever behind another's.
  auto next = questions_.begin();
  if (sameSceneRun_ < kSameSceneRun) {
    next = std::find_if(questions_.begin(), questions_.end(),
                        [&](const Question& q) { return q.sceneHash == lastSceneHash_; });
    if (next == questions_.end()) next = questions_.begin();
  }
  sameSceneRun_ = next->sceneHash == lastSceneHash_ ? sameSceneRun_ + 1 : 0;
  lastSceneHash_ = next->sceneHash;
  Question question = std::move(*next);
  questions_.erase(next);
  return question;
}

std::optional<Referee::Answer> TracingReferee::Trace(const Question& question) {
  Answer answer;
  answer.id = question.id;
  try {
    if (!tracing_) tracing_ = std::make_unique<Tracing>();
    Tracer& tracer = tracing_->TracerFor(question.sceneHash, question.sceneJson, assetRoot_, importBudget_.get());
    answer.rgb.resize(3 * question.pixels.size());
    const double cpuBefore = tracer.CpuSeconds();
    const auto started = std::chrono::steady_clock::now();
    tracer.TracePixels(question.frame, question.pixels.data(), question.pixels.size(), answer.rgb.data());
    answer.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    answer.cpuSeconds = tracer.CpuSeconds() - cpuBefore;
  } catch (const ImportBudgetBusyError&) {
    tracing_.reset();
    return std::nullopt;
  } catch (const std::exception& e) {
    answer.rgb.clear();
    answer.error = e.what();
    tracing_.reset();  // a failed build leaves nothing half made behind
  }
  return answer;
}

}  // namespace tcfarm
