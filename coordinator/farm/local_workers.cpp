#include "farm/local_workers.h"

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace tcfarm {
namespace {

// Time a worker gets to finish its current task and say DISCONNECT.
constexpr auto kStopGrace = std::chrono::seconds(3);

}  // namespace

std::string FindWorkerBinary() {
  std::error_code ec;
  std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    for (auto candidate : {self.parent_path() / "tcfarm-worker",
                           self.parent_path().parent_path() / "worker" / "tcfarm-worker"}) {
      if (std::filesystem::exists(candidate)) return candidate.string();
    }
  }
  return "tcfarm-worker";
}

LocalWorkers::LocalWorkers(std::string binary, std::string coordinatorEndpoint,
                           unsigned threadsEach, std::vector<std::string> extraArguments)
    : binary_(std::move(binary)), endpoint_(std::move(coordinatorEndpoint)),
      threadsEach_(threadsEach), extraArguments_(std::move(extraArguments)) {}

LocalWorkers::~LocalWorkers() { Stop(); }

pid_t LocalWorkers::Spawn(unsigned index) const {
  std::vector<std::string> args = {binary_,    "serve",  "--coordinator", endpoint_,
                                   "--threads", std::to_string(threadsEach_),
                                   "--name",   "local-" + std::to_string(index)};
  args.insert(args.end(), extraArguments_.begin(), extraArguments_.end());
  std::vector<char*> argv;
  for (auto& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  int error = posix_spawnp(&pid, binary_.c_str(), nullptr, nullptr, argv.data(), environ);
  if (error != 0) {
    throw std::runtime_error("cannot start worker " + binary_ + ": " + std::strerror(error));
  }
  return pid;
}

void LocalWorkers::Start(unsigned count) {
  for (unsigned i = 0; i < count; ++i) pids_.push_back(Spawn(i));
}

int LocalWorkers::RestartExited() {
  int restarted = 0;
  for (size_t i = 0; i < pids_.size(); ++i) {
    int status = 0;
    if (pids_[i] > 0 && waitpid(pids_[i], &status, WNOHANG) == pids_[i]) {
      std::fprintf(stderr, "coordinator: local worker %zu exited (status %d); restarting\n", i,
                   status);
      pids_[i] = Spawn(static_cast<unsigned>(i));
      ++restarted;
    }
  }
  return restarted;
}

void LocalWorkers::Stop() {
  for (pid_t pid : pids_) kill(pid, SIGTERM);
  auto deadline = std::chrono::steady_clock::now() + kStopGrace;
  for (pid_t pid : pids_) {
    int status = 0;
    while (waitpid(pid, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  pids_.clear();
}

}  // namespace tcfarm
