// The host's own sections of a graph config ("ground", "frame", "ensemble", "calibration"), each parameter
// declared once (ParamBinding) with its range and unit, as a plugin declares its parameters: the
// schema, the defaults (read from the structs), parsing and the errors come from one declaration.
#include <cmath>
#include <nlohmann/json.hpp>

#include "furnihost/host/calibration.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/params.hpp"
#include "sdk/shown.hpp"

namespace furnihost {

namespace {

const ParamBinding<GroundOptions>& GroundBinding() {
  static const auto b =
      ParamBinding<GroundOptions>()
          .Enum("kind", &GroundOptions::kind, {"auto", "level", "plane", "height_map", "fixed"},
                "auto: a height map where the scan shows enough floor, else a plane, else level; fixed: level at z_m")
          .Number("z_m", &GroundOptions::z_m, -1e4, 1e4, "m", "the floor's height in the scan's z-up frame (kind fixed)")
          .Number("cell_m", &GroundOptions::cell_m, 0.02, 2, "m", "height-map cell")
          .Number("step_m", &GroundOptions::step_m, 0, 1, "m", "largest floor height step between neighbouring cells")
          .Number("min_area_m2", &GroundOptions::min_area_m2, 0, 1e6, "m2",
                  "observed floor below which auto falls back to a plane")
          .Rule([](const GroundOptions& o) { return o.step_m > 0 ? "" : "step_m: must be above 0"; })
          .Rule([](const GroundOptions& o) { return std::isfinite(o.z_m) ? "" : "z_m: must be finite"; });
  return b;
}

const ParamBinding<FrameSection>& FrameBinding() {
  static const auto b =
      ParamBinding<FrameSection>()
          .Bool("canonical", &FrameSection::canonical,
                "stages see each scan in its canonical frame (its walls along x and y, its floor at z = 0); "
                "false: in its z-up frame as given")
          .Bool("level", &FrameSection::level, "level a tilted up axis on the floor");
  return b;
}

const ParamBinding<EnsembleOptions>& EnsembleBinding() {
  static const auto b =
      ParamBinding<EnsembleOptions>()
          .Int("runs", &EnsembleOptions::runs, 1, 64, "count",
               "detection runs: the scan as read and runs - 1 jittered copies, their detections fused")
          .Number("jitter_m", &EnsembleOptions::jitter_m, 0, 0.1, "m", "standard deviation of the copies' jitter")
          .Number("join_iou", &EnsembleOptions::join_iou, 0, 1, "1", "box IoU (axis-aligned) at which runs' detections join")
          .Rule([](const EnsembleOptions& e) { return e.jitter_m > 0 ? "" : "jitter_m: must be above 0"; })
          .Rule([](const EnsembleOptions& e) { return e.join_iou > 0 ? "" : "join_iou: must be above 0"; });
  return b;
}

const ParamBinding<CalibrationSection>& CalibrationBinding() {
  static const auto b =
      ParamBinding<CalibrationSection>()
          .String("file", &CalibrationSection::file,
                  "calibration file of scripts/calibrate.py, relative to the config naming it; \"\": none (the "
                  "stages' thresholds decide)")
          .Number("min_confidence", &CalibrationSection::min_confidence, 0, 1, "1",
                  "confidence at or above which a detection of a calibrated class is accepted")
          .StringList("part_of", &CalibrationSection::part_of,
                      "PART:WHOLE class pairs, comma-separated (\"chair:sofa\"): a PART detection whose box lies "
                      "inside an accepted WHOLE detection's (part_share of its volume) is dropped when the WHOLE is "
                      "at least as probable as the PART detections inside it together (a sofa's seat read as an "
                      "armchair); \"\": none")
          .Number("part_share", &CalibrationSection::part_share, 0.05, 1, "1",
                  "share of a PART detection's box volume inside a WHOLE detection's box that puts it inside (part_of)");
  return b;
}

// A section as written: null (the defaults) or an object, whose "comment" is the reader's.
template <class O>
O ParseSection(const ParamBinding<O>& binding, const nlohmann::json& j, const std::string& where, const char* example) {
  if (j.is_null()) return O{};
  if (!j.is_object()) throw InputError(where + ": expected an object such as " + example + ", got " + detail::Shown(j));
  nlohmann::json given = j;
  given.erase("comment");
  return binding.Parse(given, where);
}

}  // namespace

GroundOptions GroundOptionsFromJson(const nlohmann::json& j, const std::string& where) {
  return ParseSection(GroundBinding(), j, where, "{\"kind\": \"auto\"}");
}

void GroundOptions::Check(const std::string& where) const {
  // `where` ends with ": " (a command-line option) or "/" (a pointer): the binding's messages
  // start with the section's location.
  std::string at = where;
  while (!at.empty() && (at.back() == ' ' || at.back() == ':' || at.back() == '/')) at.pop_back();
  GroundBinding().Parse(ToJson(*this), at);
}

nlohmann::json ToJson(const GroundOptions& o) {
  return {{"kind", o.kind}, {"z_m", o.z_m}, {"cell_m", o.cell_m}, {"step_m", o.step_m}, {"min_area_m2", o.min_area_m2}};
}

FrameSection FrameSectionFromJson(const nlohmann::json& j, const std::string& where) {
  return ParseSection(FrameBinding(), j, where, "{\"canonical\": true}");
}

nlohmann::json ToJson(const FrameSection& f) { return {{"canonical", f.canonical}, {"level", f.level}}; }

EnsembleOptions EnsembleOptionsFromJson(const nlohmann::json& j, const std::string& where) {
  return ParseSection(EnsembleBinding(), j, where, "{\"runs\": 5}");
}

nlohmann::json ToJson(const EnsembleOptions& e) {
  return {{"runs", e.runs}, {"jitter_m", e.jitter_m}, {"join_iou", e.join_iou}};
}

CalibrationSection CalibrationSectionFromJson(const nlohmann::json& j, const std::string& where) {
  CalibrationSection c = ParseSection(CalibrationBinding(), j, where, "{\"file\": \"calibration/scannet.json\"}");
  c.part_pairs = PartOfPairs(c.part_of, where + "/part_of");  // throws on a malformed pair
  return c;
}

nlohmann::json ToJson(const CalibrationSection& c) {
  std::string pairs;
  for (const auto& p : c.part_of) pairs += (pairs.empty() ? "" : ", ") + p;
  return {{"file", c.file}, {"min_confidence", c.min_confidence}, {"part_of", pairs}, {"part_share", c.part_share}};
}

std::vector<std::pair<std::string, ParamSchema>> HostSectionSchemas() {
  return {{"ground", GroundBinding().Schema()},
          {"frame", FrameBinding().Schema()},
          {"ensemble", EnsembleBinding().Schema()},
          {"calibration", CalibrationBinding().Schema()}};
}

}  // namespace furnihost
