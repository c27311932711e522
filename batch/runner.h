#pragma once
// `lifmcr batch run PLAN_DIR --shard I/N`: the units of one shard, one after
// another, each its own `lifmcr` process (the executable running the batch,
// so a plan never mixes versions within a run), with PLAN_DIR as its working
// folder and its stdout and stderr appended to PLAN_DIR/logs/<unit>.log.
//
// Per unit, in this order:
//   1. take PLAN_DIR/locks/<unit>.lock (flock, not waiting): a unit another
//      process is running is passed over ("busy"); the command inherits the
//      lock, so it holds while either of them lives (on a file system without
//      locks the run goes on unguarded and says so once);
//   2. a done manifest entry whose outputs verify (batch/manifest.h,
//      VerifyOutputs) -> skipped; one that does not verify is run again;
//   3. every unit it needs (of earlier plans) must be done there, else the
//      unit fails without running, naming what it waits for;
//   4. the output folder is emptied (whatever an attempt cut off left there
//      never mixes with the new outputs), the log gets a line
//      "# lifmcr batch run: attempt K of unit ..." and the command runs;
//   5. its manifest entry is written (batch/manifest.h says when it is done).
// A failed unit does not stop the shard; the next run retries it.
// SIGTERM, SIGINT or SIGHUP (scancel, preemption, Ctrl-C) are passed on to
// the running command; its unit is recorded failed ("interrupted by signal
// 15") unless the command still completed, and the run stops.

#include "batch/plan.h"
#include "config/error.h"

#include <cstdio>
#include <filesystem>
#include <string>

namespace lifmcr::batch {

struct RunOptions {
  std::filesystem::path plan_dir;
  ShardSpec shard;
  // The `lifmcr` executable each unit runs (default: this process's own, /proc/self/exe).
  std::filesystem::path executable;
  // Progress lines (one before and one after each unit); nullptr: none.
  std::FILE* progress = stdout;

  Status Check() const;
};

struct RunReport {
  int units = 0;           // in the shard
  int ran = 0;             // started
  int done = 0;            // ran and done
  int failed = 0;          // ran (or could not run) and failed
  int skipped = 0;         // done before and verified
  int busy = 0;            // being run by another process
  int interrupted_by = 0;  // the signal that stopped the run, 0 if none
  double seconds = 0;
  // Of `seconds`, the time outside the units' commands: the runner's own cost
  // (locks, verifying, logs, checksums, manifest entries) and the skipped units.
  double runner_seconds = 0;

  // "shard 0/2: 6 units: 4 done, 1 skipped (done before), 1 failed, 0 busy in
  // 12.3 s (0.041 s of it outside the units' commands)".
  std::string BriefReport(const ShardSpec& shard) const;
  // 0 when every unit is done (now or before); 1 when any failed or was busy;
  // 128 + signal when interrupted.
  int ExitCode() const;
};

// Runs the shard's units as above. An error only where the plan cannot be
// read or PLAN_DIR cannot be written; a unit's failure is in the report.
Expected<RunReport> RunShard(const RunOptions& options);

}  // namespace lifmcr::batch
