// Coordinator capacity: how many tasks and pixel results per second the coordinator's
// loop sustains on one core, with synthetic workers that answer at once without tracing.
// The loop does what it does in production: the Search planner plans, the dispatcher
// sends TASKs and decodes RESULTs, the planner copies pixels and assembles frames
// (frames are dropped instead of written: the frame store has its own threads).
//   build/coordinator/dispatch_bench [--workers 4] [--frames 40] [--bin-width 2]
//                                    [--width 1920] [--height 1080] [--task-pixels 65536]
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "coordinator/dispatch/dispatcher.h"
#include "coordinator/planner/search_planner.h"
#include "proto/wire/zmq_io.h"

namespace tcfarm {
namespace {

const std::string kHash(64, 'c');

// A worker that answers every task with zeros of the right size, as fast as it can.
void SyntheticWorker(zmq::context_t& context, const std::string& endpoint,
                     const std::atomic<bool>& stop) {
  zmq::socket_t socket(context, zmq::socket_type::dealer);
  socket.set(zmq::sockopt::linger, 0);
  socket.connect(endpoint);
  wire::SendMessage(socket, wire::Ready{8, 1, "synthetic"});
  wire::Result result;
  while (!stop) {
    zmq::pollitem_t item{static_cast<void*>(socket), 0, ZMQ_POLLIN, 0};
    zmq::poll(&item, 1, std::chrono::milliseconds(20));
    while (auto parts = wire::ReceiveParts(socket)) {
      wire::Message message = wire::Decode(*parts);
      auto* task = std::get_if<wire::Task>(&message);
      if (!task) continue;
      result.taskId = task->taskId;
      result.jobId = task->jobId;
      result.frame = task->frame;
      result.rgb.assign(task->pixels.size() * 3, 0.0f);
      wire::SendMessage(socket, result);
    }
  }
}

class PlannerSink : public DispatchSink {
 public:
  explicit PlannerSink(SearchPlanner& planner) : planner_(planner) {}
  void OnResult(const DispatchTask& task, wire::Result&& result, double, const WorkerState&) override {
    planner_.OnResult(task.plannerTaskId, result.rgb.data(), result.rgb.size());
    pixels += result.PixelCount();
    ++tasks;
  }
  void OnTaskFailed(uint64_t, uint64_t, const std::string&) override {}
  uint64_t pixels = 0, tasks = 0;

 private:
  SearchPlanner& planner_;
};

int Flag(int argc, char** argv, const char* name, int fallback) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::string(argv[i]) == name) return std::atoi(argv[i + 1]);
  }
  return fallback;
}

}  // namespace
}  // namespace tcfarm

int main(int argc, char** argv) {
  using namespace tcfarm;
  const int workers = Flag(argc, argv, "--workers", 4);
  PlannerOptions options;
  options.width = Flag(argc, argv, "--width", 1920);
  options.height = Flag(argc, argv, "--height", 1080);
  options.frameCount = Flag(argc, argv, "--frames", 40);
  options.binWidth = Flag(argc, argv, "--bin-width", 2);
  options.maxTaskPixels = static_cast<uint32_t>(Flag(argc, argv, "--task-pixels", 65536));
  SearchPlanner planner(options);
  PlannerSink sink(planner);

  SystemClock clock;
  Dispatcher dispatcher("tcp://127.0.0.1:*", clock);
  dispatcher.AddJob(1, 0, options.width, options.height, kHash, "{}");
  std::atomic<bool> stop{false};
  zmq::context_t context;
  std::vector<std::thread> threads;
  for (int i = 0; i < workers; ++i) {
    threads.emplace_back(SyntheticWorker, std::ref(context), dispatcher.BoundEndpoint(),
                         std::cref(stop));
  }

  auto start = std::chrono::steady_clock::now();
  std::clock_t cpuStart = std::clock();
  uint64_t frames = 0;
  while (!planner.Done()) {
    for (TraceTask& t : planner.TakeReadyTasks()) {
      dispatcher.Enqueue({1, t.id, t.frame, std::move(t.pixels), 0, {}});
    }
    dispatcher.Poll(Milliseconds(1), sink);
    frames += planner.TakeFinishedFrames().size();
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  double cpuSeconds = double(std::clock() - cpuStart) / CLOCKS_PER_SEC;
  stop = true;
  for (auto& t : threads) t.join();

  std::printf("%d synthetic workers, %dx%d, %d frames, bin width %d, %u pixels per task\n",
              workers, options.width, options.height, options.frameCount, options.binWidth,
              options.maxTaskPixels);
  std::printf("coordinator loop: %.0f tasks/s, %.1f M pixel results/s, %.1f M output pixels/s "
              "(%llu tasks, %.2f s wall; process CPU %.2f s incl. workers)\n",
              sink.tasks / seconds, sink.pixels / seconds / 1e6,
              double(frames) * options.width * options.height / seconds / 1e6,
              static_cast<unsigned long long>(sink.tasks), seconds, cpuSeconds);
  return 0;
}
