#include "furnihost/host/model_file.hpp"

#include <fstream>
#include <iterator>

#include "furnihost/host/io.hpp"

namespace furnihost {

namespace {
constexpr auto& kMagic = kModelMagic;

// nlohmann's CBOR reader recurses once per nesting level, so a tampered model of 10^6 nested
// arrays overflows the stack. This DOM builder stops the reader at a depth no model needs.
class DepthLimitedSax : public nlohmann::detail::json_sax_dom_parser<nlohmann::json> {
 public:
  static constexpr int kMaxDepth = 256;
  explicit DepthLimitedSax(nlohmann::json& j) : json_sax_dom_parser(j, true) {}
  bool start_object(std::size_t n) { return Enter() && json_sax_dom_parser::start_object(n); }
  bool start_array(std::size_t n) { return Enter() && json_sax_dom_parser::start_array(n); }
  bool end_object() { --depth_; return json_sax_dom_parser::end_object(); }
  bool end_array() { --depth_; return json_sax_dom_parser::end_array(); }
  bool too_deep = false;

 private:
  bool Enter() {
    too_deep = ++depth_ > kMaxDepth;
    return !too_deep;
  }
  int depth_ = 0;
};

nlohmann::json ReadCbor(const std::string& path) {
  RequireRegularFile(path, "model file");
  std::ifstream in(path, std::ios::binary);
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t ml = sizeof(kMagic) - 1;
  if (data.size() < ml || data.compare(0, ml, kMagic) != 0)
    throw InputError(path + ": not a furnihost model file (bad magic)");
  nlohmann::json j;
  try {
    DepthLimitedSax sax(j);
    const bool ok = nlohmann::json::sax_parse(data.begin() + ml, data.end(), &sax, nlohmann::json::input_format_t::cbor);
    if (sax.too_deep)
      throw InputError(path + ": corrupt model file (nested deeper than " + std::to_string(DepthLimitedSax::kMaxDepth) +
                       " levels); delete it to retrain");
    if (!ok) throw InputError(path + ": corrupt or truncated model file; delete it to retrain");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path + ": corrupt or truncated model file (" + std::string(e.what()) + "); delete it to retrain");
  }
  return j;
}

TrainedVoter ReadVoter(const std::string& path, const nlohmann::json& j, const std::string& tag) {
  TrainedVoter v;
  v.voter_type = j.at("voter_type").get<std::string>();
  v.normaliser = Normaliser::FromJson(j.at("normaliser"));
  if (!v.normaliser.min.allFinite() || !v.normaliser.max.allFinite())
    throw InputError(path + ": corrupt model file (non-finite normaliser" +
                     (tag.empty() ? std::string() : " of voter '" + tag + "'") + "); delete it to retrain");
  v.voter_model = j.at("voter_model");
  return v;
}

// A version 1 file of one voter: its voter's fields at the top and its training key's voter
// parts ({seed, training_sensor, segmenter, features, voter}) beside the seed, without a tag.
// Upgraded to the layout of several voters, the voter's tag "".
void UpgradeSingleVoter(const std::string& path, const nlohmann::json& j, TrainedModel& m) {
  m.voters[""] = ReadVoter(path, j, "");
  nlohmann::json key = nlohmann::json::object(), voter = nlohmann::json::object();
  for (auto it = m.training_config.begin(); it != m.training_config.end(); ++it)
    (it.key() == "seed" || it.key() == "training_sensor" ? key : voter)[it.key()] = it.value();
  key["voters"] = {{"", voter}};
  m.training_config = key;
}
}  // namespace

const TrainedVoter* TrainedModel::FindVoter(const std::string& tag) const {
  auto it = voters.find(tag);
  if (it == voters.end() && voters.size() == 1) it = voters.find("");  // a version 1 file's one voter
  return it == voters.end() ? nullptr : &it->second;
}

void SaveModel(const std::string& path, const TrainedModel& m) {
  nlohmann::json voters = nlohmann::json::object();
  for (const auto& [tag, v] : m.voters)
    voters[tag] = {{"voter_type", v.voter_type}, {"normaliser", v.normaliser.ToJson()}, {"voter_model", v.voter_model}};
  const nlohmann::json j = {{"format_version", kModelFormatVersion}, {"training_config", m.training_config},
                            {"catalog_hash", m.catalog_hash}, {"voters", voters}, {"summary", m.summary}};
  const std::vector<uint8_t> cbor = nlohmann::json::to_cbor(j);
  AtomicWrite(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out.write(kMagic, sizeof(kMagic) - 1);
    out.write(reinterpret_cast<const char*>(cbor.data()), cbor.size());
    out.flush();
    if (!out) throw InputError(tmp + ": write failed");
  });
}

TrainedModel LoadModel(const std::string& path) {
  const nlohmann::json j = ReadCbor(path);
  try {
    TrainedModel m;
    const auto& version = j.at("format_version");
    if (!version.is_number_integer() || version.get<long long>() < 0 || version.get<long long>() > 1000000)
      throw InputError(path + ": corrupt model file (format_version " + version.dump().substr(0, 40) +
                       "); delete it to retrain");
    const int format = version.get<int>();
    if (format != kModelFormatVersion && format != 1)
      throw InputError(path + ": model file format version " + std::to_string(format) + ", this furnihost reads " +
                       "versions 1 to " + std::to_string(kModelFormatVersion) +
                       "; retrain with `furnihost train --graph <config>`");
    m.training_config = j.at("training_config");
    m.catalog_hash = j.at("catalog_hash").get<std::string>();
    if (format == 1 && !j.contains("voters")) {
      UpgradeSingleVoter(path, j, m);
    } else {
      const auto& vs = j.at("voters");
      if (!vs.is_object()) throw InputError(path + ": corrupt model file (voters is not an object); delete it to retrain");
      for (auto it = vs.begin(); it != vs.end(); ++it) m.voters[it.key()] = ReadVoter(path, *it, it.key());
    }
    m.summary = j.value("summary", nlohmann::json::object());
    return m;
  } catch (const InputError& e) {
    const std::string what = e.what();
    if (what.rfind(path, 0) == 0) throw;
    throw InputError(path + ": " + what + "; delete it to retrain");  // e.g. from Normaliser::FromJson
  } catch (const std::exception& e) {
    throw InputError(path + ": model file is missing a field (" + std::string(e.what()) + "); delete it to retrain");
  }
}

}  // namespace furnihost
