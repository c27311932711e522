#pragma once
// The subcommands of `lifmcr`. Each registers its options on the CLI11 app
// and returns the callback that runs it; the exit code is the callback's.

#include "apps/registration_args.h"

#include <functional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace lifmcr::apps {

using CommandRun = std::function<int()>;

// CLI11 check of an `--lcm URL` option: LcmUrlProblem (config/rig_config.h),
// the check the rig file's lcm.url gets; empty when LCM opens the URL.
std::string LcmUrlCheck(const std::string& url);

CommandRun AddInfoCommand(CLI::App& app);
CommandRun AddViconCommand(CLI::App& app);
CommandRun AddSynthCommand(CLI::App& app);
CommandRun AddRecordCommand(CLI::App& app);
CommandRun AddReplayCommand(CLI::App& app);
CommandRun AddMonitorCommand(CLI::App& app);
CommandRun AddDemoCommand(CLI::App& app);
CommandRun AddGridCommand(CLI::App& app);
CommandRun AddDepthCommand(CLI::App& app);
CommandRun AddEvaluateCommand(CLI::App& app);
CommandRun AddCalibrateCommand(CLI::App& app);
CommandRun AddRegisterCommand(CLI::App& app);
// `lifmcr relate`: c0_from_cx from the POSE channels of processes on several hosts.
CommandRun AddRelateCommand(CLI::App& app);
// `lifmcr merge HOSTDIR... --out SEQ`: per-host recordings into one sequence.
CommandRun AddMergeCommand(CLI::App& app);
// `lifmcr batch plan|run|status|merge` (apps/cmd_batch.cpp, batch/).
CommandRun AddBatchCommand(CLI::App& app);

// `lifmcr replay SEQ` with its defaults otherwise, for `lifmcr demo`; the
// second form with live registration (registration_args.h; empty: none).
// Returns the exit code.
int RunReplayCommand(const std::string& sequence, const std::string& rate_text, bool loop,
                     const std::string& lcm_url, bool processing, int concurrency,
                     const char* who);
// pixel_formats: `--pixel-format` values ([SERIAL=]FORMAT); cameras:
// `--cameras SERIAL[,SERIAL...]` (empty: every camera).
int RunReplayCommand(const std::string& sequence, const std::string& rate_text, bool loop,
                     const std::string& lcm_url, bool processing, int concurrency, const char* who,
                     const RegistrationArgs& registration,
                     const std::vector<std::string>& pixel_formats = {},
                     const std::string& cameras = "");

}  // namespace lifmcr::apps
