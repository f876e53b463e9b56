// Hostile-input corpus runner: each case of expectations.json runs the furnihost binary on a
// corpus file (or on something made at test time: FIFOs, folders, 10^7 points, deep nesting)
// and checks that it neither crashes nor hangs (30 s), exits as expected with exactly one
// error line naming the problem, and leaves no partial output behind.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "furnihost/host/io.hpp"
#include "furnihost/host/pipeline.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

const std::string kHostile = FURNIHOST_HOSTILE_DIR;
const std::string kCorpus = kHostile + "/corpus";
const std::string kTestPlugins = FURNIHOST_TEST_PLUGINS_ROOT;

struct Case {
  std::string name, args, file, setup, warning, check;
  std::vector<std::string> errors;  // substrings of the error line
  int exit = 2;
  std::vector<std::string> outputs;
};

std::vector<Case> LoadCases() {
  std::ifstream in(kHostile + "/expectations.json");
  const auto j = nlohmann::json::parse(in);
  std::vector<Case> cases;
  for (const auto& c : j.at("cases")) {
    Case k;
    k.name = c.at("name").get<std::string>();
    k.args = c.at("args").get<std::string>();
    k.exit = c.at("exit").get<int>();
    k.file = c.value("file", "");
    k.setup = c.value("setup", "");
    if (c.contains("error"))
      k.errors = c["error"].is_array() ? c["error"].get<std::vector<std::string>>()
                                       : std::vector<std::string>{c["error"].get<std::string>()};
    k.warning = c.value("warning", "");
    k.check = c.value("check", "");
    k.outputs = c.value("outputs", std::vector<std::string>());
    cases.push_back(k);
  }
  return cases;
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
  return s;
}

struct Paths {
  std::string tmp, out;
  std::string Expand(std::string s) const {
    s = Replace(s, "{corpus}", kCorpus);
    s = Replace(s, "{tmp}", tmp);
    s = Replace(s, "{out}", out);
    s = Replace(s, "{bad}", kTestPlugins + "/bad");
    s = Replace(s, "{outside}", kTestPlugins + "/outside");
    s = Replace(s, "{stubs}", kTestPlugins + "/hostile");
    return s;
  }
};

struct RunResult {
  int code = -1;
  std::string out, err;
};

// Runs the binary under `timeout`: 124 = hung for 30 s, >= 128 = killed by a signal.
// FURNIHOST_HOSTILE_TIMEOUT raises the limit for slow builds (scripts/test-sanitize: ASan).
RunResult Furnihost(const std::string& args, const std::string& dir) {
  const char* limit = std::getenv("FURNIHOST_HOSTILE_TIMEOUT");
  const std::string cmd = "timeout -k 5 " + std::string(limit ? limit : "30") + " " + std::string(FURNIHOST_TEST_BINARY) + " " + args + " >" + dir +
                          "/stdout.txt 2>" + dir + "/stderr.txt </dev/null";
  const int status = std::system(cmd.c_str());
  RunResult r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  auto slurp = [](const std::string& p) {
    std::ifstream f(p);
    return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  };
  r.out = slurp(dir + "/stdout.txt");
  r.err = slurp(dir + "/stderr.txt");
  fs::remove(dir + "/stdout.txt");
  fs::remove(dir + "/stderr.txt");
  return r;
}

using furnihost::testing::ErrorLines;

void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
  ASSERT_TRUE(out.good()) << path;
}

// 10^7 copies of one point: a binary PCD of 120 MB, too big to commit.
void WriteIdentical(const std::string& path) {
  const size_t n = 10000000;
  std::ofstream out(path, std::ios::binary);
  out << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << n
      << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n << "\nDATA binary\n";
  const float p[3] = {1.5f, 2.0f, 0.7f};
  std::vector<float> block(3 * 100000);
  for (size_t i = 0; i < block.size(); ++i) block[i] = p[i % 3];
  for (size_t i = 0; i < n; i += 100000) out.write(reinterpret_cast<const char*>(block.data()), block.size() * 4);
  ASSERT_TRUE(out.good());
}

void PrepareStep(const std::string& step, const Paths& p) {
  const std::string& t = p.tmp;
  if (step == "stub_graph") {
    std::ifstream in(kCorpus + "/graphs/stub_chain.json");
    WriteFile(t + "/g.json", p.Expand(std::string(std::istreambuf_iterator<char>(in), {})));
  } else if (step == "room_scan") {
    auto r = Furnihost("simulate -q --catalog " + kCorpus + "/catalogs/tiny/catalog.json --scene " + kCorpus +
                           "/catalogs/scene.json --out " + t + "/room.pcd",
                       t);
    ASSERT_EQ(r.code, 0) << r.err;
  } else if (step == "trained") {
    auto r = Furnihost("train -q --graph " + t + "/g.json --plugin-path " + kTestPlugins + "/hostile", t);
    ASSERT_EQ(r.code, 0) << r.err;
  } else if (step == "tamper_voter") {
    // A well-formed model file for this very graph whose voter part is not a model.
    auto m = furnihost::LoadModel(t + "/model.fhm");
    for (auto& [tag, voter] : m.voters) voter.voter_model = {{"tampered", true}};
    furnihost::SaveModel(t + "/model.fhm", m);
  } else if (step.rfind("model:", 0) == 0) {
    fs::copy_file(kCorpus + "/" + step.substr(6), t + "/model.fhm");
  } else if (step == "deep_model") {
    WriteFile(t + "/model.fhm", "furnihost-model\n" + std::string(1000000, '\x81') + std::string(1, '\0'));
  } else if (step == "model_dir") {
    fs::create_directories(t + "/model.fhm");
  } else if (step == "directory_scan") {
    fs::create_directories(t + "/dir.pcd");
  } else if (step == "fifo_scan" || step == "fifo_graph") {
    ASSERT_EQ(::mkfifo((t + (step == "fifo_scan" ? "/fifo.pcd" : "/fifo.json")).c_str(), 0644), 0);
  } else if (step == "fifo_mesh") {
    fs::create_directories(t + "/fifo_mesh");
    ASSERT_EQ(::mkfifo((t + "/fifo_mesh/m.obj").c_str(), 0644), 0);
    WriteFile(t + "/fifo_mesh/catalog.json",
              R"({"models": [{"id": "cube", "class": "cube", "mesh": "m.obj", "up": "+z", "height_m": 1}]})");
  } else if (step == "fifo_plugin") {
    fs::create_directories(t + "/plugins");
    ASSERT_EQ(::mkfifo((t + "/plugins/libfurnihost_fifo.so").c_str(), 0644), 0);
  } else if (step == "dir_plugin") {
    fs::create_directories(t + "/plugins/libfurnihost_dir.so");
  } else if (step == "identical_1e7") {
    WriteIdentical(t + "/identical.pcd");
  } else if (step == "deep_json") {
    WriteFile(t + "/deep.json", "{\"stages\": " + std::string(100000, '[') + std::string(100000, ']') + "}");
  } else if (step == "deep_sensor_params") {
    WriteFile(t + "/deep_params.json", "{\"noise_a\": " + std::string(60000, '[') + std::string(60000, ']') + "}");
  } else if (step == "out_is_file") {
    WriteFile(t + "/file", "not a folder");
  } else {
    FAIL() << "unknown setup step '" << step << "' in expectations.json";
  }
}

std::vector<std::string> FilesUnder(const std::string& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return files;
  for (const auto& e : fs::recursive_directory_iterator(dir, ec))
    if (!e.is_directory(ec)) files.push_back(e.path().string());
  return files;
}

// Test names and failure messages show the case name, not the struct's bytes.
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

class Hostile : public ::testing::TestWithParam<Case> {};

TEST_P(Hostile, FailsCleanly) {
  const Case& c = GetParam();
  Paths p;
  p.tmp = furnihost::testing::TempDir("hostile_" + c.name);
  fs::remove_all(p.tmp);
  fs::create_directories(p.tmp);
  p.out = p.tmp + "/out";
  std::istringstream steps(c.setup);
  for (std::string step; steps >> step;) {
    ASSERT_NO_FATAL_FAILURE(PrepareStep(step, p)) << step;
  }
  std::string args = c.args;
  if (!c.file.empty())
    args = Replace(args, "{file}", c.file.rfind("{tmp}", 0) == 0 ? c.file : "{corpus}/" + c.file);
  args = p.Expand(args);

  const RunResult r = Furnihost(args, p.tmp);
  const std::string ctx = "furnihost " + args + "\nstderr:\n" + r.err;
  ASSERT_NE(r.code, 124) << "hung (timeout): " << ctx;
  ASSERT_LT(r.code, 128) << "killed by signal " << r.code - 128 << ": " << ctx;
  EXPECT_EQ(r.err.find("Sanitizer"), std::string::npos) << ctx;
  EXPECT_EQ(r.err.find("runtime error:"), std::string::npos) << ctx;
  EXPECT_EQ(r.code, c.exit) << ctx;
  const auto lines = ErrorLines(r.err);
  if (c.exit != 0) {
    ASSERT_EQ(lines.size(), 1u) << "expected exactly one error line: " << ctx;
    EXPECT_EQ(lines[0].rfind("furnihost", 0), 0u) << lines[0];
    for (const auto& e : c.errors)
      EXPECT_NE(lines[0].find(e), std::string::npos) << "error line lacks '" << e << "': " << lines[0];
    // Nothing half-done: no output folder content at all.
    const auto left = FilesUnder(p.out);
    EXPECT_TRUE(left.empty()) << "partial output left: " << left.front();
  } else {
    EXPECT_TRUE(lines.empty()) << "unexpected error output: " << ctx;
    if (!c.warning.empty()) {
      EXPECT_NE(r.err.find(c.warning), std::string::npos) << "no warning '" << c.warning << "': " << ctx;
    }
    if (!c.errors.empty()) ADD_FAILURE() << "a case with exit 0 cannot expect an error line";
    for (const auto& o : c.outputs) {
      const std::string path = p.Expand(o);
      ASSERT_TRUE(fs::is_regular_file(path)) << path << " missing: " << ctx;
      EXPECT_NO_THROW(furnihost::ReadJson(path)) << path;
    }
  }
  for (const auto& f : FilesUnder(p.tmp))
    EXPECT_EQ(f.find(".tmp."), std::string::npos) << "temporary file left behind: " << f;
  if (c.check == "model_valid") {
    EXPECT_NO_THROW(furnihost::LoadModel(p.tmp + "/model.fhm")) << "the bad cache was not rewritten";
  } else if (c.check == "no_detections") {
    EXPECT_TRUE(furnihost::ReadJson(p.out + "/detections.json").at("detections").empty());
  } else if (!c.check.empty()) {
    ADD_FAILURE() << "unknown check '" << c.check << "'";
  }
  if (!HasFailure()) fs::remove_all(p.tmp);
}

INSTANTIATE_TEST_SUITE_P(Corpus, Hostile, ::testing::ValuesIn(LoadCases()),
                         [](const ::testing::TestParamInfo<Case>& i) { return i.param.name; });

// Every scan, model and catalog in the corpus is used by some case, and the corpus stays small.
TEST(HostileCorpus, EveryFileHasAnExpectationAndTheCorpusIsSmall) {
  std::string all;
  for (const auto& c : LoadCases()) all += c.args + " " + c.file + " " + c.setup + "\n";
  uintmax_t bytes = 0;
  for (const auto& f : FilesUnder(kCorpus)) {
    bytes += fs::file_size(f);
    const std::string rel = fs::relative(f, kCorpus).string();
    const bool listed = rel.rfind("scans/", 0) == 0 || rel.rfind("models/", 0) == 0 ||
                        (rel.rfind("catalogs/", 0) == 0 && fs::path(rel).filename() == "catalog.json");
    if (listed) {
      EXPECT_NE(all.find(rel), std::string::npos) << rel << " has no case in expectations.json";
    }
  }
  EXPECT_LT(bytes, 200u * 1024u) << "keep the corpus under 200 KB (make big inputs at test time)";
}

}  // namespace
