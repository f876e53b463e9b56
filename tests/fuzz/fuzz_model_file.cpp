// libFuzzer target: LoadModel (magic line + CBOR) on arbitrary bytes, then the checks the
// host runs on a loaded model. Anything but InputError is a finding.
#include "fuzz_common.hpp"
#include "furnihost/host/pipeline.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = furnihost::fuzz::Write("model.fhm", reinterpret_cast<const char*>(data), size);
  try {
    furnihost::TrainedModel m = furnihost::LoadModel(path);
    furnihost::GraphConfig g;
    g.path = "fuzz.json";
    (void)furnihost::Incompatibility(m, g, "0123456789abcdef");
    for (const auto& [tag, voter] : m.voters) {
      furnihost::FeatureMatrix f;
      f.values.setConstant(2, static_cast<Eigen::Index>(voter.normaliser.min.size()), 0.5f);
      voter.normaliser.Apply(f);
    }
  } catch (const furnihost::InputError&) {
  }
  return 0;
}
