#include "coordinator/farm/local_workers.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace tcfarm {
namespace {

// Time a worker gets to finish its current task and say DISCONNECT.
constexpr auto kStopGrace = std::chrono::seconds(3);

// The file execve runs: the binary itself when its name has a folder in it, else the first
// executable of that name in a PATH folder. Looked up before fork, since the child of a
// threaded process may only make async-signal-safe calls until it execs.
std::string ResolveExecutable(const std::string& binary) {
  if (binary.find('/') != std::string::npos) return binary;
  const char* path = std::getenv("PATH");
  std::string folders = path ? path : "/usr/local/bin:/usr/bin:/bin";
  for (size_t begin = 0; begin <= folders.size();) {
    size_t end = folders.find(':', begin);
    if (end == std::string::npos) end = folders.size();
    const std::string folder = end == begin ? "." : folders.substr(begin, end - begin);
    const std::string candidate = folder + "/" + binary;
    std::error_code ec;
    if (std::filesystem::is_regular_file(candidate, ec) && access(candidate.c_str(), X_OK) == 0) return candidate;
    begin = end + 1;
  }
  throw std::runtime_error("cannot start worker " + binary + ": no executable of that name on PATH");
}

// In the forked child. The worker is killed when the coordinator dies, however it dies
// (SIGKILL included): an orphan would go on taking tasks from whichever coordinator next
// listens on the endpoint. SIGKILL rather than SIGTERM: a worker given SIGTERM first
// finishes its task, whose result nobody would receive. If the coordinator died before
// prctl, the child was already reparented and exits here. An exec failure's errno goes
// back through errorFd (closed on exec, so the parent reads nothing when exec succeeds).
[[noreturn]] void ExecWorker(const char* file, char* const argv[], pid_t coordinator, int errorFd) {
  if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != coordinator) _exit(127);
  execve(file, argv, environ);
  const int error = errno;
  [[maybe_unused]] ssize_t written = write(errorFd, &error, sizeof error);
  _exit(127);
}

// The errno the child sent before it exited instead of exec'ing; 0 once it exec'ed.
int ReadExecError(int fd) {
  int error = 0;
  ssize_t got = 0;
  do {
    got = read(fd, &error, sizeof error);
  } while (got < 0 && errno == EINTR);
  return got == static_cast<ssize_t>(sizeof error) ? error : 0;
}

// Starts the worker in a child process that dies with this one (ExecWorker); throws when
// it cannot be started, with the reason.
pid_t ForkWorker(const std::string& file, char* const argv[]) {
  int errorPipe[2];
  if (pipe2(errorPipe, O_CLOEXEC) != 0) {
    throw std::runtime_error("cannot start worker " + file + ": " + std::strerror(errno));
  }
  const pid_t coordinator = getpid();
  const pid_t pid = fork();
  if (pid == 0) ExecWorker(file.c_str(), argv, coordinator, errorPipe[1]);
  const int forkError = errno;
  close(errorPipe[1]);
  const int execError = pid > 0 ? ReadExecError(errorPipe[0]) : 0;
  close(errorPipe[0]);
  if (pid < 0) throw std::runtime_error("cannot start worker " + file + ": " + std::strerror(forkError));
  if (execError != 0) {
    waitpid(pid, nullptr, 0);
    throw std::runtime_error("cannot start worker " + file + ": " + std::strerror(execError));
  }
  return pid;
}

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
                           unsigned threadsEach, ArgumentsFor extraArguments)
    : binary_(std::move(binary)), endpoint_(std::move(coordinatorEndpoint)),
      threadsEach_(threadsEach), extraArguments_(std::move(extraArguments)) {}

LocalWorkers::~LocalWorkers() { Stop(); }

pid_t LocalWorkers::Spawn(unsigned index) const {
  std::vector<std::string> args = {binary_,    "serve",  "--coordinator", endpoint_,
                                   "--threads", std::to_string(threadsEach_),
                                   "--name",   "local-" + std::to_string(index)};
  if (extraArguments_) {
    const std::vector<std::string> extra = extraArguments_(index);
    args.insert(args.end(), extra.begin(), extra.end());
  }
  std::vector<char*> argv;
  for (auto& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  return ForkWorker(ResolveExecutable(binary_), argv.data());
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
