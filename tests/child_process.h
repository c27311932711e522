#pragma once
// A child process for end-to-end tests that run several `lifmcr` commands and
// stock tools side by side (a logger, a monitor, replays): started at
// construction, stdout and stderr into a log file, killed if still running
// at destruction.

#include "tests/test_util.h"

#include <chrono>
#include <csignal>
#include <fcntl.h>
#include <filesystem>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace lifmcr::test {

class Child {
 public:
  // `argv` run in network namespace `ns` (empty: this one).
  Child(const std::string& ns, std::vector<std::string> argv, const std::filesystem::path& log)
      : log_(log) {
    if (!ns.empty()) argv.insert(argv.begin(), {"ip", "netns", "exec", ns});
    pid_ = fork();
    if (pid_ == 0) {
      const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        dup2(fd, STDOUT_FILENO);
        dup2(fd, STDERR_FILENO);
      }
      std::vector<char*> args;
      for (std::string& arg : argv) args.push_back(arg.data());
      args.push_back(nullptr);
      execvp(args[0], args.data());
      _exit(127);
    }
  }
  ~Child() {
    if (pid_ > 0 && !exited_) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  // The exit code, or -1 when it did not end within `timeout` (then killed).
  int Wait(std::chrono::seconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return -1;
  }
  void Signal(int signal) {
    if (pid_ > 0 && !exited_) kill(pid_, signal);
  }
  std::string Log() const { return ReadFile(log_); }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  std::filesystem::path log_;
};

// `lifmcr ARGS...` as an argv for Child.
inline std::vector<std::string> LifmcrArgv(std::vector<std::string> args) {
  args.insert(args.begin(), LifmcrBinary().string());
  return args;
}

}  // namespace lifmcr::test
