// Process-wide settings for the pipeline (process_settings.h).

#include "apps/pipeline/process_settings.h"

#include "config/memory_policy.h"

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/info.h>

namespace lifmcr::apps {

struct ProcessSettings::Impl {
  std::unique_ptr<tbb::global_control> worker_limit;
};

ProcessSettings::ProcessSettings() : impl_(std::make_unique<Impl>()) {}
ProcessSettings::~ProcessSettings() = default;

std::unique_ptr<ProcessSettings> ProcessSettings::ForPipeline(HeapArenas arenas) {
  KeepHeapResident(arenas);
  std::unique_ptr<ProcessSettings> settings(new ProcessSettings());
  const int cores = tbb::info::default_concurrency();
  settings->impl_->worker_limit = std::make_unique<tbb::global_control>(
      tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(cores) + 1);
  return settings;
}

}  // namespace lifmcr::apps
