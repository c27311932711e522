#pragma once
// What the batch tests share: a synthetic rig written by the real `lifmcr
// synth`, processes started and stopped by pid, waiting with a deadline, and
// plan folders compared byte for byte.

#include "batch/manifest.h"
#include "batch/plan.h"

#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <sys/types.h>
#include <vector>

namespace lifmcr::batch::test {

// `lifmcr synth --preset small --cameras 2 --frames FRAMES` into DIR (the
// dataset root); a test failure when it does not exit 0.
void SynthSmallRig(const std::filesystem::path& dir, int frames);

// Runs argv (argv[0] a path or a name on PATH) and returns its exit code;
// stdout and stderr go to `log` (appended) when given, else to the test's.
int Run(const std::vector<std::string>& argv, const std::filesystem::path& log = {});

// Starts argv in the background (its own process group when `own_group`),
// stdout and stderr to `log`; returns its pid.
pid_t Spawn(const std::vector<std::string>& argv, const std::filesystem::path& log, bool own_group);
// Waits for a spawned process; its exit code, or 128 + the signal that ended it.
int Wait(pid_t pid);

// Polls `done` every 20 ms until it is true or `timeout` passed; returns its last value.
bool WaitUntil(const std::function<bool()>& done, std::chrono::milliseconds timeout);

// relative path -> content of every regular file under dir.
std::map<std::string, std::string> ReadTree(const std::filesystem::path& dir);

// Each unit's manifest entry (a test failure where one is missing or unreadable).
std::map<std::string, ManifestEntry> Entries(const std::filesystem::path& plan_dir);

}  // namespace lifmcr::batch::test

namespace lifmcr::batch::test {

// stdout of a shell command line (quote the words yourself), and its exit code.
struct Captured {
  int exit_code = -1;
  std::string out;
};
Captured Capture(const std::string& command_line);

// The full path of an executable in PATH, /usr/sbin or /usr/bin; empty when none.
std::string FindProgram(const std::string& name);

}  // namespace lifmcr::batch::test
