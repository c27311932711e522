// `lifmcr batch run` of a depth plan over a synthetic rig (written first by
// `lifmcr synth`, not timed): (1) one shard pinned to one core against two
// shards pinned to two cores (units are independent: the goal is >= 1.8x);
// (2) the per-unit overhead of `batch run` (lock, manifest read, needs,
// emptying the output folder, log, XXH64 of every output, atomic manifest
// entry) against the bare `lifmcr depth` commands of the same plan run one
// after another on the same core, each with its output to a log as the
// runner does (goal <= 2 %). Both are repeated; batch and bare runs
// alternate so a change of the machine's load hits both; the fastest of each
// is compared, in wall time and in CPU time (user + system of the commands
// and the runner).
//
//   bench_batch [--preset small|medium] [--frames 8] [--repeat 3] [--per frames:1] [--keep DIR]

#include "batch/manifest.h"
#include "batch/plan.h"
#include "bench/bench_usage.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <sched.h>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Starts argv pinned to `cpu` (-1: any), in `cwd`, stdout and stderr to `log`.
pid_t Start(const std::vector<std::string>& argv, int cpu, const fs::path& cwd,
            const fs::path& log) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (cpu >= 0) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(cpu, &set);
      ::sched_setaffinity(0, sizeof set, &set);
    }
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
    }
    if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) _exit(126);
    ::execv(args[0], args.data());
    _exit(127);
  }
  return pid;
}

// CPU seconds (user + system) of the processes Finish reaped: the runner's
// include its units' (wait4 reports a child with its waited-for children).
double g_cpu_seconds = 0;

int Finish(pid_t pid) {
  int status = 0;
  struct rusage usage {};
  ::wait4(pid, &status, 0, &usage);
  g_cpu_seconds += usage.ru_utime.tv_sec + usage.ru_utime.tv_usec * 1e-6 + usage.ru_stime.tv_sec +
                   usage.ru_stime.tv_usec * 1e-6;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string one;
  in >> one;
  return one;
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_batch [--preset small|medium] [--frames 8] [--per frames:1] [--repeat 3] "
    "[--keep DIR]\n"
    "lifmcr batch run of a depth plan over a synthetic 2-camera rig: 1 shard on 1 core against\n"
    "2 shards on 2 cores (goal >= 1.8x), and the runner's overhead per unit against the bare\n"
    "commands of the same plan (goal <= 2 %), in wall and CPU time (bench/README.md).\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string preset = "small", per = "frames:1", keep;
  int frames = 8, repeat = 3;
  for (int k = 1; k + 1 < argc; k += 2) {
    const std::string flag = argv[k], value = argv[k + 1];
    if (flag == "--preset")
      preset = value;
    else if (flag == "--frames")
      frames = std::atoi(value.c_str());
    else if (flag == "--repeat")
      repeat = std::atoi(value.c_str());
    else if (flag == "--per")
      per = value;
    else if (flag == "--keep")
      keep = value;
    else {
      std::fprintf(stderr, "bench_batch: unknown flag %s\n", flag.c_str());
      return 2;
    }
  }
  if (frames < 1 || repeat < 1) {
    std::fprintf(stderr, "bench_batch: --frames and --repeat must be >= 1\n");
    return 2;
  }
  const std::string lifmcr = LIFMCR_BINARY;
  const fs::path dir =
      keep.empty() ? fs::temp_directory_path() / ("bench_batch_" + std::to_string(::getpid()))
                   : fs::path(keep);
  fs::create_directories(dir);
  const long cpus = ::sysconf(_SC_NPROCESSORS_ONLN);
  std::printf(
      "bench_batch: preset %s, %d frames x 2 cameras, depth plan per %s, %d repeats, %ld "
      "CPUs, load average %s\n",
      preset.c_str(), frames, per.c_str(), repeat, cpus, LoadAverage().c_str());
  if (Finish(Start({lifmcr, "synth", "--out", (dir / "data").string(), "--preset", preset,
                    "--cameras", "2", "--frames", std::to_string(frames), "--quiet"},
                   -1, {}, dir / "synth.log")) != 0) {
    std::fprintf(stderr, "bench_batch: lifmcr synth failed (%s)\n", (dir / "synth.log").c_str());
    return 1;
  }
  int plans = 0;
  auto plan = [&]() -> fs::path {
    const fs::path p = dir / ("plan_" + std::to_string(plans++));
    if (Finish(Start({lifmcr, "batch", "plan", (dir / "data").string(), "--stage", "depth", "--per",
                      per, "--intrinsics", "ground-truth", "--out", p.string()},
                     -1, {}, dir / "plan.log")) != 0) {
      std::fprintf(stderr, "bench_batch: lifmcr batch plan failed (%s)\n",
                   (dir / "plan.log").c_str());
      std::exit(1);
    }
    return p;
  };
  auto batch_run = [&](const fs::path& p, int shard, int shards, int cpu) {
    return Start({lifmcr, "batch", "run", p.string(), "--shard",
                  std::to_string(shard) + "/" + std::to_string(shards), "--quiet"},
                 cpu, {}, p / ("run_" + std::to_string(shard) + ".log"));
  };

  std::vector<double> one_shard, two_shards, bare, bare_cpu, one_cpu, two_cpu, inside;
  std::size_t units = 0;
  for (int r = 0; r < repeat; ++r) {
    // Bare: every unit's command as the plan writes it, one after another on core 0.
    {
      const fs::path p = plan();
      lifmcr::Expected<lifmcr::batch::Plan> pl = lifmcr::batch::ReadPlan(p);
      if (!pl) {
        std::fprintf(stderr, "bench_batch: %s\n", pl.error().message.c_str());
        return 1;
      }
      units = pl->units.size();
      for (const lifmcr::batch::Unit& u : pl->units) fs::create_directories(p / u.outputs);
      fs::create_directories(p / "logs");
      const auto t = Clock::now();
      g_cpu_seconds = 0;
      for (const lifmcr::batch::Unit& u : pl->units) {
        std::vector<std::string> command = u.command;
        command[0] = lifmcr;
        if (Finish(Start(command, 0, p, p / "logs" / "bare.log")) != 0) {
          std::fprintf(stderr, "bench_batch: %s failed (%s)\n", u.CommandLine().c_str(),
                       (p / "logs/bare.log").c_str());
          return 1;
        }
      }
      bare.push_back(Since(t));
      bare_cpu.push_back(g_cpu_seconds);
    }
    // One shard on core 0.
    {
      const fs::path p = plan();
      const auto t = Clock::now();
      g_cpu_seconds = 0;
      if (Finish(batch_run(p, 0, 1, 0)) != 0) {
        std::fprintf(stderr, "bench_batch: batch run failed (%s)\n", p.c_str());
        return 1;
      }
      one_shard.push_back(Since(t));
      one_cpu.push_back(g_cpu_seconds);
      // The units' commands' own time, as the manifest records it: the rest of
      // the run is the runner's (its start included).
      double commands = 0;
      const lifmcr::Expected<lifmcr::batch::Plan> ran = lifmcr::batch::ReadPlan(p);
      if (!ran) {
        std::fprintf(stderr, "bench_batch: %s\n", ran.error().message.c_str());
        return 1;
      }
      for (const lifmcr::batch::Unit& u : ran->units)
        if (auto e = lifmcr::batch::ReadManifestEntry(p, u.id); e && *e) commands += (*e)->seconds;
      inside.push_back((one_shard.back() - commands) / commands);
    }
    // Two shards, on cores 0 and 1.
    if (cpus >= 2) {
      const fs::path p = plan();
      const auto t = Clock::now();
      g_cpu_seconds = 0;
      const pid_t a = batch_run(p, 0, 2, 0), b = batch_run(p, 1, 2, 1);
      const int ca = Finish(a), cb = Finish(b);
      two_cpu.push_back(g_cpu_seconds);
      if (ca != 0 || cb != 0) {
        std::fprintf(stderr, "bench_batch: batch run of 2 shards failed (%s)\n", p.c_str());
        return 1;
      }
      two_shards.push_back(Since(t));
    }
    std::printf(
        "repeat %d: bare %.2f s (CPU %.2f s), 1 shard/1 core %.2f s (CPU %.2f s), 2 shards/2 "
        "cores %.2f s (load %s)\n",
        r + 1, bare.back(), bare_cpu.back(), one_shard.back(), one_cpu.back(),
        two_shards.empty() ? 0.0 : two_shards.back(), LoadAverage().c_str());
    std::fflush(stdout);
  }
  const double t_bare = *std::min_element(bare.begin(), bare.end());
  std::sort(inside.begin(), inside.end());
  std::printf(
      "batch run's time outside the units' commands (its start included), median of %d: "
      "%.2f %% of the commands' time\n",
      repeat, 100.0 * inside[inside.size() / 2]);
  const double t_one = *std::min_element(one_shard.begin(), one_shard.end());
  std::printf(
      "%zu units; fastest of %d: bare commands %.2f s (%.3f s/unit), batch run 1 shard %.2f s\n",
      units, repeat, t_bare, t_bare / units, t_one);
  std::printf("overhead of batch run: %+.1f ms per unit, %+.2f %% of wall time (goal <= 2 %%)\n",
              (t_one - t_bare) / units * 1e3, 100.0 * (t_one - t_bare) / t_bare);
  // CPU time counts what the runner itself costs and little of what other
  // processes on a shared machine take from the core (they stretch wall time).
  const double c_bare = *std::min_element(bare_cpu.begin(), bare_cpu.end());
  const double c_one = *std::min_element(one_cpu.begin(), one_cpu.end());
  std::printf("CPU time: bare %.2f s, batch run %.2f s: %+.1f ms per unit, %+.2f %%\n", c_bare,
              c_one, (c_one - c_bare) / units * 1e3, 100.0 * (c_one - c_bare) / c_bare);
  if (!two_shards.empty()) {
    const double t_two = *std::min_element(two_shards.begin(), two_shards.end());
    std::printf(
        "2 shards on 2 cores %.2f s against 1 shard on 1 core %.2f s: %.2fx (goal >= 1.8x)\n",
        t_two, t_one, t_one / t_two);
    // CPU seconds per wall second: the cores the shards got. Below 2 with
    // runnable shards, other processes held the cores for the rest.
    const std::size_t k = static_cast<std::size_t>(
        std::min_element(two_shards.begin(), two_shards.end()) - two_shards.begin());
    const std::size_t j = static_cast<std::size_t>(
        std::min_element(one_shard.begin(), one_shard.end()) - one_shard.begin());
    std::printf("cores used: 2 shards %.2f (CPU %.2f s), 1 shard %.2f (CPU %.2f s)\n",
                two_cpu[k] / two_shards[k], two_cpu[k], one_cpu[j] / one_shard[j], one_cpu[j]);
  } else {
    std::printf("one CPU: no 2-shard figure\n");
  }
  std::printf("load average at the end %s\n", LoadAverage().c_str());
  if (keep.empty()) fs::remove_all(dir);
  return 0;
}
