// libFuzzer target: JSON values given on the command line. The input is the text of one value,
// taken the ways the commands take it: as VALUE of --set TAG.PARAM=VALUE for a stage parameter,
// a parameter that does not exist, ground / frame / ensemble keys (LoadGraph: parse, merge,
// validation against the build tree's plugins, the messages that quote the value), as PARAMS of
// `gap --sensor NAME=PARAMS` (resolved against the training sensor's schema) and as `simulate
// --sensor-params`. Anything but InputError (or a StageError of bad input) is a finding.
#include "fuzz_common.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/host/pipeline.hpp"

namespace {
const furnihost::Registry& Reg() {
  static const furnihost::Registry reg = [] {
    furnihost::fuzz::Dir();  // silences logs before plugins are scanned
    return furnihost::Registry(std::vector<std::string>{FURNIHOST_FUZZ_PLUGIN_DIR});
  }();
  return reg;
}

const std::string& Graph() {
  static const std::string path = [] {
    const std::string g =
        R"({"seed": 1, "training": {"sensor": "sim"}, "stages": {"input": {"type": "sensors.scan_file"},)"
        R"( "sim": {"type": "sensors.simulated_laser"}}})";
    return furnihost::fuzz::Write("g.json", g.data(), g.size());
  }();
  return path;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& reg = Reg();
  const std::string value(reinterpret_cast<const char*>(data), size);
  static const char* const kKeys[] = {"input.voxel_m", "input.origin", "input.nope",     "sim.preset",
                                      "sim.presets",   "ground.kind",  "frame.canonical", "ensemble.runs"};
  for (const char* key : kKeys) {
    try {
      const furnihost::GraphConfig g = furnihost::LoadGraph(Graph(), reg, {std::string(key) + "=" + value});
      (void)g.resolved.dump();
      furnihost::Pipeline p(g, reg);
    } catch (const furnihost::InputError&) {
    } catch (const furnihost::StageError& e) {
      if (!e.IsInputError()) throw;
    }
  }
  const furnihost::PluginEntry* sim = reg.Find("sensors.simulated_laser");
  for (const char* option : {"--sensor x", "--sensor-params"}) {
    try {
      const nlohmann::json j = furnihost::ParseCliJson(value, option);
      if (sim && j.is_object()) (void)sim->params.Resolve(j, option).dump();
    } catch (const furnihost::InputError&) {
    } catch (const furnihost::StageError& e) {
      if (!e.IsInputError()) throw;
    }
  }
  return 0;
}
