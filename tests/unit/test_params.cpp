#include <gtest/gtest.h>

#include "furnihost/host/normaliser.hpp"
#include "furnihost/params.hpp"

using furnihost::InputError;
using furnihost::ParamSchema;
using nlohmann::json;

namespace {

ParamSchema Schema() {
  return ParamSchema()
      .Number("angle_deg", 40, 0, 180, "angle")
      .Int("min_points", 10, 1, 1e6, "points")
      .Bool("flag", false, "flag")
      .Enum("mode", "a", {"a", "b"}, "mode")
      .NumberList("origin", {}, -10, 10, "origin")
      .String("name", "x", "name")
      .Object("thresholds", json{{"chair", 0.6}}, "per class");
}

std::string ErrorOf(const json& given) {
  try {
    Schema().Resolve(given, "g.json:/stages/seg/params");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// A "preset" string and a "presets" table: the preset's values fill what is not given, are
// validated as if given, and a config's own "presets" entries add to the declared ones.
TEST(Params, PresetsFillWhatIsNotGiven) {
  const ParamSchema s = ParamSchema()
                            .Number("range_m", 4, 0, 10, "range")
                            .Int("views", 16, 1, 100, "views")
                            .String("preset", "none", "preset")
                            .Object("presets", json{{"far", {{"range_m", 8}, {"views", 4}}}}, "presets");
  json r = s.Resolve({{"preset", "far"}, {"views", 2}}, "w");
  EXPECT_EQ(r["range_m"], 8);
  EXPECT_EQ(r["views"], 2);
  EXPECT_EQ(s.Resolve(r, "w"), r);  // resolving again changes nothing
  r = s.Resolve(json::object(), "w");
  EXPECT_EQ(r["range_m"], 4);
  EXPECT_EQ(s.Resolve({{"preset", "none"}}, "w")["views"], 16);
  r = s.Resolve({{"preset", "near"}, {"presets", {{"near", {{"range_m", 1}}}}}}, "w");
  EXPECT_EQ(r["range_m"], 1);
  EXPECT_EQ(s.Resolve({{"preset", "far"}, {"presets", {{"near", {{"range_m", 1}}}}}}, "w")["range_m"], 8);
  auto error = [&](const json& given) {
    try {
      s.Resolve(given, "g.json:/stages/sim/params");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error({{"preset", "close"}}), "g.json:/stages/sim/params/preset: unknown preset \"close\"; valid: none, far");
  EXPECT_NE(error({{"preset", "x"}, {"presets", {{"x", {{"range_m", 20}}}}}}).find("/range_m: expected a number in [0, 10]"),
            std::string::npos);
  EXPECT_NE(error({{"preset", "x"}, {"presets", {{"x", {{"rnage_m", 2}}}}}}).find("/presets/x/rnage_m: not a parameter"),
            std::string::npos);
  EXPECT_NE(error({{"preset", "far"}, {"presets", 3}}).find("/presets: expected an object"), std::string::npos);
  EXPECT_NE(error({{"preset", true}}).find("/preset: expected a preset's name"), std::string::npos);
  // Without a "presets" table a "preset" parameter is an ordinary string.
  const ParamSchema plain = ParamSchema().String("preset", "none", "p").Int("views", 16, 1, 100, "v");
  EXPECT_EQ(plain.Resolve({{"preset", "far"}}, "w")["views"], 16);
}

TEST(Params, DefaultsAreFilled) {
  json r = Schema().Resolve(json::object(), "w");
  EXPECT_EQ(r["angle_deg"], 40);
  EXPECT_EQ(r["min_points"], 10);
  EXPECT_EQ(r["mode"], "a");
  EXPECT_EQ(r["thresholds"]["chair"], 0.6);
  EXPECT_EQ(Schema().Resolve(nullptr, "w"), r);
  EXPECT_EQ(Schema().Resolve({{"angle_deg", 30}}, "w")["angle_deg"], 30);
}

TEST(Params, EachErrorNamesThePointer) {
  EXPECT_EQ(ErrorOf({{"angle_deg", "forty"}}),
            "g.json:/stages/seg/params/angle_deg: expected a number in [0, 180], got \"forty\"");
  EXPECT_NE(ErrorOf({{"angle_deg", 200}}).find("in [0, 180], got 200"), std::string::npos);
  EXPECT_NE(ErrorOf({{"min_points", 2.5}}).find("/min_points: expected an integer"), std::string::npos);
  EXPECT_NE(ErrorOf({{"flag", 1}}).find("/flag: expected true or false"), std::string::npos);
  EXPECT_NE(ErrorOf({{"mode", "c"}}).find("/mode: expected one of a, b"), std::string::npos);
  EXPECT_NE(ErrorOf({{"origin", {1, "x"}}}).find("/origin: expected a list of numbers"), std::string::npos);
  EXPECT_NE(ErrorOf({{"origin", {1, 20}}}).find("/origin"), std::string::npos);
  EXPECT_NE(ErrorOf({{"name", 3}}).find("/name: expected a string"), std::string::npos);
  EXPECT_NE(ErrorOf({{"thresholds", 3}}).find("/thresholds: expected an object"), std::string::npos);
  const std::string unknown = ErrorOf({{"angel_deg", 3}});
  EXPECT_NE(unknown.find("/angel_deg: unknown parameter; valid: angle_deg, min_points"), std::string::npos) << unknown;
  EXPECT_NE(ErrorOf(json::array()).find("expected an object of parameters"), std::string::npos);
}

// An offending value is shown on one line in printable ASCII, at most 60 characters: a name in
// another script escaped as JSON writes it, a long value cut (config errors show values alike).
TEST(Params, OffendingValuesAreShownShortAndPrintable) {
  EXPECT_EQ(ErrorOf({{"angle_deg", "St\u00fchle"}}),
            "g.json:/stages/seg/params/angle_deg: expected a number in [0, 180], got \"St\\u00fchle\"");
  const std::string long_error = ErrorOf({{"angle_deg", std::string(100, 'x')}});
  const std::string shown = "got \"" + std::string(56, 'x') + "...";
  EXPECT_EQ(long_error.substr(long_error.size() - shown.size()), shown) << long_error;
  EXPECT_EQ(ErrorOf({{"angle_deg", "a\tb"}}).find('\t'), std::string::npos);
}

TEST(Params, SchemaJsonListsRanges) {
  json j = Schema().ToJson();
  ASSERT_EQ(j.size(), 7u);
  EXPECT_EQ(j[0]["name"], "angle_deg");
  EXPECT_EQ(j[0]["max"], 180);
  EXPECT_EQ(j[3]["choices"], json({"a", "b"}));
}

TEST(Params, RangeTextPrintsNumbersAsWritten) {
  furnihost::ParamSpec s;
  EXPECT_EQ(furnihost::RangeText(s), "");
  s.min = 0;
  s.max = 2147483647;
  EXPECT_EQ(furnihost::RangeText(s), " in [0, 2147483647]");
  s.min = -1e-6;
  s.max.reset();
  EXPECT_EQ(furnihost::RangeText(s), " in [-1e-06, inf]");
  s.min.reset();
  s.max = 0.25;
  EXPECT_EQ(furnihost::RangeText(s), " in [-inf, 0.25]");
}

TEST(Params, DetectionOnlyParamsLeaveTheTrainingKey) {
  ParamSchema s = ParamSchema()
                      .Int("k", 40, 1, 1e6, "words")
                      .Object("thresholds", json{{"chair", 0.6}}, "per class")
                      .DetectionOnly()
                      .Number("max_distance", 0, 0, 10, "cut")
                      .DetectionOnly();
  const json a = s.Resolve({{"thresholds", {{"chair", 2.0}}}}, "w");
  const json b = s.Resolve({{"max_distance", 0.3}}, "w");
  EXPECT_NE(a, b);
  EXPECT_EQ(s.TrainingParams(a), s.TrainingParams(b));
  EXPECT_EQ(s.TrainingParams(a), json({{"k", 40}}));
  EXPECT_NE(s.TrainingParams(s.Resolve({{"k", 20}}, "w")), s.TrainingParams(a));
  EXPECT_FALSE(s.ToJson()[0].contains("detection_only"));
  EXPECT_EQ(s.ToJson()[1]["detection_only"], true);
  EXPECT_THROW(ParamSchema().DetectionOnly(), std::logic_error);
}

TEST(Normaliser, RoundTripAndClamping) {
  furnihost::FeatureMatrix a, b;
  a.values.resize(2, 2);
  a.values << 0, 10, 2, 20;
  b.values.resize(1, 2);
  b.values << 1, 30;
  auto n = furnihost::Normaliser::Fit({&a, &b});
  EXPECT_FLOAT_EQ(n.min[1], 10);
  EXPECT_FLOAT_EQ(n.max[1], 30);
  auto n2 = furnihost::Normaliser::FromJson(n.ToJson());
  furnihost::FeatureMatrix t;
  t.values.resize(2, 2);
  t.values << 1, 20, 4, std::nanf("");
  EXPECT_EQ(n2.Apply(t), 2u);  // 4 > max, NaN
  EXPECT_FLOAT_EQ(t.values(0, 0), 0.5f);
  EXPECT_FLOAT_EQ(t.values(0, 1), 0.5f);
  EXPECT_FLOAT_EQ(t.values(1, 0), 1.f);
  EXPECT_FLOAT_EQ(t.values(1, 1), 0.f);
  // Excess in ranges: row 0 inside; row 1: column 0 is 4 with range [0, 2] -> 1 range beyond.
  ASSERT_EQ(t.excess.size(), 2);
  EXPECT_FLOAT_EQ(t.excess[0], 0.f);
  EXPECT_FLOAT_EQ(t.excess[1], 1.f);
  furnihost::FeatureMatrix below;
  below.values.resize(1, 2);
  below.values << 1, 5;  // 10 - 5 = 5 below the min of a range of 20
  n2.Apply(below);
  EXPECT_FLOAT_EQ(below.excess[0], 0.25f);
  furnihost::FeatureMatrix wrong;
  wrong.values.resize(1, 3);
  EXPECT_THROW(n2.Apply(wrong), InputError);
}
