// voters.catalog_shape, private to the plugin: its options, the models it keeps and the voter, whose
// steps live one concern per file:
//   catalog_shape.cpp  the parameters
//   model.cpp          the model: each catalog model's size and top-view profiles (Train, Load)
//   vote.cpp           the proposals' class scores, hypotheses and suppression (Vote)
//   size_index.hpp     the k-d tree over a class's models that proposes its candidate models
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/plugin.hpp"
#include "shape/shape.hpp"
#include "size_index.hpp"

namespace furnihost::catalog_shape {

// Per output class: the spreads of the score (defaults: the shared values).
struct ClassParams {
  float long_small = 0.35f, long_big = 0.2f, short_small = 0.35f, short_big = 0.2f;
  float top_small = 0.15f, top_big = 0.1f, bottom = 0.15f, profile = 0.05f, surround = 0.3f;
  float floor_under = 0.5f, floor_over = 0.2f;
  float compete = 0.f;
  float wall_mount = 0.f;  // 0: models stand on the floor; > 0: they may also hang above it, at this extra cost
  float mount_bottom = 0.f;  // lowest bottom of a hanging model above the ground (m); lower costs as the bottom term
  float view_edge = 0.f;   // cost of a proposal the left or right edge of a single view cuts (0 = off)
  float max_top = 0.f;     // highest top of a proposal the class is scored on, above the ground (m; 0 = any)
  std::string source = "catalog";  // proposals scored: "catalog" (from the class's model heights), "any", or a rule name
};

struct Model {
  std::string id, cls;  // cls: the output class (after class_map)
  float length = 0, width = 0, height = 0;
  bool wide = true;     // the model's x extent (width) is its length
  shape::Profile profile{};
  float open = 0.f;     // share of its inner footprint whose floor a sensor around it sees
  std::vector<shape::Profile> views;  // its top-view profile as each single eye around it sees it
  // Where its top quarter stands (a chair's or sofa's back): the centroid of its surface above
  // 3/4 of its height, model frame, over its x and y extents; zero when unknown or central.
  Eigen::Vector2f top_offset = Eigen::Vector2f::Zero();
};

struct Options {
  std::map<std::string, std::string> class_map;  // catalog class -> output class
  ClassParams base;
  std::map<std::string, ClassParams> per_class;
  std::map<std::string, float> thresholds;  // operating threshold per output class (accepted above)
  float default_threshold = 0.f;
  float min_score = 1e-3f;
  float nms_iou = 0.25f;
  float nms_whole = 0.f;  // a box this many times a better one's volume, holding it, is not its duplicate (0 = off)
  float cell = 0.05f;
  float tall_class = 1.2f;
  bool floor_term = true;
  bool view_profiles = false;  // single views (scans with a sensor origin): also the models' one-eye profiles
  float edge_band_deg = 1.5f;  // a point this close to its row's end of the view lies at the view's edge
  bool model_index = true;  // score a class's candidate models from its index, not all its models

  const ClassParams& Of(const std::string& c) const {
    auto it = per_class.find(c);
    return it == per_class.end() ? base : it->second;
  }
};

// Each parameter declared once (catalog_shape.cpp).
const ParamBinding<Options>& Binding();

// Whether rule is one of the comma-separated names of `list` ("all,segs").
bool RuleListed(const std::string& list, const std::string& rule);

// A profile's cumulative shares summed over each of kProfileChunks runs of bins, in double: the
// sum over the runs of |P(a) - P(b)|, over kProfileBins, is at most shape::ProfileDistance(a, b)
// (the mean of |cumulative difference| over the bins).
constexpr int kProfileChunks = 1;
inline std::array<double, kProfileChunks> ChunkSums(const shape::Profile& p) {
  std::array<double, kProfileChunks> out{};
  double c = 0;
  for (int i = 0; i < shape::kProfileBins; ++i) out[size_t(i * kProfileChunks / shape::kProfileBins)] += c += double(p[size_t(i)]);
  return out;
}

// Inner footprint cells (10 cm, the rectangle shrunk by 10 cm on every side) of a footprint.
constexpr float kFloorCell = 0.10f;
template <class F>
void ForEachInnerCell(const Eigen::Vector2f& c, float length, float width, float yaw, F&& f) {
  const float l = std::max(length - 2 * kFloorCell, kFloorCell), w = std::max(width - 2 * kFloorCell, kFloorCell);
  const float co = std::cos(yaw), si = std::sin(yaw);
  // Cells centred on the footprint (symmetric: the same cells when its axes come out reversed).
  const int nu = std::max(1, int(std::lround(l / kFloorCell))), nv = std::max(1, int(std::lround(w / kFloorCell)));
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const float u = (float(i) - 0.5f * float(nu - 1)) * kFloorCell, v = (float(j) - 0.5f * float(nv - 1)) * kFloorCell;
      f(Eigen::Vector2f(c.x() + u * co - v * si, c.y() + u * si + v * co));
    }
}

class CatalogShapeVoter : public Voter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit CatalogShapeVoter(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext&) override;
  // A model with a mesh is learned from the mesh (its size, top-view profile, open floor and
  // one-eye profiles): training need not scan it. Each model is learned on its own, so models
  // trained on runs of the catalog merge (Merge: their model lists joined in order).
  StageNeeds Needs() const override {
    StageNeeds n;
    n.training_scans = false;
    n.training_merges = true;
    return n;
  }
  nlohmann::json Merge(const std::vector<nlohmann::json>& parts) override;

  void Load(const nlohmann::json& m) override;

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext&) override;

 private:
  Options o_;
  std::vector<Model> models_;
  std::vector<std::string> classes_;
  std::map<std::string, std::string> source_;
  std::vector<SizeIndex> index_;  // per class (classes_'s order): its models' index
};

}  // namespace furnihost::catalog_shape
