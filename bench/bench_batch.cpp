// `lifmcr batch run` of a depth plan over a synthetic rig (written first by
// `lifmcr synth`, not timed): (1) one shard pinned to one core against two
// shards pinned to two cores (units are independent: the goal is >= 1.8x);
// (2) the per-unit overhead of `batch run` (its start, lock, manifest read,
// emptying the output folder, log, XXH64 of every output, atomic manifest
// entry) against the bare `lifmcr depth` commands of the same plan run one
// after another on the same core, each with its output to a log as the
// runner does (goal <= 2 %), in wall time and in CPU time (user + system of
// the commands and the runner), fastest of the repeats; and the runner's own
// share, the batch run less its commands' times as the manifest records them
// (`seconds`, `cpu_seconds`), which the commands' run-to-run spread does not
// blur.
//
// Each timed run starts from the same state: sync(2) first (untimed), so the
// writeback of the previous run's outputs does not fall into this one, and
// every run's unit outputs are deleted once its figures are read, so the page
// cache does not fill up over the bench (later runs would pay for the
// reclaim). Bare and batch runs alternate in order from one repeat to the
// next (bare first in odd repeats, batch first in even ones).
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
    "lifmcr batch run of a depth plan over a synthetic 2-camera rig (--frames per camera,\n"
    "units of --per; defaults: medium, 8 frames, frames:1 = 16 units, 3 repeats):\n"
    "  speed-up: 1 shard on core 0 against 2 shards on cores 0 and 1 (goal >= 1.8x);\n"
    "  overhead: batch run (1 shard, core 0) against the same units' bare lifmcr depth\n"
    "  commands on core 0, per unit, in wall and in CPU time, fastest of the repeats, and the\n"
    "  runner's own share from the manifest (goal <= 2 %).\n"
    "Every timed run follows a sync and its outputs are deleted after it; the load average is\n"
    "printed with every repeat. --keep DIR: the data, plans, manifests and logs stay in DIR.\n"
    "About 6 min at the defaults on 2 quiet cores (bench/README.md, docs/batch.md).\n";

// One timed run: wall and CPU seconds in all, and of it its units' commands
// (the bare run: all of it; a batch run: the manifest's seconds and cpu_seconds).
struct Timing {
  double wall = 0, cpu = 0;
  double commands_wall = 0, commands_cpu = 0;
};

double Fastest(const std::vector<Timing>& runs, double Timing::*field) {
  double best = runs.front().*field;
  for (const Timing& t : runs) best = std::min(best, t.*field);
  return best;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

const char* Verdict(double percent) { return percent <= 2.0 ? "met" : "NOT met"; }

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string preset = "medium", per = "frames:1", keep;
  int frames = 8, repeat = 3;
  for (int k = 1; k < argc; k += 2) {
    const std::string flag = argv[k];
    if (k + 1 >= argc) {
      std::fprintf(stderr, "bench_batch: %s needs a value\n%s", flag.c_str(), kUsage);
      return 2;
    }
    const std::string value = argv[k + 1];
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
      std::fprintf(stderr, "bench_batch: unknown flag %s\n%s", flag.c_str(), kUsage);
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
  const auto t_bench = Clock::now();
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
  auto read_plan = [](const fs::path& p) {
    lifmcr::Expected<lifmcr::batch::Plan> pl = lifmcr::batch::ReadPlan(p);
    if (!pl) {
      std::fprintf(stderr, "bench_batch: %s\n", pl.error().message.c_str());
      std::exit(1);
    }
    return std::move(*pl);
  };
  auto batch_run = [&](const fs::path& p, int shard, int shards, int cpu) {
    return Start({lifmcr, "batch", "run", p.string(), "--shard",
                  std::to_string(shard) + "/" + std::to_string(shards), "--quiet"},
                 cpu, {}, p / ("run_" + std::to_string(shard) + ".log"));
  };
  // The units' commands' own times in a batch run, as its manifest records them.
  auto add_manifest_times = [&](const fs::path& p, Timing& t) {
    for (const lifmcr::batch::Unit& u : read_plan(p).units) {
      auto e = lifmcr::batch::ReadManifestEntry(p, u.id);
      if (!e || !*e) {
        std::fprintf(stderr, "bench_batch: no manifest entry of %s in %s\n", u.id.c_str(),
                     p.c_str());
        std::exit(1);
      }
      t.commands_wall += (*e)->seconds;
      t.commands_cpu += (*e)->cpu_seconds;
    }
  };
  // Outputs go once a run's figures are read (see the top of the file).
  auto drop_outputs = [](const fs::path& p) {
    std::error_code ec;
    fs::remove_all(p / "units", ec);
  };

  // Bare: every unit's command as the plan writes it, one after another on core 0.
  auto run_bare = [&]() {
    const fs::path p = plan();
    const lifmcr::batch::Plan pl = read_plan(p);
    for (const lifmcr::batch::Unit& u : pl.units) fs::create_directories(p / u.outputs);
    fs::create_directories(p / "logs");
    ::sync();
    Timing t;
    const auto t0 = Clock::now();
    g_cpu_seconds = 0;
    for (const lifmcr::batch::Unit& u : pl.units) {
      std::vector<std::string> command = u.command;
      command[0] = lifmcr;
      if (Finish(Start(command, 0, p, p / "logs" / "bare.log")) != 0) {
        std::fprintf(stderr, "bench_batch: %s failed (%s)\n", u.CommandLine().c_str(),
                     (p / "logs/bare.log").c_str());
        std::exit(1);
      }
    }
    t.wall = t.commands_wall = Since(t0);
    t.cpu = t.commands_cpu = g_cpu_seconds;
    drop_outputs(p);
    return t;
  };
  // `shards` shards of the plan at once, shard k pinned to core k.
  auto run_shards = [&](int shards) {
    const fs::path p = plan();
    ::sync();
    Timing t;
    const auto t0 = Clock::now();
    g_cpu_seconds = 0;
    std::vector<pid_t> runs;
    for (int k = 0; k < shards; ++k) runs.push_back(batch_run(p, k, shards, k));
    bool failed = false;
    for (const pid_t pid : runs) failed |= Finish(pid) != 0;
    t.wall = Since(t0);
    t.cpu = g_cpu_seconds;
    if (failed) {
      std::fprintf(stderr, "bench_batch: batch run of %d shard(s) failed (%s)\n", shards,
                   p.c_str());
      std::exit(1);
    }
    add_manifest_times(p, t);
    drop_outputs(p);
    return t;
  };

  const std::size_t units = read_plan(plan()).units.size();
  std::vector<Timing> bare, one, two;
  for (int r = 0; r < repeat; ++r) {
    const bool bare_first = r % 2 == 0;
    if (bare_first) bare.push_back(run_bare());
    one.push_back(run_shards(1));
    if (!bare_first) bare.push_back(run_bare());
    if (cpus >= 2) two.push_back(run_shards(2));
    const Timing &b = bare.back(), &o = one.back();
    std::printf(
        "repeat %d (%s first): bare %.2f s (CPU %.2f s); batch run 1 shard %.2f s (CPU %.2f s), "
        "its commands %.2f s (CPU %.2f s): %+.2f %% wall, %+.2f %% CPU; 2 shards %.2f s; load "
        "%s\n",
        r + 1, bare_first ? "bare" : "batch", b.wall, b.cpu, o.wall, o.cpu, o.commands_wall,
        o.commands_cpu, 100.0 * (o.wall - b.wall) / b.wall, 100.0 * (o.cpu - b.cpu) / b.cpu,
        two.empty() ? 0.0 : two.back().wall, LoadAverage().c_str());
    std::fflush(stdout);
  }

  const double n = static_cast<double>(units);
  const double bare_wall = Fastest(bare, &Timing::wall), one_wall = Fastest(one, &Timing::wall);
  const double bare_cpu = Fastest(bare, &Timing::cpu), one_cpu = Fastest(one, &Timing::cpu);
  std::printf(
      "%zu units; fastest of %d: bare commands %.2f s (%.3f s/unit), batch run 1 shard %.2f s\n",
      units, repeat, bare_wall, bare_wall / n, one_wall);
  const double over_wall = 100.0 * (one_wall - bare_wall) / bare_wall;
  const double over_cpu = 100.0 * (one_cpu - bare_cpu) / bare_cpu;
  std::printf("overhead of batch run: %+.1f ms per unit, %+.2f %% of wall time (goal <= 2 %%: %s)\n",
              (one_wall - bare_wall) / n * 1e3, over_wall, Verdict(over_wall));
  // CPU time counts what the runner itself costs and little of what other
  // processes on a shared machine take from the core (they stretch wall time).
  std::printf(
      "overhead in CPU time: bare %.2f s, batch run %.2f s: %+.1f ms per unit, %+.2f %% (goal "
      "<= 2 %%: %s)\n",
      bare_cpu, one_cpu, (one_cpu - bare_cpu) / n * 1e3, over_cpu, Verdict(over_cpu));
  // The runner's own share in each batch run: the run less its commands. Free
  // of the commands' spread from run to run, which the comparisons above carry.
  std::vector<double> own_wall, own_cpu, commands_cpu_change;
  for (std::size_t k = 0; k < one.size(); ++k) {
    own_wall.push_back(one[k].wall - one[k].commands_wall);
    own_cpu.push_back(one[k].cpu - one[k].commands_cpu);
    commands_cpu_change.push_back(100.0 * (one[k].commands_cpu - bare[k].cpu) / bare[k].cpu);
  }
  const double runner_wall = Median(own_wall), runner_cpu = Median(own_cpu);
  std::printf(
      "batch run's own share (the run less its commands, from the manifest), median of %d: "
      "%.1f ms per unit wall = %.2f %% of a bare unit, %.1f ms per unit CPU = %.2f %% (goal <= 2 "
      "%%: %s)\n",
      repeat, runner_wall / n * 1e3, 100.0 * runner_wall / bare_wall, runner_cpu / n * 1e3,
      100.0 * runner_cpu / bare_cpu, Verdict(100.0 * runner_wall / bare_wall));
  std::printf(
      "its commands' CPU against the bare commands' in the same repeat (the same command lines: "
      "the machine's spread), median %+.2f %%\n",
      Median(commands_cpu_change));
  if (!two.empty()) {
    const double two_wall = Fastest(two, &Timing::wall);
    std::printf(
        "2 shards on 2 cores %.2f s against 1 shard on 1 core %.2f s: %.2fx (goal >= 1.8x)\n",
        two_wall, one_wall, one_wall / two_wall);
    // CPU seconds per wall second: the cores the shards got. Below 2 with
    // runnable shards, other processes held the cores for the rest.
    const auto fastest = [](const std::vector<Timing>& v) {
      return *std::min_element(v.begin(), v.end(),
                               [](const Timing& a, const Timing& b) { return a.wall < b.wall; });
    };
    const Timing t2 = fastest(two), t1 = fastest(one);
    std::printf("cores used: 2 shards %.2f (CPU %.2f s), 1 shard %.2f (CPU %.2f s)\n",
                t2.cpu / t2.wall, t2.cpu, t1.cpu / t1.wall, t1.cpu);
  } else {
    std::printf("one CPU: no 2-shard figure\n");
  }
  std::printf("load average at the end %s; the bench took %.0f s\n", LoadAverage().c_str(),
              Since(t_bench));
  if (keep.empty()) fs::remove_all(dir);
  return 0;
}
