// Logger set-up of the command (logging.h).

#include "apps/logging.h"

#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

namespace lifmcr::apps {

Status ConfigureLogging(const std::string& level, const std::string& file) {
  const spdlog::level::level_enum parsed = spdlog::level::from_str(level);
  // from_str maps unknown names to off; "off" itself is a valid choice.
  if (parsed == spdlog::level::off && level != "off")
    return Error{"--log-level: expected trace, debug, info, warn, error or off, got '" + level +
                 "'"};
  std::shared_ptr<spdlog::logger> logger;
  try {
    if (file.empty())
      logger = spdlog::stderr_logger_mt("lifmcr");
    else
      logger = spdlog::basic_logger_mt("lifmcr", file, /*truncate=*/false);
  } catch (const spdlog::spdlog_ex& e) {
    return Error{"--log-file: " + file + ": " + e.what()};
  }
  logger->set_level(parsed);
  logger->set_pattern("%Y-%m-%dT%H:%M:%S.%e %l %v");
  // Warnings and errors reach the file at once (a run may end by a signal).
  logger->flush_on(spdlog::level::warn);
  spdlog::set_default_logger(logger);
  return Status::Ok();
}

}  // namespace lifmcr::apps
