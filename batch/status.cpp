#include "batch/status.h"

#include <cstdio>

namespace lifmcr::batch {

std::string PlanStatus::BriefReport() const {
  char text[256];
  std::snprintf(text, sizeof text, ": %zu unit%s: %d done, %d failed, %d left", plan.units.size(),
                plan.units.size() == 1 ? "" : "s", done, failed, left);
  std::string line = std::string(ToString(plan.stage)) + " plan of " + plan.dataset + text;
  if (done > 0) {
    std::snprintf(text, sizeof text, "; %.1f s of units done (%.2f s each)", unit_seconds,
                  unit_seconds / done);
    line += text;
  }
  if (peak_rss_kib > 0) {
    std::snprintf(text, sizeof text, ", peak RSS %lld MiB (unit %s)",
                  static_cast<long long>(peak_rss_kib / 1024), peak_rss_unit.c_str());
    line += text;
  }
  return line;
}

int PlanStatus::ExitCode() const {
  if (failed > 0) return 1;
  return left > 0 ? 3 : 0;
}

Expected<PlanStatus> ReadPlanStatus(const std::filesystem::path& plan_dir) {
  Expected<Plan> plan = ReadPlan(plan_dir);
  if (!plan) return plan.error();
  PlanStatus status;
  status.plan = std::move(*plan);
  for (const Unit& unit : status.plan.units) {
    Expected<std::optional<ManifestEntry>> entry = ReadManifestEntry(plan_dir, unit.id);
    if (!entry) return entry.error();
    if (!*entry) {
      ++status.left;
      status.left_units.push_back(unit.id);
      continue;
    }
    const ManifestEntry& e = **entry;
    if (e.peak_rss_kib > status.peak_rss_kib) {
      status.peak_rss_kib = e.peak_rss_kib;
      status.peak_rss_unit = e.unit;
    }
    if (e.state == UnitState::kDone) {
      ++status.done;
      status.unit_seconds += e.seconds;
    } else {
      ++status.failed;
      status.failures.push_back(e);
    }
  }
  return status;
}

}  // namespace lifmcr::batch
