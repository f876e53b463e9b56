// Hostile-input corpus runner: each case of expectations.json runs the furnihost binary on a
// corpus file (or on something made at test time: FIFOs, folders, 10^7 points, deep nesting)
// and checks that it neither crashes nor hangs (30 s), exits as expected with exactly one
// error line naming the problem, and leaves no partial output behind.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
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
  std::vector<std::string> unset_env;  // variables the command runs without (env -u)
  double max_rss_mb = 0;               // the command's peak resident memory, when set
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
    k.unset_env = c.value("unset_env", std::vector<std::string>());
    k.max_rss_mb = c.value("max_rss_mb", 0.0);
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
  double max_rss_mb = 0;  // the largest peak resident memory of any command run so far
};

// Runs the binary under `timeout`: 124 = hung for 30 s, >= 128 = killed by a signal.
// FURNIHOST_HOSTILE_TIMEOUT raises the limit for slow builds (scripts/test-sanitize: ASan).
// `env` prefixes the command (env -u NAME ...). FURNIHOST_HOSTILE_BINARY runs the corpus against
// another build of the binary (an installed one, or an older one to see a case fail).
RunResult Furnihost(const std::string& args, const std::string& dir, const std::string& env = "") {
  const char* limit = std::getenv("FURNIHOST_HOSTILE_TIMEOUT");
  const char* binary = std::getenv("FURNIHOST_HOSTILE_BINARY");
  const std::string cmd = env + "timeout -k 5 " + std::string(limit ? limit : "30") + " " +
                          std::string(binary ? binary : FURNIHOST_TEST_BINARY) + " " + args + " >" + dir +
                          "/stdout.txt 2>" + dir + "/stderr.txt </dev/null";
  const int status = std::system(cmd.c_str());
  RunResult r;
  rusage u{};
  if (::getrusage(RUSAGE_CHILDREN, &u) == 0) r.max_rss_mb = double(u.ru_maxrss) / 1024.0;  // Linux: kB
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

std::string Slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

// A binary PCD of points, with a VIEWPOINT.
void WritePoints(const std::string& path, const std::vector<std::array<float, 3>>& pts, const std::string& viewpoint) {
  std::ofstream out(path, std::ios::binary);
  out << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << pts.size()
      << "\nHEIGHT 1\nVIEWPOINT " << viewpoint << " 1 0 0 0\nPOINTS " << pts.size() << "\nDATA binary\n";
  out.write(reinterpret_cast<const char*>(pts.data()), std::streamsize(pts.size() * 12));
  ASSERT_TRUE(out.good()) << path;
}

// The points and VIEWPOINT of a binary x y z PCD written by `furnihost simulate`.
std::vector<std::array<float, 3>> ReadPoints(const std::string& path, std::string* viewpoint = nullptr) {
  const std::string s = Slurp(path);
  const size_t data = s.find("DATA binary\n");
  const size_t vp = s.find("VIEWPOINT ");
  if (viewpoint && vp != std::string::npos) {
    std::istringstream in(s.substr(vp + 10, s.find('\n', vp) - vp - 10));
    double x, y, z;
    in >> x >> y >> z;
    *viewpoint = std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z);
  }
  std::vector<std::array<float, 3>> pts((s.size() - data - 12) / 12);
  std::memcpy(pts.data(), s.data() + data + 12, pts.size() * 12);
  return pts;
}

std::vector<std::string> Fields(const std::string& text, char sep) {
  std::vector<std::string> f;
  std::istringstream in(text);
  for (std::string x; std::getline(in, x, sep);) f.push_back(x);
  return f;
}

// The steps of issue 50's cases (hardening, second round): see expectations.json.
bool PrepareIssue50(const std::string& step, const Paths& p) {
  const std::string& t = p.tmp;
  const std::vector<std::string> arg = Fields(step, ':');
  const std::string& what = arg[0];
  if (what == "deep_value") {
    // 6*10^4 levels: the most one command-line argument holds (128 KiB).
    const std::string deep = std::string(60000, '[') + std::string(60000, ']');
    WriteFile(t + "/deep.txt", deep);
    WriteFile(t + "/deep_object.txt", "{\"a\": " + deep + "}");
  } else if (what == "fifo_mtl" || what == "dir_mtl") {
    // An OBJ whose mtllib names a FIFO (or a folder): assimp opened it and blocked forever.
    fs::create_directories(t + "/mtl");
    WriteFile(t + "/mtl/m.obj", "mtllib m.mtl\nusemtl red\n" + Slurp(kCorpus + "/catalogs/tiny/cube.obj"));
    WriteFile(t + "/mtl/catalog.json", Slurp(kCorpus + "/catalogs/tiny/catalog.json").replace(
                                           Slurp(kCorpus + "/catalogs/tiny/catalog.json").find("cube.obj"), 8, "m.obj"));
    if (what == "fifo_mtl") EXPECT_EQ(::mkfifo((t + "/mtl/m.mtl").c_str(), 0644), 0);
    else fs::create_directories(t + "/mtl/m.mtl");
  } else if (what == "fifo_gltf_buffer" || what == "dir_gltf_buffer") {
    // A glTF whose buffer uri names a FIFO (or a folder).
    fs::create_directories(t + "/gltf");
    std::string doc = Slurp(kCorpus + "/catalogs/gltf_good/good.gltf");
    const size_t uri = doc.find("data:application");
    doc.replace(uri, doc.find('"', uri) - uri, "m.bin");
    WriteFile(t + "/gltf/m.gltf", doc);
    WriteFile(t + "/gltf/catalog.json",
              R"({"models": [{"id": "cube", "class": "cube", "mesh": "m.gltf", "up": "+z", "size_m": [0.5, 0.5, 0.6]}]})");
    if (what == "fifo_gltf_buffer") EXPECT_EQ(::mkfifo((t + "/gltf/m.bin").c_str(), 0644), 0);
    else fs::create_directories(t + "/gltf/m.bin");
  } else if (what == "line") {
    // line:<axis x|y|z|xy>:<points>:<metres>: a run of points along an axis (or the diagonal).
    const size_t n = std::stoul(arg[2]);
    const float len = std::stof(arg[3]);
    std::vector<std::array<float, 3>> pts(n);
    for (size_t i = 0; i < n; ++i) {
      const float s = len * float(i) / float(n);
      const float jitter = 0.002f * float((i * 7919) % 11);  // not one exact line
      if (arg[1] == "x") pts[i] = {s, jitter, 1.f};
      else if (arg[1] == "y") pts[i] = {jitter, s, 1.f};
      else if (arg[1] == "z") pts[i] = {jitter, 1.f, s};
      else pts[i] = {s * 0.7071f, s * 0.7071f + jitter, 1.f};
    }
    WritePoints(t + "/line_" + arg[1] + ".pcd", pts, "0 0 0");
  } else if (what == "viewpoint") {
    // viewpoint:<x,y,z>: the room scan with another VIEWPOINT, as far.pcd.
    std::string vp;
    const auto pts = ReadPoints(t + "/room.pcd", &vp);
    WritePoints(t + "/far.pcd", pts, Replace(arg[1], ",", " "));
  } else if (what == "stray") {
    // stray:<x,y,z>[:first]: the room scan with one more point there (at the end, or first).
    std::string vp;
    auto pts = ReadPoints(t + "/room.pcd", &vp);
    std::istringstream in(Replace(arg[1], ",", " "));
    std::array<float, 3> q{};
    in >> q[0] >> q[1] >> q[2];
    if (arg.size() > 2 && arg[2] == "first") pts.insert(pts.begin(), q);
    else pts.push_back(q);
    WritePoints(t + "/stray.pcd", pts, vp);
  } else if (what == "two_rooms") {
    // The room scan (and its ground truth) as a/room.pcd, b/room.pcd and ...pcd (stem "..").
    for (const std::string d : {"a", "b"}) {
      fs::create_directories(t + "/" + d);
      fs::copy_file(t + "/room.pcd", t + "/" + d + "/room.pcd");
      fs::copy_file(t + "/room.gt.json", t + "/" + d + "/room.gt.json");
    }
    fs::copy_file(t + "/room.pcd", t + "/...pcd");
  } else if (what == "dataset") {
    // dataset:<gt file>: a dataset of the room scan; two_rooms: a/room.pcd and b/room.pcd.
    const std::string gt = arg.size() > 1 ? arg[1] : "room.gt.json";
    std::string scenes = "{\"scan\": \"room.pcd\", \"gt\": \"" + gt + "\"}";
    if (gt == "two_rooms")
      scenes = R"({"scan": "a/room.pcd", "gt": "a/room.gt.json"}, {"scan": "b/room.pcd", "gt": "b/room.gt.json"})";
    WriteFile(t + "/dataset.json", "{\"classes\": [\"cube\"], \"scenes\": [" + scenes + "]}");
  } else if (what == "bad_gt") {
    // bad_gt:<w,d,h>: the room's ground truth with that size for its object.
    WriteFile(t + "/bad.gt.json", R"({"units": "m", "up": "z", "objects": [{"class": "cube", "center": [1.5, 2, 0.3], "size": [)" +
                                      arg[1] + "]}]}");
  } else if (what == "transform_dataset") {
    // transform_dataset:<text>: the room's dataset with that scene transform.
    WriteFile(t + "/dataset.json", R"({"classes": ["cube"], "scenes": [{"scan": "room.pcd", "gt": "room.gt.json", "transform": ")" +
                                       arg[1] + "\"}]}");
  } else if (what == "cache_is") {
    // cache_is:<notes|fifo>: the stub graph's model_cache names a user's file, or a FIFO.
    if (arg[1] == "fifo") EXPECT_EQ(::mkfifo((t + "/model.fhm").c_str(), 0644), 0);
    else WriteFile(t + "/model.fhm", "my notes, not a model\n");
  } else if (what == "evil_repo") {
    // A git checkout whose config runs a command on `git status` (core.fsmonitor), holding the
    // graph that eval reads: eval must not run it.
    const std::string r = t + "/repo";
    fs::create_directories(r);
    WriteFile(r + "/tracked.txt", "x\n");
    const std::string git = "git -C " + r + " -c user.name=t -c user.email=t@t ";
    EXPECT_EQ(std::system((git + "init -q && " + git + "add tracked.txt && " + git + "commit -q -m x").c_str()), 0);
    EXPECT_EQ(std::system((git + "rev-parse HEAD >" + t + "/head.txt").c_str()), 0);
    EXPECT_EQ(std::system(("git -C " + r + " config core.fsmonitor 'touch " + t + "/pwned; false'").c_str()), 0);
    WriteFile(r + "/tracked.txt", "changed\n");
    fs::copy_file(t + "/g.json", r + "/g.json");
  } else if (what == "graph_catalog") {
    // graph_catalog:<corpus path>: the stub graph trains from that catalog.
    std::string g = Slurp(t + "/g.json");
    const std::string tiny = kCorpus + "/catalogs/tiny/catalog.json";
    g.replace(g.find(tiny), tiny.size(), kCorpus + "/" + arg[1]);
    WriteFile(t + "/g.json", g);
  } else if (what == "fifo") {
    // fifo:<name>: a FIFO in the case's folder.
    EXPECT_EQ(::mkfifo((t + "/" + arg[1]).c_str(), 0644), 0);
  } else if (what == "extends_fifo") {
    WriteFile(t + "/ext.json", R"({"extends": "base.json", "stages": {}})");
    EXPECT_EQ(::mkfifo((t + "/base.json").c_str(), 0644), 0);
  } else if (what == "dataset_origin") {
    // dataset_origin:<x,y,z>: the room's dataset with that sensor origin.
    WriteFile(t + "/dataset.json", R"({"classes": ["cube"], "scenes": [{"scan": "room.pcd", "gt": "room.gt.json", "origin": [)" +
                                       arg[1] + "]}]}");
  } else if (what == "utf8_name") {  // the room scan under a name that is not UTF-8
    fs::copy_file(t + "/room.pcd", t + "/r\xffm.pcd");
  } else if (what == "notes") {
    WriteFile(t + "/notes.txt", "my notes\n");
  } else if (what == "many_objects") {
    // many_objects:<nx>x<ny>:<edge m>[:overlap]: a grid of nx x ny cubes of that edge, 2 edges
    // apart, in a room just large enough (1 m at least); with overlap, a last cube on the first.
    const auto dims = Fields(arg[1], 'x');
    const int nx = std::stoi(dims[0]), ny = std::stoi(dims[1]);
    const double e = std::stod(arg[2]);
    fs::create_directories(t + "/many");
    fs::copy_file(kCorpus + "/catalogs/tiny/cube.obj", t + "/many/cube.obj");
    std::ostringstream cat;
    cat << R"({"models": [{"id": "cube", "class": "cube", "mesh": "cube.obj", "up": "+z", "size_m": [)" << e << ", "
        << e << ", " << e << "]}]}";
    WriteFile(t + "/many/catalog.json", cat.str());
    std::ostringstream scene;
    scene.precision(10);
    scene << R"({"room": {"size_m": [)" << std::max(2 * e * nx + e, 1.0) << ", " << std::max(2 * e * ny + e, 1.0)
          << R"(], "height_m": 2.5}, "sensors": [{"position": [)" << e << ", " << e
          << R"(, 1.2]}], "sensor_params": {"angular_resolution_deg": 5, "tilt_resolution_deg": 5}, "objects": [)";
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j)
        scene << (i || j ? ", " : "") << R"({"model": "cube", "x": )" << 2 * e * (i + 1) << ", \"y\": " << 2 * e * (j + 1) << "}";
    if (arg.size() > 3) scene << R"(, {"model": "cube", "x": )" << 2 * e + 0.3 * e << ", \"y\": " << 2 * e << "}";
    scene << "]}";
    WriteFile(t + "/many/scene.json", scene.str());
  } else if (what == "compressed_1gb") {
    // A binary_compressed PCD of 1000 points of 1 MiB each (x y z and a 262141-float field):
    // 1 GB uncompressed, in a 12 MB LZF stream of runs that is cut short at the end. The reader
    // allocated the whole 1 GB before decoding.
    const size_t n = 1000, step = 12 + 4 * 262141, raw = n * step;
    std::string body = std::string(1, '\0') + std::string(1, '\0');  // a literal run of one zero byte
    std::string run("\xE0\xFF\x00", 3);  // back 1, 7 + 255 + 2 = 264 bytes
    const size_t runs = (raw - 1) / 264 - 10;  // ten runs short: the stream does not fill it
    std::string all;
    all.reserve(body.size() + runs * 3);
    all += body;
    for (size_t k = 0; k < runs; ++k) all += run;
    std::ofstream out(t + "/huge.pcd", std::ios::binary);
    out << "VERSION 0.7\nFIELDS x y z d\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 262141\nWIDTH " << n
        << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n << "\nDATA binary_compressed\n";
    const uint32_t sz[2] = {uint32_t(all.size()), uint32_t(raw)};
    out.write(reinterpret_cast<const char*>(sz), 8);
    out.write(all.data(), std::streamsize(all.size()));
    EXPECT_TRUE(out.good());
  } else if (what == "one_line_xyz") {
    // one_line_xyz:<points>: every point on one line.
    const size_t n = std::stoul(arg[1]);
    std::ofstream out(t + "/one_line.xyz");
    for (size_t i = 0; i < n; ++i) out << i % 100 << " " << (i / 100) % 100 << " 1.5 ";
    out << "\n";
  } else {
    return false;
  }
  return true;
}

void PrepareStep(const std::string& step, const Paths& p) {
  const std::string& t = p.tmp;
  if (step == "stub_graph" || step == "stub_fit_graph") {
    std::ifstream in(kCorpus + (step == "stub_graph" ? "/graphs/stub_chain.json" : "/graphs/stub_fit_chain.json"));
    WriteFile(t + "/g.json", p.Expand(std::string(std::istreambuf_iterator<char>(in), {})));
  } else if (step == "room_scan") {
    auto r = Furnihost("simulate -q --catalog " + kCorpus + "/catalogs/tiny/catalog.json --scene " + kCorpus +
                           "/catalogs/scene.json --out " + t + "/room.pcd",
                       t);
    ASSERT_EQ(r.code, 0) << r.err;
  } else if (step == "room_scan_dense") {  // the same room, 25x the returns (~100k points)
    auto r = Furnihost("simulate -q --catalog " + kCorpus + "/catalogs/tiny/catalog.json --scene " + kCorpus +
                           "/catalogs/scene.json --out " + t + "/room.pcd --sensor-params "
                           "'{\"angular_resolution_deg\": 0.4, \"tilt_resolution_deg\": 0.4}'",
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
  } else if (PrepareIssue50(step, p)) {
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
  // What the setup left, for the checks that nothing else was written or replaced.
  std::set<std::string> before;
  std::map<std::string, std::string> before_content;
  for (const auto& f : FilesUnder(p.tmp)) {
    before.insert(f);
    struct stat st {};
    if (::stat(f.c_str(), &st) == 0 && S_ISREG(st.st_mode) && st.st_size < (1 << 20)) before_content[f] = Slurp(f);
  }
  std::string env;
  for (const auto& v : c.unset_env) env += "env -u " + v + " ";

  const RunResult r = Furnihost(args, p.tmp, env);
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
  if (c.max_rss_mb > 0) {
    // FURNIHOST_HOSTILE_RSS_SLACK_MB adds what a build's own runtime takes (scripts/test-sanitize:
    // ASan's shadow and allocator, ~170 MB for `furnihost --version`).
    const char* slack = std::getenv("FURNIHOST_HOSTILE_RSS_SLACK_MB");
    EXPECT_LE(r.max_rss_mb, c.max_rss_mb + (slack ? std::atof(slack) : 0.0)) << "peak resident memory: " << ctx;
  }
  std::istringstream checks(c.check);
  for (std::string check; checks >> check;) {
    const auto arg = Fields(check, ':');
    if (check == "model_valid") {
      EXPECT_NO_THROW(furnihost::LoadModel(p.tmp + "/model.fhm")) << "the bad cache was not rewritten";
    } else if (check == "no_detections") {
      EXPECT_TRUE(furnihost::ReadJson(p.out + "/detections.json").at("detections").empty());
    } else if (check == "only_out") {
      // Nothing written outside --out: every file under the case's folder is one the setup made.
      for (const auto& f : FilesUnder(p.tmp))
        if (f.rfind(p.out + "/", 0) != 0) {
          EXPECT_TRUE(before.count(f)) << "written outside --out: " << f << "\n" << ctx;
        }
    } else if (arg[0] == "no_file") {
      EXPECT_FALSE(fs::exists(p.Expand(arg[1]))) << p.Expand(arg[1]) << " exists: " << ctx;
    } else if (arg[0] == "unchanged") {
      EXPECT_EQ(Slurp(p.Expand(arg[1])), before_content.at(p.Expand(arg[1]))) << "replaced: " << p.Expand(arg[1]);
    } else if (arg[0] == "shift") {
      // shift:<x,y,z>: the global shift detections.json records for the (first) scan.
      const auto want = Fields(arg[1], ',');
      const auto got = furnihost::ReadJson(p.out + "/detections.json").at("frames").at(0).at("shift");
      for (size_t k = 0; k < 3; ++k) EXPECT_EQ(got.at(k).get<double>(), std::stod(want.at(k))) << ctx;
    } else if (check == "git_revision") {
      std::string head = Slurp(p.tmp + "/head.txt");
      while (!head.empty() && std::isspace(static_cast<unsigned char>(head.back()))) head.pop_back();
      EXPECT_EQ(furnihost::ReadJson(p.out + "/summary.json").at("git").at("revision"), head) << ctx;
    } else {
      ADD_FAILURE() << "unknown check '" << check << "'";
    }
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
