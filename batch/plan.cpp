#include "batch/plan.h"

#include "batch/atomic_file.h"
#include "config/text_escape.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <set>

namespace lifmcr::batch {

namespace fs = std::filesystem;
using nlohmann::json;

std::string_view ToString(Stage stage) {
  switch (stage) {
    case Stage::kDepth:
      return "depth";
    case Stage::kCalibrate:
      return "calibrate";
    case Stage::kRegister:
      return "register";
    case Stage::kEvaluate:
      return "evaluate";
  }
  return "?";
}

Expected<Stage> ParseStage(std::string_view text) {
  for (Stage s : {Stage::kDepth, Stage::kCalibrate, Stage::kRegister, Stage::kEvaluate})
    if (text == ToString(s)) return s;
  return Error{"stage '" + Excerpt(std::string(text)) +
               "': expected depth, calibrate, register or evaluate"};
}

namespace {

bool IsNameChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
         c == '_' || c == '-';
}

std::string ShellQuote(const std::string& word) {
  bool plain = !word.empty();
  for (char c : word)
    if (!IsNameChar(c) && c != '/' && c != ':' && c != '=' && c != ',' && c != '+') plain = false;
  if (plain) return word;
  std::string quoted = "'";
  for (char c : word) {
    if (c == '\'')
      quoted += "'\\''";
    else
      quoted += c;
  }
  return quoted + "'";
}

}  // namespace

bool IsValidUnitId(std::string_view id) {
  if (id.empty() || id.size() > 1024) return false;
  std::size_t start = 0;
  while (start <= id.size()) {
    const std::size_t end = std::min(id.find('/', start), id.size());
    const std::string_view part = id.substr(start, end - start);
    if (part.empty() || part == "." || part == "..") return false;
    for (char c : part)
      if (!IsNameChar(c)) return false;
    start = end + 1;
  }
  return true;
}

std::string Unit::CommandLine() const {
  std::string line;
  for (const std::string& word : command) {
    if (!line.empty()) line += ' ';
    line += ShellQuote(word);
  }
  return line;
}

std::string Plan::BriefReport() const {
  return std::string(ToString(stage)) + " plan of " + dataset + ": " +
         std::to_string(units.size()) + " unit" + (units.size() == 1 ? "" : "s") + " per " + per;
}

std::vector<std::size_t> Plan::ShardUnits(int index, int count) const {
  std::vector<std::size_t> mine;
  for (std::size_t k = static_cast<std::size_t>(index); k < units.size();
       k += static_cast<std::size_t>(count))
    mine.push_back(k);
  return mine;
}

std::string FormatPlan(const Plan& plan) {
  json header = {{"lifmcr_batch_plan", kPlanVersion},
                 {"stage", ToString(plan.stage)},
                 {"per", plan.per},
                 {"dataset", plan.dataset},
                 {"units", plan.units.size()},
                 {"command", plan.planned_by}};
  std::string text = header.dump() + "\n";
  for (const Unit& u : plan.units) {
    json needs = json::array();
    for (const UnitNeed& n : u.needs) needs.push_back({{"plan", n.plan}, {"unit", n.unit}});
    json line = {{"unit", u.id},         {"scene", u.scene},         {"sequence", u.sequence},
                 {"camera", u.camera},   {"reference", u.reference}, {"command", u.command},
                 {"outputs", u.outputs}, {"writes", u.writes},       {"done_exits", u.done_exits},
                 {"needs", needs}};
    text += line.dump() + "\n";
  }
  return text;
}

namespace {

// One field of a JSON line with its type checked; the error names the line and field.
struct LineReader {
  const std::string& label;
  int line;
  const json& object;

  Error Fail(const std::string& field, const std::string& what) const {
    return MakeError(label, line, 0, "\"" + field + "\": " + what);
  }
  Expected<std::string> String(const std::string& field) const {
    const auto it = object.find(field);
    if (it == object.end() || !it->is_string()) return Fail(field, "expected a string");
    return it->get<std::string>();
  }
  Expected<std::vector<std::string>> Strings(const std::string& field) const {
    const auto it = object.find(field);
    if (it == object.end() || !it->is_array()) return Fail(field, "expected an array of strings");
    std::vector<std::string> out;
    for (const json& v : *it) {
      if (!v.is_string()) return Fail(field, "expected an array of strings");
      out.push_back(v.get<std::string>());
    }
    return out;
  }
};

}  // namespace

Expected<Plan> ParsePlan(std::string_view text, const std::string& label) {
  Plan plan;
  std::set<std::string> ids;
  std::size_t start = 0;
  int line_no = 0;
  std::int64_t declared_units = -1;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos)
      return MakeError(label, line_no + 1, 0,
                       "the last line does not end with a newline (cut short?)");
    const std::string_view line = text.substr(start, end - start);
    start = end + 1;
    ++line_no;
    json object;
    try {
      object = json::parse(line);
    } catch (const json::parse_error& e) {
      return MakeError(label, line_no, 0, std::string("expected one JSON object: ") + e.what());
    }
    if (!object.is_object()) return MakeError(label, line_no, 0, "expected one JSON object");
    const LineReader r{label, line_no, object};
    if (line_no == 1) {
      const auto version = object.find("lifmcr_batch_plan");
      if (version == object.end() || !version->is_number_integer())
        return r.Fail("lifmcr_batch_plan", "expected the plan header (version number) on line 1");
      if (version->get<int>() != kPlanVersion)
        return r.Fail("lifmcr_batch_plan", "version " + version->dump() +
                                               " is not the one this lifmcr reads (" +
                                               std::to_string(kPlanVersion) + ")");
      Expected<std::string> stage = r.String("stage");
      if (!stage) return stage.error();
      Expected<Stage> parsed = ParseStage(*stage);
      if (!parsed) return r.Fail("stage", parsed.error().message);
      plan.stage = *parsed;
      for (auto [field, target] : {std::pair{"per", &plan.per}, std::pair{"dataset", &plan.dataset},
                                   std::pair{"command", &plan.planned_by}}) {
        Expected<std::string> v = r.String(field);
        if (!v) return v.error();
        *target = *v;
      }
      const auto units = object.find("units");
      if (units == object.end() || !units->is_number_unsigned())
        return r.Fail("units", "expected the number of units");
      declared_units = units->get<std::int64_t>();
      continue;
    }
    Unit u;
    for (auto [field, target] :
         {std::pair{"unit", &u.id}, std::pair{"scene", &u.scene},
          std::pair{"sequence", &u.sequence}, std::pair{"camera", &u.camera},
          std::pair{"reference", &u.reference}, std::pair{"outputs", &u.outputs}}) {
      Expected<std::string> v = r.String(field);
      if (!v) return v.error();
      *target = *v;
    }
    if (!IsValidUnitId(u.id))
      return r.Fail("unit",
                    "'" + Excerpt(u.id) +
                        "': expected names of letters, digits, '.', '_', '-' joined by '/'");
    if (!ids.insert(u.id).second) return r.Fail("unit", "'" + u.id + "' is listed twice");
    Expected<std::vector<std::string>> command = r.Strings("command");
    if (!command) return command.error();
    if (command->empty() || command->front() != "lifmcr")
      return r.Fail("command", "expected a lifmcr command (first word \"lifmcr\")");
    u.command = *command;
    // The runner empties the output folder before each attempt: it must be
    // the unit's own folder, never anything else under PLAN_DIR.
    if (u.outputs != "units/" + u.id)
      return r.Fail("outputs", "expected \"units/" + u.id + "\", got '" + Excerpt(u.outputs) + "'");
    Expected<std::vector<std::string>> writes = r.Strings("writes");
    if (!writes) return writes.error();
    for (const std::string& w : *writes)
      if (w.rfind(u.outputs + "/", 0) != 0 || w.find("..") != std::string::npos)
        return r.Fail("writes", "'" + Excerpt(w) + "' is not inside " + u.outputs + "/");
    u.writes = *writes;
    const auto done_exits = object.find("done_exits");
    if (done_exits == object.end() || !done_exits->is_array())
      return r.Fail("done_exits", "expected an array of exit codes (0 among them)");
    u.done_exits.clear();
    for (const json& code : *done_exits) {
      if (!code.is_number_integer() || code.get<int>() < 0 || code.get<int>() > 255)
        return r.Fail("done_exits", "expected exit codes 0 .. 255");
      u.done_exits.push_back(code.get<int>());
    }
    if (std::find(u.done_exits.begin(), u.done_exits.end(), 0) == u.done_exits.end())
      return r.Fail("done_exits", "expected 0 among the exit codes");
    const auto needs = object.find("needs");
    if (needs == object.end() || !needs->is_array())
      return r.Fail("needs", "expected an array of {\"plan\", \"unit\"}");
    for (const json& n : *needs) {
      if (!n.is_object() || !n.contains("plan") || !n["plan"].is_string() || !n.contains("unit") ||
          !n["unit"].is_string())
        return r.Fail("needs", "expected an array of {\"plan\", \"unit\"}");
      UnitNeed need{n["plan"].get<std::string>(), n["unit"].get<std::string>()};
      if (!fs::path(need.plan).is_absolute() || !IsValidUnitId(need.unit))
        return r.Fail("needs", "expected an absolute plan folder and a unit id, got '" +
                                   Excerpt(need.plan) + "', '" + Excerpt(need.unit) + "'");
      u.needs.push_back(std::move(need));
    }
    plan.units.push_back(std::move(u));
  }
  if (line_no == 0) return MakeError(label, 0, 0, "empty: expected the plan header on line 1");
  if (declared_units != static_cast<std::int64_t>(plan.units.size()))
    return MakeError(label, 1, 0,
                     "\"units\": the header says " + std::to_string(declared_units) +
                         " units, the file lists " + std::to_string(plan.units.size()));
  return plan;
}

Expected<Plan> ReadPlan(const fs::path& plan_dir) {
  const fs::path path = plan_dir / kPlanFileName;
  Expected<std::string> text = ReadWholeFile(path);
  if (!text)
    return Error{text.error().message + " (is " + plan_dir.string() +
                 " a folder written by lifmcr batch plan?)"};
  return ParsePlan(*text, path.string());
}

Status WritePlan(const fs::path& plan_dir, const Plan& plan) {
  return WriteFileAtomically(plan_dir / kPlanFileName, FormatPlan(plan));
}

Expected<ShardSpec> ShardSpec::Parse(std::string_view text) {
  const auto fail = [&] {
    return Error{"--shard '" + Excerpt(std::string(text)) +
                 "': expected I/N with 0 <= I < N <= 100000 (e.g. 0/4; Slurm: "
                 "$SLURM_ARRAY_TASK_ID/N)"};
  };
  const std::size_t slash = text.find('/');
  if (slash == std::string_view::npos) return fail();
  ShardSpec s;
  const char* b = text.data();
  const auto [e1, c1] = std::from_chars(b, b + slash, s.index);
  const auto [e2, c2] = std::from_chars(b + slash + 1, b + text.size(), s.count);
  if (c1 != std::errc() || e1 != b + slash || c2 != std::errc() || e2 != b + text.size() ||
      slash == 0 || slash + 1 == text.size())
    return fail();
  if (s.count < 1 || s.count > 100000 || s.index < 0 || s.index >= s.count) return fail();
  return s;
}

std::string ShardSpec::ToString() const {
  return std::to_string(index) + "/" + std::to_string(count);
}

}  // namespace lifmcr::batch
