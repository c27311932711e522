#include "batch/planner.h"

#include "config/text_escape.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/synth/cameras_yaml.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <map>

namespace lifmcr::batch {

namespace fs = std::filesystem;

Expected<PerSpec> PerSpec::Parse(std::string_view text) {
  PerSpec p;
  if (text == "camera") {
    p.kind = Kind::kCamera;
    return p;
  }
  if (text == "sequence") {
    p.kind = Kind::kSequence;
    return p;
  }
  constexpr std::string_view kFrames = "frames:";
  if (text.substr(0, kFrames.size()) == kFrames) {
    const char* b = text.data() + kFrames.size();
    const char* e = text.data() + text.size();
    const auto [end, ec] = std::from_chars(b, e, p.frames);
    if (ec == std::errc() && end == e && b != e && p.frames >= 1 && p.frames <= 100000) return p;
  }
  return Error{"--per '" + Excerpt(std::string(text)) +
               "': expected frames:N (1 <= N <= 100000), camera or sequence"};
}

std::string PerSpec::ToString() const {
  switch (kind) {
    case Kind::kFrames:
      return "frames:" + std::to_string(frames);
    case Kind::kCamera:
      return "camera";
    case Kind::kSequence:
      return "sequence";
  }
  return "?";
}

namespace {

std::string DefaultPer(Stage stage) {
  switch (stage) {
    case Stage::kDepth:
      return "frames:16";
    case Stage::kCalibrate:
      return "camera";
    case Stage::kRegister:
      return "sequence";
    case Stage::kEvaluate:
      return "sequence";
  }
  return "";
}

// Which --per each stage takes (the table of batch/planner.h).
bool PerFits(Stage stage, PerSpec::Kind kind) {
  switch (stage) {
    case Stage::kDepth:
      return kind != PerSpec::Kind::kSequence;
    case Stage::kCalibrate:
      return kind == PerSpec::Kind::kCamera;
    case Stage::kRegister:
      return kind != PerSpec::Kind::kFrames;
    case Stage::kEvaluate:
      return kind == PerSpec::Kind::kSequence;
  }
  return false;
}

std::string Frame6(std::int64_t frame) {
  char text[32];
  std::snprintf(text, sizeof text, "%0*lld", layout::kFrameDigits, static_cast<long long>(frame));
  return text;
}

std::string Absolute(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path), ec);
  if (ec) p = fs::absolute(path).lexically_normal();
  return p.string();
}

bool IsNamePart(const std::string& name) {
  return IsValidUnitId(name) && name.find('/') == std::string::npos;
}

// An earlier plan, and its units by id.
struct EarlierPlan {
  std::string dir;  // absolute
  Plan plan;
  std::map<std::string, const Unit*> by_id;
};

Expected<EarlierPlan> LoadEarlier(const std::string& dir, Stage expected, const char* option) {
  EarlierPlan e;
  e.dir = Absolute(dir);
  Expected<Plan> plan = ReadPlan(e.dir);
  if (!plan) return Error{std::string(option) + ": " + plan.error().message};
  if (plan->stage != expected)
    return Error{std::string(option) + " " + dir + ": a " + std::string(ToString(plan->stage)) +
                 " plan, expected a " + std::string(ToString(expected)) + " plan"};
  e.plan = std::move(*plan);
  return e;
}

}  // namespace

Status PlanOptions::Check() const {
  if (dataset.empty()) return Error{"DATASET: expected a dataset root, scene or sequence folder"};
  if (out.empty()) return Error{"--out: expected the plan folder to write"};
  Expected<PerSpec> p = PerSpec::Parse(per.empty() ? DefaultPer(stage) : per);
  if (!p) return p.error();
  if (!PerFits(stage, p->kind)) {
    const char* fits =
        stage == Stage::kDepth       ? "frames:N or camera (one depth command is one camera)"
        : stage == Stage::kCalibrate ? "camera (one calibration is one camera)"
        : stage == Stage::kRegister  ? "sequence or camera (registration needs whole sequences)"
                                     : "sequence (one evaluation is one sequence)";
    return Error{"--per " + p->ToString() + " does not apply to --stage " +
                 std::string(ToString(stage)) + ": expected " + fits};
  }
  for (const std::string& s : cameras)
    if (!layout::IsValidSerial(s))
      return Error{"--camera '" + Excerpt(s) + "': expected a serial (letters, digits, '-')"};
  if (!reference_camera.empty() && !layout::IsValidSerial(reference_camera))
    return Error{"--reference-camera '" + Excerpt(reference_camera) +
                 "': expected a serial (letters, digits, '-')"};
  for (const std::string& s : sequences)
    if (s.empty() || s.find("..") != std::string::npos)
      return Error{"--sequence '" + Excerpt(s) + "': expected SEQ or SCENE/SEQ"};
  for (const std::string& word : extra)
    if (word == "--out" || word.rfind("--out=", 0) == 0)
      return Error{"'" + word + "' after --: the plan chooses each unit's --out (under PLAN_DIR)"};
  auto only_for = [&](bool given, const char* option,
                      std::initializer_list<Stage> stages) -> Status {
    if (!given) return Status::Ok();
    for (Stage s : stages)
      if (s == stage) return Status::Ok();
    std::string names;
    for (Stage s : stages) names += (names.empty() ? "" : " or ") + std::string(ToString(s));
    return Error{std::string(option) + " does not apply to --stage " +
                 std::string(ToString(stage)) + " (it is for --stage " + names + ")"};
  };
  for (Status s :
       {only_for(!intrinsics.empty(), "--intrinsics", {Stage::kDepth}),
        only_for(!calibration_plan.empty(), "--calibration-plan",
                 {Stage::kDepth, Stage::kRegister, Stage::kEvaluate}),
        only_for(!registration_plan.empty(), "--registration-plan", {Stage::kEvaluate}),
        only_for(!reference.empty(), "--reference", {Stage::kRegister}),
        only_for(reference_from_ground_truth, "--reference-from-ground-truth", {Stage::kRegister}),
        only_for(!reference_camera.empty(), "--reference-camera",
                 {Stage::kRegister, Stage::kEvaluate})})
    if (!s) return s;
  if (stage == Stage::kDepth && !intrinsics.empty() && !calibration_plan.empty())
    return Error{
        "--intrinsics and --calibration-plan exclude each other (both give the intrinsics)"};
  if (stage == Stage::kRegister) {
    const int given = !reference.empty() + reference_from_ground_truth + !calibration_plan.empty();
    if (given != 1)
      return Error{
          "--stage register needs exactly one of --reference MAP_DIR, "
          "--reference-from-ground-truth and --calibration-plan CAL_PLAN_DIR"};
  }
  if (stage == Stage::kEvaluate && registration_plan.empty())
    return Error{"--stage evaluate needs --registration-plan REG_PLAN_DIR (a register plan)"};
  return Status::Ok();
}

Expected<Plan> MakePlan(const PlanOptions& o) {
  if (Status s = o.Check(); !s) return s.error();
  const PerSpec per = *PerSpec::Parse(o.per.empty() ? DefaultPer(o.stage) : o.per);
  const std::string dataset = Absolute(o.dataset);

  // The sequences, by the dataset layer's rules.
  std::vector<SequenceLayout> sequences;
  switch (ClassifyPath(dataset)) {
    case PathKind::kDatasetRoot: {
      Expected<DatasetLayout> d = DiscoverDataset(dataset);
      if (!d) return d.error();
      for (SceneLayout& scene : d->scenes)
        for (SequenceLayout& seq : scene.sequences) sequences.push_back(std::move(seq));
      break;
    }
    case PathKind::kScene: {
      Expected<SceneLayout> scene = DiscoverScene(dataset);
      if (!scene) return scene.error();
      sequences = std::move(scene->sequences);
      break;
    }
    case PathKind::kSequence: {
      Expected<SequenceLayout> seq = DiscoverSequence(dataset);
      if (!seq) return seq.error();
      sequences.push_back(std::move(*seq));
      break;
    }
    default:
      return Error{dataset + ": " + std::string(ToString(ClassifyPath(dataset))) +
                   ", expected a dataset root, a scene or a sequence folder (lifmcr info " +
                   dataset + " says what it holds)"};
  }
  if (!o.sequences.empty()) {
    std::vector<SequenceLayout> chosen;
    for (SequenceLayout& seq : sequences)
      for (const std::string& want : o.sequences)
        if (want == seq.name || want == seq.scene + "/" + seq.name) {
          chosen.push_back(std::move(seq));
          break;
        }
    sequences = std::move(chosen);
  }
  if (sequences.empty()) return Error{dataset + ": no sequence to plan (after --sequence)"};

  std::optional<EarlierPlan> calibration, registration;
  if (!o.calibration_plan.empty()) {
    Expected<EarlierPlan> e =
        LoadEarlier(o.calibration_plan, Stage::kCalibrate, "--calibration-plan");
    if (!e) return e.error();
    calibration = std::move(*e);
  }
  if (!o.registration_plan.empty()) {
    Expected<EarlierPlan> e =
        LoadEarlier(o.registration_plan, Stage::kRegister, "--registration-plan");
    if (!e) return e.error();
    registration = std::move(*e);
  }
  for (std::optional<EarlierPlan>* e : {&calibration, &registration})
    if (*e)
      for (const Unit& u : (*e)->plan.units) (*e)->by_id[u.id] = &u;

  Plan plan;
  plan.stage = o.stage;
  plan.per = per.ToString();
  plan.dataset = dataset;
  plan.planned_by = o.planned_by;
  const std::string stage(ToString(o.stage));

  for (const SequenceLayout& seq : sequences) {
    if (!IsNamePart(seq.scene) || !IsNamePart(seq.name))
      return Error{seq.dir.string() +
                   ": scene and sequence names must be letters, digits, '.', "
                   "'_', '-' to name units (got '" +
                   Excerpt(seq.scene) + "/" + Excerpt(seq.name) + "')"};
    const std::string seq_id = seq.scene + "/" + seq.name;
    const std::string seq_dir = Absolute(seq.dir.string());
    std::vector<const CameraFolder*> cameras;
    for (const CameraFolder& c : seq.cameras)
      if (o.cameras.empty() ||
          std::find(o.cameras.begin(), o.cameras.end(), c.serial) != o.cameras.end())
        cameras.push_back(&c);
    if (seq.cameras.empty()) return Error{seq_dir + ": no camera folder (TypeE_<serial>/)"};
    const fs::path gt_yaml = layout::CamerasYamlPath(seq_dir);
    std::error_code ec;
    const bool has_gt_yaml = fs::is_regular_file(gt_yaml, ec);

    // Camera 0 of register and evaluate units, by the first rule that gives one:
    // --reference-camera; register --reference MAP_DIR: the map's camera (the
    // one camera of its intrinsics.yaml, which lifmcr calibrate writes beside
    // the map); evaluate: the camera 0 of the register plan's units; the
    // sequence's GroundTruth/cameras.yaml's first camera (lifmcr synth lists
    // camera 0 first, and evaluate and register --reference-from-ground-truth
    // take it); the sequence's first camera by serial.
    std::string reference;
    if (o.stage == Stage::kRegister || o.stage == Stage::kEvaluate) {
      reference = o.reference_camera;
      if (o.reference_from_ground_truth) {
        // lifmcr register builds that map from the ground truth's first camera.
        Expected<std::vector<std::string>> serials = synth::ReadCameraSerialsYaml(gt_yaml);
        if (!serials)
          return Error{serials.error().message + " (--reference-from-ground-truth reads it)"};
        if (serials->empty()) return Error{gt_yaml.string() + ": lists no camera"};
        if (!reference.empty() && reference != serials->front())
          return Error{"--reference-camera " + reference + ": the ground-truth map is camera " +
                       serials->front() + "'s (the first of " + gt_yaml.string() + ")"};
        reference = serials->front();
      }
      if (reference.empty() && o.stage == Stage::kRegister && !o.reference.empty()) {
        const fs::path map_yaml = fs::path(Absolute(o.reference)) / "intrinsics.yaml";
        Expected<std::vector<std::string>> serials = synth::ReadCameraSerialsYaml(map_yaml);
        if (!serials || serials->size() != 1)
          return Error{"--reference " + o.reference + ": " +
                       (serials ? map_yaml.string() + " names " + std::to_string(serials->size()) +
                                      " cameras"
                                : serials.error().message) +
                       "; give the map's camera with --reference-camera SERIAL"};
        reference = serials->front();
      }
      if (reference.empty() && registration) {
        for (const Unit& r : registration->plan.units) {
          if (r.scene != seq.scene || r.sequence != seq.name || r.reference.empty()) continue;
          if (!reference.empty() && r.reference != reference)
            return Error{"--registration-plan " + registration->dir + ": its units of " + seq_id +
                         " register to cameras " + reference + " and " + r.reference +
                         "; give --reference-camera SERIAL"};
          reference = r.reference;
        }
      }
      if (reference.empty() && has_gt_yaml) {
        Expected<std::vector<std::string>> serials = synth::ReadCameraSerialsYaml(gt_yaml);
        if (!serials) return Error{serials.error().message + " (camera 0 is its first camera)"};
        if (serials->empty()) return Error{gt_yaml.string() + ": lists no camera"};
        reference = serials->front();
      }
      if (reference.empty()) reference = seq.cameras.front().serial;
      bool reference_found = false;
      for (const CameraFolder& c : seq.cameras) reference_found |= c.serial == reference;
      if (!reference_found)
        return Error{seq_dir + ": no camera folder of the reference camera " + reference};
    }

    // A unit of the calibration plan (the camera's, in this sequence).
    auto calibration_unit = [&](const std::string& serial) -> const Unit* {
      if (!calibration) return nullptr;
      const auto it = calibration->by_id.find(seq_id + "/" + serial);
      return it == calibration->by_id.end() ? nullptr : it->second;
    };
    auto unit_dir = [](const EarlierPlan& e, const Unit& u) {
      return (fs::path(e.dir) / u.outputs).string();
    };

    auto add_unit = [&](Unit u) {
      u.scene = seq.scene;
      u.sequence = seq.name;
      u.outputs = "units/" + u.id;
      u.command.insert(u.command.end(), o.extra.begin(), o.extra.end());
      plan.units.push_back(std::move(u));
    };

    if (o.stage == Stage::kDepth) {
      for (const CameraFolder* c : cameras) {
        std::vector<std::string> intrinsics_args;
        std::vector<UnitNeed> needs;
        if (o.intrinsics == "ground-truth") {
          if (!has_gt_yaml)
            return Error{gt_yaml.string() +
                         ": missing (--intrinsics ground-truth reads each "
                         "sequence's GroundTruth/cameras.yaml)"};
          intrinsics_args = {"--intrinsics", gt_yaml.string()};
        } else if (!o.intrinsics.empty()) {
          intrinsics_args = {"--intrinsics", Absolute(o.intrinsics)};
        } else if (calibration) {
          const Unit* cal = calibration_unit(c->serial);
          if (!cal)
            return Error{"--calibration-plan " + calibration->dir + ": no unit for camera " +
                         c->serial + " of " + seq_id};
          intrinsics_args = {"--intrinsics", unit_dir(*calibration, *cal) + "/intrinsics.yaml"};
          needs.push_back({calibration->dir, cal->id});
        }
        if (c->frames.empty()) continue;
        const std::size_t chunk = per.kind == PerSpec::Kind::kCamera
                                      ? c->frames.size()
                                      : static_cast<std::size_t>(per.frames);
        for (std::size_t first = 0; first < c->frames.size(); first += chunk) {
          const std::size_t last = std::min(first + chunk, c->frames.size()) - 1;
          Unit u;
          u.camera = c->serial;
          u.id = seq_id + "/" + c->serial;
          if (per.kind == PerSpec::Kind::kFrames)
            u.id += "/" + Frame6(c->frames[first]) + "-" + Frame6(c->frames[last]);
          u.command = {"lifmcr", "depth", seq_dir, "--camera", c->serial, "--out", "units/" + u.id};
          u.command.insert(u.command.end(), intrinsics_args.begin(), intrinsics_args.end());
          if (per.kind == PerSpec::Kind::kCamera) {
            u.command.push_back("--all-frames");
          } else {
            u.command.push_back("--frame");
            for (std::size_t k = first; k <= last; ++k)
              u.command.push_back(std::to_string(c->frames[k]));
          }
          for (std::size_t k = first; k <= last; ++k) {
            const std::string name = layout::VirtualDepthFileName(c->serial, c->frames[k]);
            const std::string stem =
                name.substr(0, name.size() - std::string("_virtual_depth.tiff").size());
            std::vector<std::string> suffixes = {"_virtual_depth.tiff", "_virtual_depth_tf.tiff",
                                                 "_confidence.tiff",    "_tf.png",
                                                 "_depth.png",          "_lens_depth.csv",
                                                 "_lens_depth.tiff",    "_lens_tf.png"};
            if (!intrinsics_args.empty()) {
              suffixes.push_back("_depth_mm.tiff");
              suffixes.push_back("_points.ply");
            }
            for (const std::string& s : suffixes)
              u.writes.push_back("units/" + u.id + "/" + stem + s);
          }
          u.needs = needs;
          add_unit(std::move(u));
        }
      }
    } else if (o.stage == Stage::kCalibrate) {
      for (const CameraFolder* c : cameras) {
        Unit u;
        u.camera = c->serial;
        u.id = seq_id + "/" + c->serial;
        u.command = {"lifmcr",  "calibrate", seq_dir,        "--camera",
                     c->serial, "--out",     "units/" + u.id};
        for (const char* f : {"intrinsics.yaml", "calibration_report.md"})
          u.writes.push_back("units/" + u.id + "/" + f);
        u.writes.push_back("units/" + u.id + "/" + layout::PosesCsvFileName(c->serial));
        add_unit(std::move(u));
      }
    } else if (o.stage == Stage::kRegister) {
      std::vector<std::string> reference_args;
      std::vector<UnitNeed> needs;
      if (o.reference_from_ground_truth) {
        reference_args = {"--reference-from-ground-truth"};
      } else if (!o.reference.empty()) {
        reference_args = {"--reference", Absolute(o.reference)};
      } else {
        const Unit* cal = calibration_unit(reference);
        if (!cal)
          return Error{"--calibration-plan " + calibration->dir +
                       ": no unit for the reference camera " + reference + " of " + seq_id};
        reference_args = {"--reference", unit_dir(*calibration, *cal), "--intrinsics",
                          unit_dir(*calibration, *cal) + "/intrinsics.yaml"};
        needs.push_back({calibration->dir, cal->id});
        // Every other camera's own calibration where the plan has one, the
        // sequence's ground truth for the rest (lifmcr register takes each
        // camera from the first --intrinsics file that has it).
        bool all = true;
        for (const CameraFolder& c : seq.cameras) {
          if (c.serial == reference) continue;
          if (const Unit* other = calibration_unit(c.serial)) {
            reference_args.push_back("--intrinsics");
            reference_args.push_back(unit_dir(*calibration, *other) + "/intrinsics.yaml");
            needs.push_back({calibration->dir, other->id});
          } else {
            all = false;
          }
        }
        if (!all) {
          if (!has_gt_yaml)
            return Error{"--calibration-plan " + calibration->dir +
                         " calibrates not every camera of " + seq_id + " and " + gt_yaml.string() +
                         " is missing: no intrinsics for the rest"};
          reference_args.push_back("--intrinsics");
          reference_args.push_back(gt_yaml.string());
        }
      }
      if (per.kind == PerSpec::Kind::kSequence) {
        Unit u;
        u.id = seq_id;
        u.reference = reference;
        u.command = {"lifmcr", "register", seq_dir, "--out", "units/" + u.id};
        for (const CameraFolder* c : cameras) {
          if (!o.cameras.empty()) {
            u.command.push_back("--camera");
            u.command.push_back(c->serial);
          }
        }
        u.command.insert(u.command.end(), reference_args.begin(), reference_args.end());
        u.writes = {"units/" + u.id + "/registration.csv"};
        u.needs = needs;
        add_unit(std::move(u));
      } else {
        for (const CameraFolder* c : cameras) {
          if (c->serial == reference) continue;  // registered in every unit as camera 0
          Unit u;
          u.camera = c->serial;
          u.reference = reference;
          u.id = seq_id + "/" + c->serial;
          u.command = {"lifmcr",  "register", seq_dir,        "--camera",
                       c->serial, "--out",    "units/" + u.id};
          u.command.insert(u.command.end(), reference_args.begin(), reference_args.end());
          u.writes = {"units/" + u.id + "/registration.csv"};
          u.needs = needs;
          add_unit(std::move(u));
        }
      }
    } else {  // evaluate
      Unit u;
      u.id = seq_id;
      u.reference = reference;
      u.command = {"lifmcr",        "evaluate",    seq_dir,  "--out",
                   "units/" + u.id, "--reference", reference};
      for (const Unit& r : registration->plan.units) {
        if (r.scene != seq.scene || r.sequence != seq.name) continue;
        u.command.push_back("--registration");
        u.command.push_back(unit_dir(*registration, r) + "/registration.csv");
        u.needs.push_back({registration->dir, r.id});
      }
      if (u.needs.empty())
        return Error{"--registration-plan " + registration->dir + ": no unit for " + seq_id};
      if (calibration) {
        const Unit* cal = calibration_unit(reference);
        if (!cal)
          return Error{"--calibration-plan " + calibration->dir +
                       ": no unit for the reference camera " + reference + " of " + seq_id};
        u.command.insert(
            u.command.end(),
            {"--map", unit_dir(*calibration, *cal), "--reference-poses",
             unit_dir(*calibration, *cal) + "/" + layout::PosesCsvFileName(reference)});
        u.needs.push_back({calibration->dir, cal->id});
      }
      u.writes = {"units/" + u.id + "/evaluation.md", "units/" + u.id + "/evaluation.json"};
      u.done_exits = {0, 3};
      add_unit(std::move(u));
    }
  }
  if (plan.units.empty())
    return Error{dataset + ": the " + stage + " plan has no unit (no camera matched --camera?)"};
  return plan;
}

}  // namespace lifmcr::batch
