#include "batch/runner.h"

#include "batch/atomic_file.h"
#include "batch/manifest.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace lifmcr::batch {

namespace fs = std::filesystem;

namespace {

// The signal handler's state: the command to pass a signal on to, and the
// first signal received. Lock-free atomics are async-signal-safe.
std::atomic<pid_t> g_child{0};
std::atomic<int> g_signal{0};

void OnTerminate(int sig) {
  int expected = 0;
  g_signal.compare_exchange_strong(expected, sig);
  const pid_t child = g_child.load();
  if (child > 0) ::kill(child, sig);
}

// Installs OnTerminate for the signals that stop a run, restores the old
// handlers when it goes.
class TerminateHandlers {
 public:
  TerminateHandlers() {
    g_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = OnTerminate;
    sigemptyset(&sa.sa_mask);
    for (int k = 0; k < 3; ++k) ::sigaction(kSignals[k], &sa, &old_[k]);
  }
  ~TerminateHandlers() {
    for (int k = 0; k < 3; ++k) ::sigaction(kSignals[k], &old_[k], nullptr);
  }
  TerminateHandlers(const TerminateHandlers&) = delete;
  TerminateHandlers& operator=(const TerminateHandlers&) = delete;

 private:
  static constexpr int kSignals[3] = {SIGTERM, SIGINT, SIGHUP};
  struct sigaction old_[3];
};

double SecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&now, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return text;
}

std::string HostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof name - 1) != 0) return "?";
  return name;
}

constexpr std::string_view kAttemptPrefix = "# lifmcr batch run: attempt ";

// Attempts recorded in a unit's log so far (each start writes one line).
int AttemptsInLog(const fs::path& log) {
  Expected<std::string> text = ReadWholeFile(log);
  if (!text) return 0;
  int count = 0;
  std::size_t pos = 0;
  while ((pos = text->find(kAttemptPrefix, pos)) != std::string::npos) {
    if (pos == 0 || (*text)[pos - 1] == '\n') ++count;
    pos += kAttemptPrefix.size();
  }
  return count;
}

// The last non-empty line the command wrote in this attempt (after `from`),
// at most 300 bytes: what a failure's message shows.
std::string LastLine(const fs::path& log, std::size_t from) {
  Expected<std::string> text = ReadWholeFile(log);
  if (!text || text->size() <= from) return "";
  std::string_view rest(*text);
  rest.remove_prefix(from);
  while (!rest.empty() && (rest.back() == '\n' || rest.back() == '\r' || rest.back() == ' '))
    rest.remove_suffix(1);
  const std::size_t nl = rest.rfind('\n');
  std::string line(nl == std::string_view::npos ? rest : rest.substr(nl + 1));
  if (line.size() > 300) line = line.substr(0, 300) + "...";
  return line;
}

struct ChildResult {
  int exit_code = -1;
  int signal = 0;
  std::int64_t peak_rss_kib = 0;
  double cpu_seconds = 0;  // user + system
  std::string spawn_error;
};

// Runs argv with `cwd` as working folder, stdout and stderr onto log_fd,
// stdin from /dev/null; returns how it ended.
ChildResult RunCommand(const fs::path& executable, const std::vector<std::string>& argv,
                       const fs::path& cwd, int log_fd) {
  ChildResult result;
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  // posix_spawn (glibc: clone with CLONE_VM | CLONE_VFORK) instead of fork:
  // the runner is a large process, and copying its page tables for every unit
  // is time of the unit spent on no work of its own.
  // The stop signals are blocked across the spawn: the parent must know the
  // child's pid before its handler runs (it unblocks once g_child is set, so
  // the handler passes on what came meanwhile); the child starts with them at
  // their default actions and the old mask, so one that came meanwhile ends it.
  sigset_t stop_signals, old_mask;
  sigemptyset(&stop_signals);
  for (int sig : {SIGTERM, SIGINT, SIGHUP}) sigaddset(&stop_signals, sig);
  ::sigprocmask(SIG_BLOCK, &stop_signals, &old_mask);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, log_fd, 1);
  posix_spawn_file_actions_adddup2(&actions, log_fd, 2);
  posix_spawn_file_actions_addchdir_np(&actions, cwd.c_str());
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setsigdefault(&attributes, &stop_signals);
  posix_spawnattr_setsigmask(&attributes, &old_mask);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  pid_t pid = 0;
  const int spawned =
      ::posix_spawn(&pid, executable.c_str(), &actions, &attributes, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attributes);
  if (spawned != 0) {
    ::sigprocmask(SIG_SETMASK, &old_mask, nullptr);
    result.spawn_error =
        "cannot run " + executable.string() + " in " + cwd.string() + ": " + std::strerror(spawned);
    return result;
  }
  g_child = pid;
  ::sigprocmask(SIG_SETMASK, &old_mask, nullptr);
  // A signal that came before the unit started (after the loop's check) was
  // not passed on by the handler: pass it now.
  if (const int sig = g_signal.load(); sig != 0) ::kill(pid, sig);
  int status = 0;
  struct rusage usage {};
  while (::wait4(pid, &status, 0, &usage) < 0) {
    if (errno != EINTR) {
      result.spawn_error = std::string("wait failed: ") + std::strerror(errno);
      g_child = 0;
      return result;
    }
  }
  g_child = 0;
  result.peak_rss_kib = usage.ru_maxrss;
  result.cpu_seconds = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                       static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
  if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) result.signal = WTERMSIG(status);
  return result;
}

}  // namespace

Status RunOptions::Check() const {
  if (plan_dir.empty()) return Error{"PLAN_DIR: expected a plan folder"};
  if (shard.count < 1 || shard.index < 0 || shard.index >= shard.count)
    return Error{"--shard " + shard.ToString() + ": expected I/N with 0 <= I < N"};
  if (executable.empty()) return Error{"executable: expected the lifmcr executable's path"};
  return Status::Ok();
}

std::string RunReport::BriefReport(const ShardSpec& shard) const {
  char text[256];
  std::snprintf(
      text, sizeof text,
      "shard %s: %d unit%s: %d done, %d skipped (done before), %d failed, %d busy in "
      "%.1f s (%.3f s of it outside the units' commands)%s",
      shard.ToString().c_str(), units, units == 1 ? "" : "s", done, skipped, failed, busy, seconds,
      runner_seconds,
      interrupted_by ? (", interrupted by signal " + std::to_string(interrupted_by)).c_str() : "");
  return text;
}

int RunReport::ExitCode() const {
  if (interrupted_by != 0) return 128 + interrupted_by;
  return failed > 0 || busy > 0 ? 1 : 0;
}

Expected<RunReport> RunShard(const RunOptions& o) {
  if (Status s = o.Check(); !s) return s.error();
  Expected<Plan> plan = ReadPlan(o.plan_dir);
  if (!plan) return plan.error();
  const fs::path plan_dir = o.plan_dir;
  const std::vector<std::size_t> mine = plan->ShardUnits(o.shard.index, o.shard.count);
  RunReport report;
  report.units = static_cast<int>(mine.size());
  const std::string host = HostName();
  const auto t_run = std::chrono::steady_clock::now();
  double ran_seconds = 0;
  bool lock_warned = false;
  TerminateHandlers handlers;
  auto say = [&](const char* format, auto... args) {
    if (!o.progress) return;
    std::fprintf(o.progress, format, args...);
    std::fflush(o.progress);
  };
  say("lifmcr batch run: %s, shard %s: %zu of its units\n", plan->BriefReport().c_str(),
      o.shard.ToString().c_str(), mine.size());
  for (std::size_t k = 0; k < mine.size(); ++k) {
    if (g_signal.load() != 0) break;
    const Unit& unit = plan->units[mine[k]];
    const std::string tag =
        "[" + std::to_string(k + 1) + "/" + std::to_string(mine.size()) + "] " + unit.id;

    // 1. The unit's lock, held (with the command, which inherits it) until its entry is written.
    const fs::path lock_path = plan_dir / "locks" / (unit.id + ".lock");
    std::error_code ec;
    fs::create_directories(lock_path.parent_path(), ec);
    const int lock_fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT, 0644);
    if (lock_fd < 0) return Error{lock_path.string() + ": cannot open: " + std::strerror(errno)};
    if (::flock(lock_fd, LOCK_EX | LOCK_NB) != 0) {
      if (errno == EWOULDBLOCK) {
        ::close(lock_fd);
        ++report.busy;
        say("%s: busy (another process runs it)\n", tag.c_str());
        continue;
      }
      // A file system without locks (an NFS mount without its lock service:
      // ENOLCK) must not stop the work: shards own disjoint units, so only a
      // shard run twice at once goes unguarded. Said once per run.
      if (!lock_warned) {
        lock_warned = true;
        say("lifmcr batch run: %s: flock failed (%s): units run without their lock; run each "
            "shard once at a time\n",
            lock_path.c_str(), std::strerror(errno));
      }
    }
    struct LockGuard {
      int fd;
      ~LockGuard() { ::close(fd); }
    } lock_guard{lock_fd};

    // 2. Done before and still what the manifest says?
    Expected<std::optional<ManifestEntry>> previous = ReadManifestEntry(plan_dir, unit.id);
    if (!previous) return previous.error();
    if (*previous && (*previous)->state == UnitState::kDone) {
      const Status verified = VerifyOutputs(plan_dir, unit, **previous);
      if (verified) {
        ++report.skipped;
        say("%s: skipped, done before (%zu outputs verified)\n", tag.c_str(),
            (*previous)->outputs.size());
        continue;
      }
      say("%s: done before, but %s: running it again\n", tag.c_str(),
          verified.error().message.c_str());
    }

    ManifestEntry entry;
    entry.unit = unit.id;
    entry.log = LogPathOf(unit.id);
    entry.host = host;
    entry.shard = o.shard.ToString();
    const fs::path log_path = plan_dir / entry.log;
    fs::create_directories(log_path.parent_path(), ec);
    entry.attempt = AttemptsInLog(log_path) + 1;

    // 3. The units of earlier plans it needs.
    std::string waiting;
    for (const UnitNeed& need : unit.needs) {
      Expected<std::optional<ManifestEntry>> e = ReadManifestEntry(need.plan, need.unit);
      if (!e) {
        waiting = e.error().message;
      } else if (!*e || (*e)->state != UnitState::kDone) {
        waiting = "needs unit " + need.unit + " of the plan " + need.plan + ", which is " +
                  (!*e ? std::string("not run yet") : "failed") + " (lifmcr batch status " +
                  need.plan + ")";
      }
      if (!waiting.empty()) break;
    }
    if (!waiting.empty()) {
      entry.state = UnitState::kFailed;
      entry.exit_code = -1;
      entry.message = waiting;
      entry.attempt -= 1;  // not started: no attempt line (AttemptsInLog counts those)
      entry.finished_utc = UtcNow();
      // The log the entry names says why, as a failed attempt's would.
      const std::string line =
          "# lifmcr batch run: not started, " + entry.finished_utc + ": " + waiting + "\n";
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
      if (fd >= 0) {
        [[maybe_unused]] ssize_t n = ::write(fd, line.data(), line.size());
        ::close(fd);
      }
      if (Status s = WriteManifestEntry(plan_dir, entry); !s) return s.error();
      ++report.failed;
      say("%s: not run: %s\n", tag.c_str(), waiting.c_str());
      continue;
    }

    // 4. Empty output folder, the log's attempt line, the command.
    const fs::path out_dir = plan_dir / unit.outputs;
    fs::remove_all(out_dir, ec);
    if (ec)
      return Error{out_dir.string() + ": cannot empty the unit's output folder: " + ec.message()};
    fs::create_directories(out_dir, ec);
    if (ec) return Error{out_dir.string() + ": cannot create: " + ec.message()};
    const int log_fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (log_fd < 0) return Error{log_path.string() + ": cannot open: " + std::strerror(errno)};
    const std::string header = std::string(kAttemptPrefix) + std::to_string(entry.attempt) +
                               " of unit " + unit.id + ", shard " + entry.shard + ", host " + host +
                               ", pid " + std::to_string(::getpid()) + ", " + UtcNow() + "\n# " +
                               unit.CommandLine() + "\n";
    [[maybe_unused]] ssize_t written = ::write(log_fd, header.data(), header.size());
    const off_t attempt_start = ::lseek(log_fd, 0, SEEK_END);
    say("%s: running (attempt %d)\n", tag.c_str(), entry.attempt);
    ++report.ran;
    const auto t_unit = std::chrono::steady_clock::now();
    const ChildResult child = RunCommand(o.executable, unit.command, plan_dir, log_fd);
    ::close(log_fd);
    entry.seconds = SecondsSince(t_unit);
    ran_seconds += entry.seconds;
    entry.exit_code = child.exit_code;
    entry.signal = child.signal;
    entry.peak_rss_kib = child.peak_rss_kib;
    entry.cpu_seconds = child.cpu_seconds;

    // 5. The entry.
    if (!child.spawn_error.empty()) {
      entry.message = child.spawn_error;
    } else if (child.signal == 0 && std::find(unit.done_exits.begin(), unit.done_exits.end(),
                                              child.exit_code) != unit.done_exits.end()) {
      // An exit code other than 0 that the plan counts as done (evaluate's 3)
      // keeps the command's last line as a note.
      if (child.exit_code != 0)
        entry.message = LastLine(log_path, static_cast<std::size_t>(attempt_start));
      std::string missing;
      for (const std::string& w : unit.writes)
        if (!fs::is_regular_file(plan_dir / w, ec)) {
          missing = w;
          break;
        }
      if (!missing.empty()) {
        entry.message =
            "exited " + std::to_string(child.exit_code) + " but did not write " + missing;
      } else {
        Expected<std::vector<OutputFile>> outputs = DigestOutputs(plan_dir, unit);
        if (!outputs)
          entry.message = outputs.error().message;
        else
          entry.outputs = std::move(*outputs), entry.state = UnitState::kDone;
      }
    } else {
      const std::string last = LastLine(log_path, static_cast<std::size_t>(attempt_start));
      const int sig = g_signal.load();
      if (sig != 0)
        entry.message = "interrupted by signal " + std::to_string(sig) + " (" + strsignal(sig) +
                        ": cancelled or preempted); lifmcr batch run runs it again";
      else if (child.signal != 0)
        entry.message = "killed by signal " + std::to_string(child.signal) + " (" +
                        strsignal(child.signal) + ")" +
                        (last.empty() ? "" : "; last line: " + last);
      else
        entry.message = last.empty() ? "exit code " + std::to_string(child.exit_code) : last;
    }
    entry.finished_utc = UtcNow();
    if (Status s = WriteManifestEntry(plan_dir, entry); !s) return s.error();
    if (entry.state == UnitState::kDone)
      ++report.done;
    else
      ++report.failed;

    const int executed = report.done + report.failed;
    const int left = static_cast<int>(mine.size()) - static_cast<int>(k) - 1;
    say("%s: %s | %d done, %d skipped, %d failed, %d left, ~%.0f s to go\n", tag.c_str(),
        entry.BriefReport().c_str(), report.done, report.skipped, report.failed, left,
        executed > 0 ? ran_seconds / executed * left : 0.0);
    if (g_signal.load() != 0) break;
  }
  report.interrupted_by = g_signal.load();
  report.seconds = SecondsSince(t_run);
  report.runner_seconds = report.seconds - ran_seconds;
  say("lifmcr batch run: %s\n", report.BriefReport(o.shard).c_str());
  return report;
}

}  // namespace lifmcr::batch
