#include <iostream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/host/registry.hpp"

namespace furnihost::app {

namespace {

void PrintSpecs(const ParamSchema& schema) {
  for (const auto& s : schema.Specs()) {
    std::cout << "    " << s.name << " (" << ToString(s.type);
    std::cout << RangeText(s);
    if (!s.choices.empty()) {
      std::cout << ":";
      for (const auto& c : s.choices) std::cout << " " << c;
    }
    std::cout << ", default " << s.default_value.dump() << (s.training ? "" : ", detection only") << ")  " << s.help
              << (s.unit.empty() ? "" : " [" + s.unit + "]") << "\n";
  }
}

}  // namespace

int RunPlugins(const std::vector<std::string>& args) {
  CLI::App app{"List every plugin found (kind, type, version, path and parameters) and the parameters of the "
               "host's own sections of a graph config (ground, frame, ensemble).",
               "plugins"};
  CommonOptions common;
  bool as_json = false;
  common.Add(app, false);
  app.add_flag("--json", as_json, "print JSON instead of text");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  auto reg = common.MakeRegistry();
  if (as_json) {
    nlohmann::json j = {{"search_path", reg->SearchDirs()}, {"plugins", nlohmann::json::array()},
                        {"refused", nlohmann::json::array()}};
    for (const auto& p : reg->Plugins())
      j["plugins"].push_back({{"type", p.type}, {"kind", ToString(p.kind)}, {"version", p.version},
                              {"description", p.description}, {"path", p.path}, {"params", p.params.ToJson()}});
    for (const auto& r : reg->Refusals()) j["refused"].push_back({{"path", r.path}, {"reason", r.reason}});
    j["host_sections"] = nlohmann::json::object();
    for (const auto& [name, schema] : HostSectionSchemas()) j["host_sections"][name] = schema.ToJson();
    std::cout << DumpJson(j, 2) << "\n";
    return 0;
  }
  std::cout << reg->Plugins().size() << " plugins (search path:";
  for (const auto& d : reg->SearchDirs()) std::cout << " " << d;
  std::cout << ")\n";
  for (StageKind k : {StageKind::Sensor, StageKind::Segmenter, StageKind::Features, StageKind::Proposer, StageKind::Voter,
                      StageKind::Fitter}) {
    for (const auto& p : reg->Plugins()) {
      if (p.kind != k) continue;
      std::cout << "\n" << p.type << "  [" << ToString(p.kind) << ", v" << p.version << "]\n  " << p.description
                << "\n  " << p.path << "\n";
      PrintSpecs(p.params);
    }
  }
  std::cout << "\nhost sections of a graph config (\"ground\": {...} beside \"stages\")\n";
  for (const auto& [name, schema] : HostSectionSchemas()) {
    std::cout << "  " << name << "\n";
    PrintSpecs(schema);
  }
  for (const auto& r : reg->Refusals()) std::cout << "\nrefused: " << r.path << ": " << r.reason << "\n";
  return 0;
}

}  // namespace furnihost::app
