#include "tests/batch/batch_test_util.h"

#include "batch/atomic_file.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace lifmcr::batch::test {

namespace fs = std::filesystem;

void SynthSmallRig(const fs::path& dir, int frames) {
  const int code =
      Run({lifmcr::test::LifmcrBinary().string(), "synth", "--out", dir.string(), "--preset",
           "small", "--cameras", "2", "--frames", std::to_string(frames), "--quiet"});
  ASSERT_EQ(code, 0) << "lifmcr synth failed";
}

pid_t Spawn(const std::vector<std::string>& argv, const fs::path& log, bool own_group) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (own_group) ::setpgid(0, 0);
    if (!log.empty()) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
    }
    const int null_fd = ::open("/dev/null", O_RDONLY);
    if (null_fd >= 0) ::dup2(null_fd, 0);
    ::execvp(args[0], args.data());
    _exit(127);
  }
  if (own_group && pid > 0) ::setpgid(pid, pid);  // both sides: no race with a kill(-pid)
  return pid;
}

int Wait(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return -1;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

int Run(const std::vector<std::string>& argv, const fs::path& log) {
  return Wait(Spawn(argv, log, false));
}

bool WaitUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return done();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

std::map<std::string, std::string> ReadTree(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file())
      files[fs::relative(e.path(), dir).string()] = lifmcr::test::ReadFile(e.path());
  return files;
}

std::map<std::string, ManifestEntry> Entries(const fs::path& plan_dir) {
  std::map<std::string, ManifestEntry> entries;
  Expected<Plan> plan = ReadPlan(plan_dir);
  EXPECT_TRUE(plan) << plan.error().message;
  if (!plan) return entries;
  for (const Unit& u : plan->units) {
    Expected<std::optional<ManifestEntry>> e = ReadManifestEntry(plan_dir, u.id);
    EXPECT_TRUE(e && *e) << "unit " << u.id << ": "
                         << (e ? "no manifest entry" : e.error().message);
    if (e && *e) entries[u.id] = **e;
  }
  return entries;
}

}  // namespace lifmcr::batch::test

namespace lifmcr::batch::test {

Captured Capture(const std::string& command_line) {
  Captured c;
  std::FILE* pipe = ::popen(command_line.c_str(), "r");
  if (!pipe) return c;
  char block[4096];
  std::size_t n;
  while ((n = std::fread(block, 1, sizeof block, pipe)) > 0) c.out.append(block, n);
  const int status = ::pclose(pipe);
  c.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return c;
}

std::string FindProgram(const std::string& name) {
  std::vector<std::string> dirs;
  if (const char* path = std::getenv("PATH")) {
    std::string p = path;
    for (std::size_t start = 0; start <= p.size();) {
      const std::size_t end = std::min(p.find(':', start), p.size());
      dirs.push_back(p.substr(start, end - start));
      start = end + 1;
    }
  }
  dirs.push_back("/usr/sbin");
  dirs.push_back("/usr/bin");
  for (const std::string& d : dirs) {
    const fs::path candidate = fs::path(d) / name;
    if (!d.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

}  // namespace lifmcr::batch::test
