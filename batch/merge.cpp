#include "batch/merge.h"

#include "batch/atomic_file.h"
#include "batch/manifest.h"
#include "batch/plan.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

namespace lifmcr::batch {

namespace fs = std::filesystem;
using nlohmann::json;

std::string MergeReport::BriefReport() const {
  std::string line = "merged " + std::to_string(merged) + " of " +
                     std::to_string(merged + static_cast<int>(not_done.size())) + " units into ";
  for (std::size_t k = 0; k < files.size(); ++k) line += (k ? ", " : "") + files[k];
  if (!not_done.empty()) {
    line += "; not done: ";
    for (std::size_t k = 0; k < not_done.size() && k < 5; ++k)
      line += (k ? ", " : "") + not_done[k];
    if (not_done.size() > 5) line += ", ... (" + std::to_string(not_done.size()) + ")";
  }
  return line;
}

namespace {

// CSV fields are written as they are when plain, else quoted (RFC 4180).
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string q = "\"";
  for (char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

struct EvalRow {
  std::string scene, sequence, table, method, camera, correction;
  std::int64_t frames = 0;
  double t_rmse = NAN, t_sd = NAN, r_rmse = NAN, r_sd = NAN;
};

// The rows of one evaluation.json: "map frame" (ape of map_frame_evaluations),
// "relative" (rpe) and "absolute" (ape) of evaluations; uncorrected and, where
// present, hand-eye corrected.
Status EvaluationRows(const fs::path& path, const Unit& unit, std::vector<EvalRow>* rows) {
  Expected<std::string> text = ReadWholeFile(path);
  if (!text) return text.error();
  try {
    const json j = json::parse(*text);
    auto add = [&](const json& e, const char* table, const char* protocol) {
      for (const char* correction : {"uncorrected", "corrected"}) {
        if (!e.contains(correction)) continue;
        const json& summary = e.at(correction).at(protocol);
        EvalRow r{unit.scene,
                  unit.sequence,
                  table,
                  e.at("method").get<std::string>(),
                  e.at("camera").get<std::string>(),
                  std::string(correction) == "corrected" ? "hand-eye" : "uncorrected"};
        r.frames = summary.at("translation_mm").at("count").get<std::int64_t>();
        r.t_rmse = summary.at("translation_mm").at("rmse").get<double>();
        r.t_sd = summary.at("translation_mm").at("sd").get<double>();
        r.r_rmse = summary.at("rotation_deg").at("rmse").get<double>();
        r.r_sd = summary.at("rotation_deg").at("sd").get<double>();
        rows->push_back(r);
      }
    };
    if (j.contains("map_frame_evaluations"))
      for (const json& e : j.at("map_frame_evaluations")) add(e, "map frame", "ape");
    for (const json& e : j.at("evaluations")) {
      add(e, "relative", "rpe");
      add(e, "absolute", "ape");
    }
  } catch (const json::exception& e) {
    return Error{path.string() + ": expected lifmcr evaluate's evaluation.json: " + e.what()};
  }
  return Status::Ok();
}

std::string Fixed(double v, int digits) {
  if (std::isnan(v)) return "-";
  char text[32];
  std::snprintf(text, sizeof text, "%.*f", digits, v);
  return text;
}

}  // namespace

Expected<MergeReport> MergePlan(const fs::path& plan_dir) {
  Expected<Plan> plan = ReadPlan(plan_dir);
  if (!plan) return plan.error();
  MergeReport report;
  std::string outputs_csv = "unit,path,bytes,xxh64\n";
  std::string registration_csv, registration_header;
  std::vector<EvalRow> eval_rows;
  for (const Unit& unit : plan->units) {
    Expected<std::optional<ManifestEntry>> entry = ReadManifestEntry(plan_dir, unit.id);
    if (!entry) return entry.error();
    if (!*entry || (*entry)->state != UnitState::kDone) {
      report.not_done.push_back(unit.id);
      continue;
    }
    ++report.merged;
    for (const OutputFile& f : (*entry)->outputs)
      outputs_csv += CsvField(unit.id) + "," + CsvField(f.path) + "," + std::to_string(f.bytes) +
                     "," + f.xxh64 + "\n";
    if (plan->stage == Stage::kRegister) {
      const fs::path path = plan_dir / unit.outputs / "registration.csv";
      Expected<std::string> text = ReadWholeFile(path);
      if (!text) return text.error();
      std::size_t start = 0;
      bool first = true;
      while (start < text->size()) {
        std::size_t end = text->find('\n', start);
        if (end == std::string::npos) end = text->size();
        const std::string line = text->substr(start, end - start);
        start = end + 1;
        if (line.empty()) continue;
        if (first) {
          first = false;
          if (registration_header.empty())
            registration_header = line;
          else if (line != registration_header)
            return Error{path.string() + ":1: header '" + line +
                         "' differs from the first unit's '" + registration_header + "'"};
          continue;
        }
        registration_csv +=
            CsvField(unit.scene) + "," + CsvField(unit.sequence) + "," + line + "\n";
      }
    }
    if (plan->stage == Stage::kEvaluate)
      if (Status s = EvaluationRows(plan_dir / unit.outputs / "evaluation.json", unit, &eval_rows);
          !s)
        return s.error();
  }
  auto write = [&](const std::string& name, const std::string& content) -> Status {
    if (Status s = WriteFileAtomically(plan_dir / "merged" / name, content); !s) return s;
    report.files.push_back("merged/" + name);
    return Status::Ok();
  };
  if (Status s = write("outputs.csv", outputs_csv); !s) return s.error();
  if (plan->stage == Stage::kRegister && !registration_header.empty())
    if (Status s = write("registration.csv",
                         "scene,sequence," + registration_header + "\n" + registration_csv);
        !s)
      return s.error();
  if (plan->stage == Stage::kEvaluate) {
    std::string csv =
        "scene,sequence,table,method,camera,correction,frames,t_rmse_mm,t_sd_mm,r_rmse_deg,r_sd_"
        "deg\n";
    std::string md =
        "| sequence | table | method | camera | correction | frames | T RMSE mm | T SD mm | R RMSE "
        "deg | R SD deg |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n";
    // Pooled over sequences: per (table, method, camera, correction).
    std::map<std::tuple<std::string, std::string, std::string, std::string>,
             std::tuple<std::int64_t, double, double>>
        pooled;
    for (const EvalRow& r : eval_rows) {
      csv += CsvField(r.scene) + "," + CsvField(r.sequence) + "," + CsvField(r.table) + "," +
             CsvField(r.method) + "," + CsvField(r.camera) + "," + r.correction + "," +
             std::to_string(r.frames) + "," + Fixed(r.t_rmse, 4) + "," + Fixed(r.t_sd, 4) + "," +
             Fixed(r.r_rmse, 5) + "," + Fixed(r.r_sd, 5) + "\n";
      md += "| " + r.scene + "/" + r.sequence + " | " + r.table + " | " + r.method + " | " +
            r.camera + " | " + r.correction + " | " + std::to_string(r.frames) + " | " +
            Fixed(r.t_rmse, 2) + " | " + Fixed(r.t_sd, 2) + " | " + Fixed(r.r_rmse, 3) + " | " +
            Fixed(r.r_sd, 3) + " |\n";
      if (r.frames > 0 && !std::isnan(r.t_rmse) && !std::isnan(r.r_rmse)) {
        auto& [n, t2, r2] = pooled[{r.table, r.method, r.camera, r.correction}];
        n += r.frames;
        t2 += r.frames * r.t_rmse * r.t_rmse;
        r2 += r.frames * r.r_rmse * r.r_rmse;
      }
    }
    for (const auto& [key, value] : pooled) {
      const auto& [table, method, camera, correction] = key;
      const auto& [n, t2, r2] = value;
      md += "| all | " + table + " | " + method + " | " + camera + " | " + correction + " | " +
            std::to_string(n) + " | " + Fixed(std::sqrt(t2 / n), 2) + " | - | " +
            Fixed(std::sqrt(r2 / n), 3) + " | - |\n";
    }
    if (Status s = write("evaluation.csv", csv); !s) return s.error();
    if (Status s = write("evaluation.md",
                         "# Evaluation over " + std::to_string(report.merged) +
                             " sequences\n\nPlan: " + plan->BriefReport() +
                             ". Rows \"all\": frames summed, RMSE pooled over the sequences "
                             "(sqrt of the frame-weighted mean of the squares).\n\n" +
                             md);
        !s)
      return s.error();
  }
  return report;
}

}  // namespace lifmcr::batch
