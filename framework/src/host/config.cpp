#include "furnihost/host/config.hpp"

#include <algorithm>
#include <filesystem>
#include <functional>
#include <map>
#include <set>

#include "furnihost/host/io.hpp"
#include "host/graph/stage_kinds.hpp"
#include "sdk/shown.hpp"

namespace fs = std::filesystem;

namespace furnihost {

using detail::Clipped;
using detail::Shown;

namespace {

const std::vector<std::string> kTopKeys = {"extends", "description", "comment", "seed", "threads",
                                           "catalog", "model_cache", "training", "stages", "limits",
                                           "ground", "frame", "ensemble", "calibration"};
const std::vector<std::string> kStageKeys = {"type", "inputs", "params", "comment"};
const std::vector<std::string> kTrainingKeys = {"sensor", "comment"};
const std::vector<std::string> kLimitKeys = {"max_points", "max_grid_cells", "comment"};

// Resource limits: each caps the parameter of that name of every stage of that kind which
// declares it, so one line of a config bounds the memory of whatever plugins it uses. A stage
// left at its default gets the limit; one that asks for more is refused.
struct LimitRule {
  const char* key;
  StageKind kind;
};
const LimitRule kLimitRules[] = {{"max_points", StageKind::Sensor},        // points per scan
                                 {"max_grid_cells", StageKind::Voter}};    // vote grid size

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

void CheckKeys(const nlohmann::json& obj, const std::vector<std::string>& allowed, const std::string& where) {
  for (auto it = obj.begin(); it != obj.end(); ++it)
    if (std::find(allowed.begin(), allowed.end(), it.key()) == allowed.end())
      throw InputError(where + "/" + it.key() + ": unknown key; valid: " + Join(allowed));
}

// Makes path-valued keys absolute relative to the file that sets them, so a variant that
// extends a base in another folder keeps the base's paths.
void AbsolutisePaths(nlohmann::json& j, const fs::path& dir) {
  auto absolute = [&](nlohmann::json& value) {
    if (!value.is_string()) return;
    const fs::path p = value.get<std::string>();
    if (!p.empty() && p.is_relative()) value = (dir / p).lexically_normal().string();
  };
  for (const char* key : {"catalog", "model_cache"})
    if (j.contains(key)) absolute(j[key]);
  if (j.contains("calibration") && j["calibration"].is_object() && j["calibration"].contains("file"))
    absolute(j["calibration"]["file"]);
}

nlohmann::json LoadRecursive(const std::string& path, std::vector<std::string>& chain) {
  std::error_code ec;
  std::string canon = fs::weakly_canonical(path, ec).string();
  if (std::find(chain.begin(), chain.end(), canon) != chain.end())
    throw InputError(path + ": extends loop: " + Join(chain) + ", " + canon);
  if (chain.size() > 32) throw InputError(path + ": extends chain deeper than 32 files");
  chain.push_back(canon);
  nlohmann::json j = ReadJson(path);
  if (!j.is_object()) throw InputError(path + ": expected a JSON object at the top level, got " + Shown(j));
  AbsolutisePaths(j, fs::path(path).parent_path());
  if (j.contains("extends")) {
    const auto& ext = j["extends"];
    if (!ext.is_string()) throw InputError(path + ":/extends: expected a file name string, got " + Shown(ext));
    fs::path base = fs::path(path).parent_path() / ext.get<std::string>();
    std::error_code exists_ec;  // a name too long or not searchable is a bad extends, not a crash
    if (!fs::exists(base, exists_ec))
      throw InputError(path + ":/extends: unknown base config " + base.string() + " (" +
                       (exists_ec ? exists_ec.message() : std::string("no such file")) + ")");
    nlohmann::json b = LoadRecursive(base.string(), chain);
    j.erase("extends");
    j = MergePatch(std::move(b), j);
  }
  chain.pop_back();
  return j;
}

}  // namespace

nlohmann::json MergePatch(nlohmann::json target, const nlohmann::json& patch) {
  if (!patch.is_object()) return patch;
  if (!target.is_object()) target = nlohmann::json::object();
  for (auto it = patch.begin(); it != patch.end(); ++it) {
    if (it.value().is_null())
      target.erase(it.key());
    else
      target[it.key()] = MergePatch(target.contains(it.key()) ? target[it.key()] : nlohmann::json(), it.value());
  }
  return target;
}

nlohmann::json LoadConfigJson(const std::string& path) {
  std::vector<std::string> chain;
  return LoadRecursive(path, chain);
}

const StageConfig* GraphConfig::Find(const std::string& tag) const {
  for (const auto& s : stages)
    if (s.tag == tag) return &s;
  return nullptr;
}

const StageConfig* GraphConfig::FirstOfKind(StageKind kind) const {
  auto all = AllOfKind(kind);
  return all.empty() ? nullptr : all.front();
}

std::vector<const StageConfig*> GraphConfig::AllOfKind(StageKind kind) const {
  std::vector<const StageConfig*> out;
  for (const auto& s : stages)
    if (s.kind == kind && s.tag != training_sensor) out.push_back(&s);
  return out;
}

const StageConfig* GraphConfig::InputOfKind(const StageConfig& s, StageKind kind) const {
  for (const auto& in : s.inputs)
    if (const StageConfig* c = Find(in); c && c->kind == kind) return c;
  return nullptr;
}

const StageConfig* GraphConfig::Input(const StageConfig& s, InputRole role) const {
  const graph::KindRule& rule = graph::RuleOf(s.kind);
  for (const auto& in : s.inputs)
    if (const StageConfig* c = Find(in))
      if (const graph::Slot* slot = graph::SlotFor(rule, c->kind); slot && slot->role == role) return c;
  return nullptr;
}

const StageConfig* GraphConfig::SegmenterOf(const StageConfig& s) const {
  return graph::SegmenterOf(s, [this](const std::string& tag) { return Find(tag); }, stages.size());
}

const StageConfig* GraphConfig::ChainRoot(const StageConfig& s) const {
  const StageConfig* c = &s;
  // Validation refuses cycles; the bound only guards a graph built by hand.
  for (size_t hops = 0; c && hops <= stages.size(); ++hops)
    if (const StageConfig* in = Input(*c, InputRole::Detections)) c = in;
    else return graph::RuleOf(c->kind).detections ? c : nullptr;
  return nullptr;
}

std::vector<const StageConfig*> GraphConfig::Trained() const {
  std::vector<const StageConfig*> out;
  for (const auto& s : stages)
    if (graph::RuleOf(s.kind).trained) out.push_back(&s);
  return out;
}

std::vector<const StageConfig*> GraphConfig::Sinks() const {
  std::set<std::string> fed;  // stages some stage takes as its detections
  for (const auto& s : stages)
    if (const StageConfig* in = Input(s, InputRole::Detections)) fed.insert(in->tag);
  std::vector<const StageConfig*> out;
  for (const auto& s : stages)
    if (graph::RuleOf(s.kind).detections && !fed.count(s.tag)) out.push_back(&s);
  return out;
}

GraphConfig ValidateGraph(const std::string& path, const nlohmann::json& config, const Registry& registry) {
  const std::string w = path + ":";
  if (!config.is_object()) throw InputError(w + " expected a JSON object, got " + Shown(config));
  CheckKeys(config, kTopKeys, w);
  GraphConfig g;
  g.path = path;
  nlohmann::json resolved = config;

  if (config.contains("seed")) {
    const auto& s = config["seed"];
    if (!s.is_number_unsigned()) throw InputError(w + "/seed: expected a non-negative integer, got " + Shown(s));
    g.seed = s.get<uint64_t>();
  }
  resolved["seed"] = g.seed;
  if (config.contains("threads") && !(config["threads"].is_number_unsigned() && config["threads"].get<uint64_t>() <= 1024))
    throw InputError(w + "/threads: expected an integer in [0, 1024], got " + Shown(config["threads"]));
  for (const char* key : {"catalog", "model_cache", "description"}) {
    if (config.contains(key) && !config[key].is_string())
      throw InputError(w + "/" + key + ": expected a string, got " + Shown(config[key]));
  }
  // Before anything runs (a typo in the ground's kind must not surface after training).
  g.ground = GroundOptionsFromJson(config.value("ground", nlohmann::json()), w + "/ground");
  resolved["ground"] = ToJson(g.ground);
  g.frame = FrameSectionFromJson(config.value("frame", nlohmann::json()), w + "/frame");
  resolved["frame"] = ToJson(g.frame);
  g.ensemble = EnsembleOptionsFromJson(config.value("ensemble", nlohmann::json()), w + "/ensemble");
  resolved["ensemble"] = ToJson(g.ensemble);
  g.calibration = CalibrationSectionFromJson(config.value("calibration", nlohmann::json()), w + "/calibration");
  resolved["calibration"] = ToJson(g.calibration);
  if (!g.calibration.file.empty()) {
    try {
      g.calibration_map = std::make_shared<const Calibration>(Calibration::Load(g.calibration.file));
    } catch (const InputError& e) {
      throw InputError(w + "/calibration/file: " + e.what());
    }
  }
  if (config.contains("catalog")) g.catalog = config["catalog"].get<std::string>();
  if (config.contains("model_cache")) g.model_cache = config["model_cache"].get<std::string>();
  if (config.contains("limits")) {
    const auto& l = config["limits"];
    if (!l.is_object()) throw InputError(w + "/limits: expected an object, got " + Shown(l));
    CheckKeys(l, kLimitKeys, w + "/limits");
    for (const auto& rule : kLimitRules)
      if (l.contains(rule.key) && !(l[rule.key].is_number_unsigned() && l[rule.key].get<uint64_t>() > 0))
        throw InputError(w + "/limits/" + rule.key + ": expected a positive integer, got " + Shown(l[rule.key]));
  }

  if (!config.contains("stages")) throw InputError(w + "/stages: missing (an object of stages keyed by tag)");
  const auto& stages = config["stages"];
  if (!stages.is_object())
    throw InputError(w + "/stages: expected an object keyed by stage tag, got " + Shown(stages));
  if (stages.empty()) throw InputError(w + "/stages: no stages");

  // First pass: structure and plugin names, collecting every missing plugin for one message.
  // Letters, digits, _ and -, checked character by character: std::regex_match recursed once
  // per character and overflowed the stack on a 32 kB tag (fuzz_graph_config finding).
  auto valid_tag = [](const std::string& t) {
    return !t.empty() && std::all_of(t.begin(), t.end(), [](char c) {
      return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    });
  };
  std::vector<std::string> missing;
  std::string first_missing_at;
  for (auto it = stages.begin(); it != stages.end(); ++it) {
    const std::string at = w + "/stages/" + it.key();
    if (!valid_tag(it.key()))
      throw InputError(w + "/stages/" + Clipped(it.key()) + ": stage tags may use letters, digits, _ and - only");
    const auto& st = it.value();
    if (!st.is_object()) throw InputError(at + ": expected an object, got " + Shown(st));
    CheckKeys(st, kStageKeys, at);
    if (!st.contains("type") || !st["type"].is_string())
      throw InputError(at + "/type: expected a plugin type name such as \"segmenters.region_growing\"");
    const std::string type = st["type"].get<std::string>();
    if (!KindFromTypeName(type))
      throw InputError(at + "/type: '" + type + "' is not <kind>s.<name> (" + KindTypePrefixes() + " and a name)");
    if (!registry.Find(type)) {
      if (missing.empty()) first_missing_at = at + "/type";
      if (std::find(missing.begin(), missing.end(), type) == missing.end()) missing.push_back(type);
    }
    if (st.contains("inputs")) {
      const auto& in = st["inputs"];
      bool ok = in.is_array();
      if (ok) for (const auto& x : in) ok = ok && x.is_string();
      if (!ok) throw InputError(at + "/inputs: expected a list of stage tags, got " + Shown(in));
    }
  }
  if (!missing.empty()) {
    std::string known = Join(registry.TypeNames());
    const size_t refused = registry.Refusals().size();
    throw InputError(first_missing_at + ": missing plugin" + (missing.size() > 1 ? "s " : " ") + Join(missing) +
                     "; known: " + (known.empty() ? "(none found)" : known) +
                     (refused ? "; " + std::to_string(refused) + " librar" + (refused > 1 ? "ies were" : "y was") +
                                    " refused (see the warnings above)"
                              : std::string()));
  }

  // Second pass: parameters and connections.
  std::map<std::string, StageConfig> by_tag;
  for (auto it = stages.begin(); it != stages.end(); ++it) {
    StageConfig s;
    s.tag = it.key();
    s.pointer = "/stages/" + it.key();
    s.type = it.value()["type"].get<std::string>();
    s.kind = registry.Find(s.type)->kind;
    s.version = registry.Find(s.type)->version;
    if (it.value().contains("inputs")) s.inputs = it.value()["inputs"].get<std::vector<std::string>>();
    const ParamSchema& schema = registry.Find(s.type)->params;
    s.params = schema.Resolve(it.value().contains("params") ? it.value()["params"] : nlohmann::json(),
                              w + s.pointer + "/params");
    s.training_params = schema.TrainingParams(s.params);
    for (const auto& rule : kLimitRules) {
      const ParamSpec* spec = schema.Find(rule.key);
      if (s.kind != rule.kind || !spec || spec->type != ParamType::Int || !config.contains("limits") ||
          !config["limits"].contains(rule.key))
        continue;
      const uint64_t limit = config["limits"][rule.key].get<uint64_t>();
      if (spec->min && static_cast<double>(limit) < *spec->min)
        throw InputError(w + "/limits/" + rule.key + ": " + std::to_string(limit) + " is below the smallest " +
                         rule.key + " stage '" + s.tag + "' (" + s.type + ") accepts, " +
                         std::to_string(static_cast<long long>(*spec->min)));
      const bool given = it.value().contains("params") && it.value()["params"].is_object() &&
                         it.value()["params"].contains(rule.key);
      if (given && s.params[rule.key].get<double>() > static_cast<double>(limit))
        throw InputError(w + s.pointer + "/params/" + rule.key + ": " + s.params[rule.key].dump() +
                         " exceeds /limits/" + rule.key + " = " + std::to_string(limit));
      if (!given)
        s.params[rule.key] = spec->max ? std::min<uint64_t>(limit, static_cast<uint64_t>(*spec->max)) : limit;
    }
    resolved["stages"][s.tag]["params"] = s.params;
    resolved["stages"][s.tag]["inputs"] = s.inputs;
    by_tag[s.tag] = s;
  }
  for (auto& [tag, s] : by_tag) graph::CheckInputs(s, by_tag, w + s.pointer + "/inputs");

  // Topological order; a cycle can only run through fitters but is checked generally.
  std::map<std::string, int> state;  // 0 new, 1 visiting, 2 done
  std::vector<std::string> order;
  std::function<void(const std::string&, std::vector<std::string>&)> visit =
      [&](const std::string& t, std::vector<std::string>& path_tags) {
        if (state[t] == 2) return;
        path_tags.push_back(t);
        if (state[t] == 1) throw InputError(w + "/stages: cycle in connections: " + Join(path_tags));
        state[t] = 1;
        for (const auto& in : by_tag[t].inputs) visit(in, path_tags);
        state[t] = 2;
        path_tags.pop_back();
        order.push_back(t);
      };
  for (const auto& [tag, _] : by_tag) {
    std::vector<std::string> p;
    visit(tag, p);
  }
  for (const auto& t : order) g.stages.push_back(by_tag[t]);

  if (config.contains("training")) {
    const auto& tr = config["training"];
    if (!tr.is_object()) throw InputError(w + "/training: expected an object, got " + Shown(tr));
    CheckKeys(tr, kTrainingKeys, w + "/training");
    if (tr.contains("sensor")) {
      if (!tr["sensor"].is_string()) throw InputError(w + "/training/sensor: expected a stage tag");
      g.training_sensor = tr["sensor"].get<std::string>();
      auto it = by_tag.find(g.training_sensor);
      if (it == by_tag.end()) throw InputError(w + "/training/sensor: unknown stage '" + g.training_sensor + "'");
      if (it->second.kind != StageKind::Sensor)
        throw InputError(w + "/training/sensor: '" + g.training_sensor + "' is a " + ToString(it->second.kind) + ", not a sensor");
      for (const auto& [t, s] : by_tag)
        for (const auto& in : s.inputs)
          if (in == g.training_sensor)
            throw InputError(w + s.pointer + "/inputs: '" + t + "' takes the training sensor '" + in +
                             "' as input; the detection chain must start at a file sensor");
    }
  }

  // Scans come in through one sensor; every other stage may fan out (see config.hpp).
  if (auto sensors = g.AllOfKind(StageKind::Sensor); sensors.size() > 1)
    throw InputError(w + "/stages/" + sensors[1]->tag + ": more than one sensor stage (" + sensors[0]->tag + ", " +
                     sensors[1]->tag + "); a graph reads its scans through one sensor (plus an optional training "
                     "sensor named by /training/sensor)");
  for (const auto& s : g.stages)
    graph::CheckParts(s, [&g](const std::string& tag) { return g.Find(tag); }, g.stages.size(),
                      w + s.pointer + "/inputs");
  if (const auto trained = g.Trained(); g.catalog.empty() && !trained.empty())
    throw InputError(w + "/catalog: missing (the catalog.json " + ToString(trained.front()->kind) + " '" +
                     trained.front()->tag + "' is trained from)");
  g.resolved = resolved;
  return g;
}

GraphConfig LoadGraph(const std::string& path, const Registry& registry, const std::vector<std::string>& sets) {
  nlohmann::json config = LoadConfigJson(path);
  struct Set {
    std::string text, pointer;
  };
  std::vector<Set> applied;
  for (const auto& s : sets) {
    const std::string where = "--set " + s;
    const size_t eq = s.find('='), dot = s.find('.');
    if (eq == std::string::npos || dot == std::string::npos || dot > eq || dot == 0 || dot + 1 == eq)
      throw InputError(where + ": expected TAG.PARAM=VALUE (e.g. vote.height_tolerance_m=0.2)");
    const std::string tag = s.substr(0, dot), key = s.substr(dot + 1, eq - dot - 1), text = s.substr(eq + 1);
    RequireUtf8(s, "--set");  // the override goes into run records
    const nlohmann::json value = ParseCliJson(text, "--set " + s.substr(0, eq), true);  // a bare word: a string
    if (tag == "ground" || tag == "frame" || tag == "ensemble" || tag == "calibration") {
      if (!config.contains(tag) || !config[tag].is_object()) config[tag] = nlohmann::json::object();
      config[tag][key] = value;
      applied.push_back({s.substr(0, eq), "/" + tag + "/" + key});
      continue;
    }
    if (!config.contains("stages") || !config["stages"].is_object() || !config["stages"].contains(tag)) {
      std::string tags;
      if (config.contains("stages") && config["stages"].is_object())
        for (auto it = config["stages"].begin(); it != config["stages"].end(); ++it) tags += (tags.empty() ? "" : ", ") + it.key();
      throw InputError(where + ": no stage '" + tag + "' in " + path + " (stages: " + tags + "; or ground, frame, ensemble, calibration)");
    }
    auto& st = config["stages"][tag];
    if (!st.is_object()) throw InputError(where + ": stage '" + tag + "' is not an object");
    if (!st.contains("params") || !st["params"].is_object()) st["params"] = nlohmann::json::object();
    st["params"][key] = value;
    applied.push_back({s.substr(0, eq), "/stages/" + tag + "/params/" + key});
  }
  try {
    GraphConfig g = ValidateGraph(path, config, registry);
    if (!sets.empty()) g.resolved["overrides"] = sets;
    return g;
  } catch (const InputError& e) {
    const std::string what = e.what();
    for (const auto& a : applied)
      if (what.find(":" + a.pointer) != std::string::npos) {
        std::string rest = what.substr(what.find(":" + a.pointer) + a.pointer.size() + 1);
        while (!rest.empty() && (rest[0] == ':' || rest[0] == ' ')) rest.erase(0, 1);
        throw InputError("--set " + a.text + ": " + rest);
      }
    throw;
  }
}

}  // namespace furnihost
