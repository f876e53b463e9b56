// ParamBinding: one declaration per parameter gives the schema (defaults read from the options
// struct), the parsing and the cross-field rules.
#include <gtest/gtest.h>

#include "furnihost/params.hpp"
#include "furnihost/host/registry.hpp"
#include "test_support.hpp"

using furnihost::InputError;
using furnihost::ParamBinding;
using furnihost::ParamType;
using furnihost::StageError;
using nlohmann::json;

namespace {

enum class Mode { Fast, Exact };

struct Inner {
  float spread = 0.35f;
};

struct Opts {
  double angle_deg = 40;
  float floor_cut = 0.04f;
  int min_points = 10;
  size_t max_points = 20000000;
  bool flag = true;
  std::string name = "x";
  std::string adaptive = "auto";
  Mode mode = Mode::Exact;
  std::vector<double> radii{2.0, 2.5};
  std::vector<float> origin;
  std::map<std::string, float> thresholds{{"chair", 0.6f}};
  Inner inner;
  std::map<std::string, std::string> class_map;
  double lo = 0, hi = 1;
};

const ParamBinding<Opts>& Binding() {
  static const auto b =
      ParamBinding<Opts>()
          .Number("angle_deg", &Opts::angle_deg, 0, 180, "deg", "angle")
          .Number("floor_cut_m", &Opts::floor_cut, 0, 1, "m", "floor")
          .Int("min_points", &Opts::min_points, 1, 1e6, "", "points")
          .Int("max_points", &Opts::max_points, 1, 2e9, "", "cap")
          .Bool("flag", &Opts::flag, "flag")
          .String("name", &Opts::name, "name")
          .Enum("adaptive", &Opts::adaptive, {"auto", "on", "off"}, "as a string")
          .Enum("mode", &Opts::mode, {"fast", "exact"}, "as an enum")
          .NumberList("radii", &Opts::radii, 0.5, 20, "", "radii")
          .NumberList("origin", &Opts::origin, -10, 10, "m", "origin")
          .NumberMap("thresholds", &Opts::thresholds, 0, 1, "", "per class")
          .DetectionOnly()
          .Number("spread", [](Opts& o) -> float& { return o.inner.spread; }, 1e-3, 100, "", "nested member")
          .Object("class_map", json::object(), "renames",
                  [](Opts& o, const json& j) {
                    for (auto it = j.begin(); it != j.end(); ++it) {
                      if (!it->is_string()) throw InputError("class_map/" + it.key() + ": expected a class name");
                      o.class_map[it.key()] = it->get<std::string>();
                    }
                  })
          .Number("lo", &Opts::lo, 0, 10, "m", "low")
          .Number("hi", &Opts::hi, 0, 10, "m", "high")
          .Rule([](const Opts& o) { return o.lo < o.hi ? "" : "lo must be < hi"; })
          .Rule([](const Opts& o) {
            return o.origin.empty() || o.origin.size() == 3 ? "" : "origin: expected 3 numbers";
          });
  return b;
}

template <class E>
std::string ErrorOf(const json& params) {
  try {
    Binding().Parse(params);
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(ParamBinding, DefaultsComeFromTheStruct) {
  const auto& schema = Binding().Schema();
  const json d = schema.Resolve(json::object(), "t");
  EXPECT_EQ(d["angle_deg"], 40.0);
  EXPECT_EQ(d["floor_cut_m"].dump(), "0.04");  // the float as written, not 0.03999999910593033
  EXPECT_EQ(d["spread"].dump(), "0.35");
  EXPECT_EQ(d["min_points"], 10);
  EXPECT_TRUE(d["min_points"].is_number_integer());
  EXPECT_EQ(d["max_points"], 20000000);
  EXPECT_EQ(d["flag"], true);
  EXPECT_EQ(d["adaptive"], "auto");
  EXPECT_EQ(d["mode"], "exact");
  EXPECT_EQ(d["radii"], json({2.0, 2.5}));
  EXPECT_EQ(d["origin"], json::array());
  EXPECT_EQ(d["thresholds"].dump(), R"({"chair":0.6})");
  EXPECT_EQ(d["class_map"], json::object());
  EXPECT_EQ(schema.Find("thresholds")->type, ParamType::NumberMap);
  EXPECT_FALSE(schema.Find("thresholds")->training);
  EXPECT_EQ(schema.Find("floor_cut_m")->unit, "m");
  EXPECT_EQ(schema.Find("min_points")->unit, "");
  EXPECT_EQ(schema.ToJson()[0]["unit"], "deg");
  EXPECT_FALSE(schema.ToJson()[2].contains("unit"));
  // Declaration order is schema order.
  EXPECT_EQ(schema.Specs().front().name, "angle_deg");
  EXPECT_EQ(schema.Specs().back().name, "hi");
}

TEST(ParamBinding, ParseOfDefaultsIsTheDefaultStruct) {
  const Opts o = Binding().Parse(Binding().Schema().Resolve(nullptr, "t"));
  const Opts d;
  EXPECT_EQ(o.angle_deg, d.angle_deg);
  EXPECT_EQ(o.floor_cut, d.floor_cut);
  EXPECT_EQ(o.inner.spread, d.inner.spread);
  EXPECT_EQ(o.max_points, d.max_points);
  EXPECT_EQ(o.mode, d.mode);
  EXPECT_EQ(o.radii, d.radii);
  EXPECT_EQ(o.thresholds, d.thresholds);
  EXPECT_EQ(Binding().Parse(json::object()).min_points, d.min_points);  // missing = default
}

TEST(ParamBinding, ParseRoundTrip) {
  const json given = {{"angle_deg", 12.5},
                      {"floor_cut_m", 0.1},
                      {"min_points", 7},
                      {"max_points", 3000000000LL / 2},
                      {"flag", false},
                      {"name", "y"},
                      {"adaptive", "off"},
                      {"mode", "fast"},
                      {"radii", {1.0}},
                      {"origin", {1, 2, 3}},
                      {"thresholds", {{"table", 0.25}, {"sofa", 1}}},
                      {"spread", 2},
                      {"class_map", {{"desk", "table"}}},
                      {"lo", 2},
                      {"hi", 3}};
  const Opts o = Binding().Parse(Binding().Schema().Resolve(given, "t"));
  EXPECT_EQ(o.angle_deg, 12.5);
  EXPECT_EQ(o.floor_cut, 0.1f);
  EXPECT_EQ(o.min_points, 7);
  EXPECT_EQ(o.max_points, 1500000000u);
  EXPECT_FALSE(o.flag);
  EXPECT_EQ(o.name, "y");
  EXPECT_EQ(o.adaptive, "off");
  EXPECT_EQ(o.mode, Mode::Fast);
  EXPECT_EQ(o.radii, std::vector<double>{1.0});
  EXPECT_EQ(o.origin, (std::vector<float>{1, 2, 3}));
  EXPECT_EQ(o.thresholds, (std::map<std::string, float>{{"sofa", 1.f}, {"table", 0.25f}}));
  EXPECT_EQ(o.inner.spread, 2.f);
  EXPECT_EQ(o.class_map.at("desk"), "table");
  EXPECT_EQ(o.lo, 2);
  EXPECT_EQ(o.hi, 3);
}

TEST(ParamBinding, TypeAndRangeErrorsNameTheParameter) {
  EXPECT_EQ(ErrorOf<InputError>({{"angle_deg", "forty"}}), "angle_deg: expected a number in [0, 180], got \"forty\"");
  EXPECT_EQ(ErrorOf<InputError>({{"angle_deg", 181}}), "angle_deg: expected a number in [0, 180], got 181");
  EXPECT_EQ(ErrorOf<InputError>({{"min_points", 2.5}}).rfind("min_points: expected an integer", 0), 0u);
  EXPECT_EQ(ErrorOf<InputError>({{"mode", "slow"}}), "mode: expected one of fast, exact, got \"slow\"");
  EXPECT_EQ(ErrorOf<InputError>({{"radii", {0.1}}}).rfind("radii: expected a list of numbers in [0.5, 20]", 0), 0u);
  EXPECT_EQ(ErrorOf<InputError>({{"angel_deg", 1}}).rfind("angel_deg: unknown parameter; valid: angle_deg, ", 0), 0u);
  EXPECT_EQ(ErrorOf<InputError>(json::array()).rfind("params: expected an object of parameters", 0), 0u);
  EXPECT_EQ(ErrorOf<InputError>({{"class_map", {{"desk", 3}}}}), "class_map/desk: expected a class name");
}

TEST(ParamBinding, NumberMapValuesAreChecked) {
  EXPECT_EQ(ErrorOf<InputError>({{"thresholds", {{"chair", 1.5}}}}),
            "thresholds/chair: expected a number in [0, 1], got 1.5");
  EXPECT_EQ(ErrorOf<InputError>({{"thresholds", {{"chair", "high"}}}}),
            "thresholds/chair: expected a number in [0, 1], got \"high\"");
  EXPECT_EQ(ErrorOf<InputError>({{"thresholds", 0.5}}).rfind("thresholds: expected an object of name: number", 0), 0u);
  EXPECT_EQ(ErrorOf<InputError>({{"thresholds", json::object()}}), "");
  // Resolve checks it the same way, with the config's pointer.
  try {
    Binding().Schema().Resolve({{"thresholds", {{"chair", -1}}}}, "g.json:/stages/v/params");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "g.json:/stages/v/params/thresholds/chair: expected a number in [0, 1], got -1");
  }
}

TEST(ParamBinding, RuleFailureIsAStageInputError) {
  EXPECT_EQ(ErrorOf<StageError>({{"lo", 5}, {"hi", 4}}), "lo must be < hi");
  EXPECT_EQ(ErrorOf<StageError>({{"origin", {1, 2}}}), "origin: expected 3 numbers");
  try {
    Binding().Parse({{"lo", 5}});
    ADD_FAILURE() << "no error";
  } catch (const StageError& e) {
    EXPECT_TRUE(e.IsInputError());  // the user's config: exit 2
  }
}

// Every plugin found: its schema accepts its own defaults, and the stage constructs from them
// (a default outside its range, or defaults breaking a rule, fail here). For the plugins that
// declare their parameters with ParamBinding, schema defaults equal the options struct's by
// construction (read from O{}); for the others this is the check that they at least agree
// with the constructor's rules.
TEST(ParamBinding, EveryPluginConstructsFromItsOwnDefaults) {
  // Whatever plugins this build has: the sanitizer pass builds only a few of them.
  auto reg = furnihost::testing::MakeRegistry();
  ASSERT_FALSE(reg->Plugins().empty());
  EXPECT_TRUE(reg->Refusals().empty());
  for (const auto& p : reg->Plugins()) {
    SCOPED_TRACE(p.type);
    json given = json::object();
    for (const auto& s : p.params.Specs()) given[s.name] = s.default_value;
    json resolved;
    ASSERT_NO_THROW(resolved = p.params.Resolve(given, p.type)) << "a default is outside its own schema";
    EXPECT_EQ(resolved, p.params.Resolve(json::object(), p.type));
    std::shared_ptr<furnihost::Stage> stage;
    try {
      stage = reg->Create(p.type, resolved);
    } catch (const std::exception& e) {
      ADD_FAILURE() << "constructing from the defaults: " << e.what();
    }
    EXPECT_NE(stage, nullptr);
  }
}

TEST(ParamBinding, StringListSplitsACommaSeparatedString) {
  struct L {
    std::vector<std::string> classes;
    std::vector<std::string> keep{"chair", "table"};
  };
  const auto b = ParamBinding<L>()
                     .StringList("classes", &L::classes, "classes")
                     .StringList("keep", &L::keep, "kept");
  const auto& s = b.Schema();
  EXPECT_EQ(s.Find("classes")->type, ParamType::String);
  EXPECT_EQ(s.Find("classes")->default_value, "");
  EXPECT_EQ(s.Find("keep")->default_value, "chair, table");
  EXPECT_EQ(b.Parse(json::object()).keep, (std::vector<std::string>{"chair", "table"}));
  EXPECT_EQ(b.Parse({{"classes", " chair,, table ,\tsofa , "}}).classes,
            (std::vector<std::string>{"chair", "table", "sofa"}));
  EXPECT_TRUE(b.Parse({{"classes", " , "}}).classes.empty());
  EXPECT_THROW(b.Parse({{"classes", 3}}), InputError);
}
