#include <gtest/gtest.h>

#include <map>
#include <string>

#include "decision/decision_params.hpp"
#include "furnihost/error.hpp"

namespace furnihost {
namespace {

struct Nested {
  int k = 3;
  DecisionOptions decision{{{"chair", 0.5f}}, 0.2, 1e-3, 0.25, 2.};
};

struct Flat {
  std::map<std::string, float> thresholds;
  float default_threshold = 1.f;
};

ParamBinding<Nested> NestedBinding() {
  ParamBinding<Nested> b;
  b.Int("k", &Nested::k, 1, 10, "count", "k");
  return BindDecision(b, [](Nested& o) -> DecisionOptions& { return o.decision; }, {"in [0, 1]", "", true});
}

TEST(Decision, DeclaresEveryParameterWithOneRangeAndAUnit) {
  const auto b = NestedBinding();
  for (const char* name : {"thresholds", "default_threshold", "min_score", "nms_iou", "nms_whole_ratio"}) {
    const ParamSpec* s = b.Schema().Find(name);
    ASSERT_NE(s, nullptr) << name;
    EXPECT_EQ(s->unit, "1") << name;
    EXPECT_FALSE(s->training) << name;
    ASSERT_TRUE(s->min.has_value()) << name;
    EXPECT_EQ(*s->min, 0.0) << name;
  }
  EXPECT_EQ(*b.Schema().Find("min_score")->max, 1.0);
  EXPECT_EQ(*b.Schema().Find("nms_iou")->max, 1.0);
  EXPECT_FALSE(b.Schema().Find("thresholds")->max.has_value());
  EXPECT_FALSE(b.Schema().Find("default_threshold")->max.has_value());
  EXPECT_NE(b.Schema().Find("thresholds")->help.find("(score in [0, 1])"), std::string::npos);
}

TEST(Decision, DefaultsComeFromThePluginsStruct) {
  const auto o = NestedBinding().Parse(nlohmann::json::object());
  EXPECT_EQ(o.decision.thresholds.at("chair"), 0.5f);
  EXPECT_EQ(o.decision.default_threshold, 0.2);
  EXPECT_EQ(o.decision.min_score, 1e-3);
  EXPECT_EQ(o.decision.nms_iou, 0.25);
  EXPECT_EQ(o.decision.nms_whole_ratio, 2.);
  const auto p = NestedBinding().Parse({{"min_score", 0.5}, {"thresholds", {{"table", 2.0}}}});
  EXPECT_EQ(p.decision.min_score, 0.5);
  EXPECT_EQ(p.decision.thresholds.at("table"), 2.f);
}

TEST(Decision, RejectsOutOfRangeValuesNamingTheParameter) {
  const auto b = NestedBinding();
  for (const auto& [name, value] : std::map<std::string, nlohmann::json>{
           {"min_score", 1.5}, {"nms_iou", -0.1}, {"default_threshold", -1}, {"thresholds", {{"chair", -0.5}}}}) {
    try {
      b.Parse({{name, value}});
      ADD_FAILURE() << name << " accepted " << value.dump();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

TEST(Decision, PluginsWithoutSuppressionDeclareOnlyTheThresholds) {
  ParamBinding<Flat> b;
  BindDecision(b, DecisionFields{&Flat::thresholds, &Flat::default_threshold}, {"", "synthesis: ", false});
  ASSERT_EQ(b.Schema().Specs().size(), 2u);
  EXPECT_EQ(b.Schema().Specs()[0].name, "thresholds");
  EXPECT_EQ(b.Schema().Specs()[1].name, "default_threshold");
  EXPECT_TRUE(b.Schema().Specs()[1].training);
  EXPECT_EQ(b.Schema().Specs()[1].help.rfind("synthesis: ", 0), 0u);
  EXPECT_EQ(b.Parse(nlohmann::json::object()).default_threshold, 1.f);
}

struct Named {
  std::map<std::string, std::string> class_map;
};

TEST(Decision, ClassMapParserFillsTheMapAndNamesABadEntry) {
  ParamBinding<Named> b;
  b.Object("class_map", nlohmann::json::object(), "map", ClassMapParser<Named>(&Named::class_map));
  EXPECT_EQ(b.Parse({{"class_map", {{"desk", "table"}}}}).class_map.at("desk"), "table");
  for (const nlohmann::json& bad : {nlohmann::json(""), nlohmann::json(3)}) {
    try {
      b.Parse({{"class_map", {{"desk", bad}}}});
      ADD_FAILURE() << bad.dump() << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("class_map/desk: expected a class name"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace furnihost
