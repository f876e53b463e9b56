// libFuzzer target: graph configs. The input is split at "\n---\n" lines into g.json and the
// files it may extend (base.json, base2.json); the graph is loaded, validated against the
// plugins of the build tree and its stages are created. Anything but InputError, or a
// StageError of bad input from a plugin constructor, is a finding.
#include "fuzz_common.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/pipeline.hpp"

namespace {
const furnihost::Registry& Reg() {
  static const furnihost::Registry reg = [] {
    furnihost::fuzz::Dir();  // silences logs before plugins are scanned
    // Not test_plugins/bad: segmenters.throws throws by design.
    std::vector<std::string> dirs = {FURNIHOST_FUZZ_PLUGIN_DIR, FURNIHOST_FUZZ_TEST_PLUGIN_DIR "/outside"};
    return furnihost::Registry(dirs);
  }();
  return reg;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto& reg = Reg();
  const auto parts = furnihost::fuzz::Split(data, size);
  static const char* const kNames[] = {"g.json", "base.json", "base2.json"};
  for (size_t i = 0; i < 3; ++i) {
    const std::string& text = i < parts.size() ? parts[i] : std::string();
    furnihost::fuzz::Write(kNames[i], text.data(), text.size());
  }
  try {
    furnihost::GraphConfig g = furnihost::LoadGraph(furnihost::fuzz::Dir() + "/g.json", reg);
    (void)g.resolved.dump();
    furnihost::Pipeline p(g, reg);
    (void)furnihost::TrainingKey(g);
  } catch (const furnihost::InputError&) {
  } catch (const furnihost::StageError& e) {
    if (!e.IsInputError()) throw;
  }
  return 0;
}
