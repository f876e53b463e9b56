// voters.catalog_shape — recognises object proposals (proposals.<name>) by the catalog's
// metric sizes and top-view shapes: for every class, the catalog model whose length, width and
// height and whose top-view height profile the proposal matches best gives the class score;
// one detection per proposal and plausible class, the proposal's box, non-maximum suppressed.
//
// Why size and top view (docs/experiments/ has the comparisons): the metric size of an object
// survives the gap between simulated CAD views and real reconstructions, which part features
// and global descriptors do not (on real segments the size and height alone name the class
// more often than ESF); the top-view height profile (the distribution of each floor column's
// highest point as a share of the object's height) tells a chair's seat-and-back from a
// table's one level and a sofa's two, and needs no points the scan lacks (undersides, legs).
//
// Score of class c for a proposal of footprint L x W (L >= W), top T and bottom B above the
// ground, profile h and surround s (Proposal::surround):
//   E_m = pen(ln L/L_m; long) + pen(ln W/W_m; short) + pen(ln T/H_m; top) + (B / sig_bottom)^2 / 2
//         + EMD(h, h_m)^2 / (2 sig_profile^2)
//   pen(d) = d^2 / (2 s^2), s = sig_*_small when the proposal is smaller than the model (a partial
//   scan is tolerated), sig_*_big when larger;
//   with wall_mount > 0 (a class whose objects may hang on a wall, as kitchen wall cabinets do),
//   also E_m' = pen(ln L/L_m) + pen(ln W/W_m) + pen(ln (T - B)/H_m; top) + wall_mount: the model
//   lifted to the proposal's bottom, without the bottom, profile and floor terms, plus
//   (max(0, wall_mount_bottom_m - B) / sig_bottom)^2 / 2 (wall units hang high); E_m = min(E_m, E_m');
//   score_c = exp(-min over the class's models m of E_m - s / sig_surround - cut * view_edge), cut = 1
//   when the left or right end of a single view cuts the proposal (ViewEdges), else 0; 0 when the
//   proposal's top stands higher than the class's max_top_m (a bound on where the class's objects
//   end, not on its catalog: a table's top does not stand 1.5 m up, whatever models its catalog has),
// then optionally class competition (score_c * (score_c / best class score of the proposal's
// group)^compete): one object is one class, whatever variant of its cluster is looked at.
// The minimum over a class's models is searched in a k-d tree over their log sizes, open floor
// and profile cumulative sums (size_index.hpp), best first: the size, bottom and floor terms and
// the profiles' difference in mean bound E_m from below, so the energy is computed only for the
// models that can still beat the best energy found; the choice and the score are those of
// scoring every model (model_index false does that).
// Per class, non-maximum suppression by box IoU; with nms_whole_ratio, a box that holds a better
// one and is that many times its volume is kept beside it: a fragment (the lower half of a wall
// cabinet, which fits a smaller catalog model) may score better than its whole.
//
// Training: the catalog models' sizes (TrainingView::object_size), and the profile and open
// floor of each model's mesh as a sensor around it sees them (views without a mesh: of their
// simulated views fused). Also the profile each single eye of that ring (or each simulated view)
// sees alone: with view_profiles, a scan with a sensor origin (one view, one side of each
// object) takes the closest of those and the fused one as h_m.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
#include <unordered_map>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "decision/decision_params.hpp"
#include "shape/shape.hpp"
#include "catalog_shape.hpp"

namespace furnihost::catalog_shape {

namespace {

const std::vector<std::pair<std::string, float ClassParams::*>>& Fields() {
  static const std::vector<std::pair<std::string, float ClassParams::*>> f = {
      {"sig_long_small", &ClassParams::long_small}, {"sig_long_big", &ClassParams::long_big},
      {"sig_short_small", &ClassParams::short_small}, {"sig_short_big", &ClassParams::short_big},
      {"sig_top_small", &ClassParams::top_small},   {"sig_top_big", &ClassParams::top_big},
      {"sig_bottom", &ClassParams::bottom},          {"sig_profile", &ClassParams::profile},
      {"sig_surround", &ClassParams::surround},      {"sig_floor_less", &ClassParams::floor_under},
      {"sig_floor_more", &ClassParams::floor_over},  {"compete", &ClassParams::compete},
      {"wall_mount", &ClassParams::wall_mount},       {"wall_mount_bottom_m", &ClassParams::mount_bottom},
      {"view_edge", &ClassParams::view_edge},         {"max_top_m", &ClassParams::max_top}};
  return f;
}

}  // namespace

// Whether rule is one of the comma-separated names of `list` ("all,segs").
bool RuleListed(const std::string& list, const std::string& rule) {
  size_t start = 0;
  while (start <= list.size()) {
    const size_t end = std::min(list.find(',', start), list.size());
    if (list.compare(start, end - start, rule) == 0) return true;
    start = end + 1;
  }
  return false;
}

namespace {

ClassParams ParseClassParams(const nlohmann::json& j, ClassParams p, const std::string& where) {
  if (!j.is_object()) throw InputError(where + ": expected an object of spreads, e.g. {\"sig_top_big\": 0.2}");
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (it.key() == "source") {
      if (!it->is_string()) throw InputError(where + "/source: expected a string");
      p.source = it->get<std::string>();
      if (p.source.empty() || p.source.front() == ',' || p.source.back() == ',' || p.source.find(",,") != std::string::npos)
        throw InputError(where + "/source: expected 'catalog', 'any' or rule names, comma-separated (e.g. \"all,segs\"), got \"" +
                         p.source + "\"");
      continue;
    }
    auto f = std::find_if(Fields().begin(), Fields().end(), [&](const auto& x) { return x.first == it.key(); });
    if (f == Fields().end()) {
      std::string names = "source";
      for (const auto& x : Fields()) names += ", " + x.first;
      throw InputError(where + "/" + it.key() + ": unknown; valid: " + names);
    }
    if (!it->is_number() || !(it->get<double>() >= 0.0) || it->get<double>() > 100.0 ||
        (f->first.rfind("sig_", 0) == 0 && !(it->get<double>() > 0.0)))
      throw InputError(where + "/" + it.key() + ": expected a number in " +
                       (f->first.rfind("sig_", 0) == 0 ? "(0, 100]" : "[0, 100]"));
    p.*(f->second) = it->get<float>();
  }
  return p;
}

}  // namespace

// Each parameter declared once; its default is Options{}'s (the shared spreads: ClassParams{}'s).
const ParamBinding<Options>& Binding() {
  using O = Options;
  // The shared spread of ClassParams field `f`, bound through Options::base.
  auto base = [](float ClassParams::*f) { return [f](O& o) -> float& { return o.base.*f; }; };
  static const auto b =
      BindDecision(ParamBinding<O>()
          .Object("class_map", nlohmann::json::object(),
                  "catalog class -> detected class, e.g. {\"armchair\": \"chair\", \"desk\": \"table\"}: the models "
                  "of merged classes compete as one class (one detection per object)",
                  ClassMapParser<O>(&O::class_map))
          .DetectionOnly()
          .Object("class_params", nlohmann::json::object(),
                  "per detected class, spreads overriding the shared ones below ({\"table\": {\"sig_long_big\": 0.5}}); "
                  "also 'source': which proposals a class is scored on ('catalog' = segs for classes whose models are "
                  "mostly taller than tall_class_m, else all; 'any'; or proposer rule names, comma-separated: 'all,segs')",
                  // Runs after the shared spreads are parsed: a class's spreads start from them.
                  [](O& o, const nlohmann::json& j) {
                    for (auto it = j.begin(); it != j.end(); ++it)
                      o.per_class[it.key()] = ParseClassParams(*it, o.base, "class_params/" + it.key());
                  })
          .DetectionOnly()
          .Number("sig_long_small", base(&ClassParams::long_small), 1e-3, 100, "1",
                  "spread of ln(length / model length) when shorter than the model")
          .DetectionOnly()
          .Number("sig_long_big", base(&ClassParams::long_big), 1e-3, 100, "1", "... when longer")
          .DetectionOnly()
          .Number("sig_short_small", base(&ClassParams::short_small), 1e-3, 100, "1",
                  "spread of ln(width / model width) when narrower")
          .DetectionOnly()
          .Number("sig_short_big", base(&ClassParams::short_big), 1e-3, 100, "1", "... when wider")
          .DetectionOnly()
          .Number("sig_top_small", base(&ClassParams::top_small), 1e-3, 100, "1",
                  "spread of ln(top height / model height) when lower")
          .DetectionOnly()
          .Number("sig_top_big", base(&ClassParams::top_big), 1e-3, 100, "1", "... when higher")
          .DetectionOnly()
          .Number("sig_bottom", base(&ClassParams::bottom), 1e-3, 100, "m", "spread of the bottom's height above the ground")
          .DetectionOnly()
          .Number("sig_profile", base(&ClassParams::profile), 1e-3, 100, "1",
                  "spread of the top-view height profile's distance to the model's")
          .DetectionOnly()
          .Number("sig_surround", base(&ClassParams::surround), 1e-3, 100, "1", "score factor exp(-surround / this)")
          .DetectionOnly()
          .Bool("view_profiles", &O::view_profiles,
                "on scans with a sensor origin (single views), also compare the proposal's top-view profile with "
                "the model's as each single eye around it sees it, and take the closest (one view sees one side: "
                "an armrest hides the seat behind it); reconstructions are always compared with the fused profile")
          .DetectionOnly()
          .Bool("floor_term", &O::floor_term,
                "compare the floor seen under the proposal with the model's open floor (under a table or chair "
                "the floor shows, under a cabinet or a bed never): a share of floor cells seen above the model's is "
                "strong evidence against it, below it weak (chairs and people hide it)")
          .DetectionOnly()
          .Number("sig_floor_less", base(&ClassParams::floor_under), 1e-3, 100, "1",
                  "spread of (floor seen - model's open floor) when less is seen")
          .DetectionOnly()
          .Number("sig_floor_more", base(&ClassParams::floor_over), 1e-3, 100, "1", "... when more is seen")
          .DetectionOnly()
          .Number("compete", base(&ClassParams::compete), 0, 100, "1", "class competition exponent (0 = off)")
          .Number("wall_mount", base(&ClassParams::wall_mount), 0, 100, "1",
                  "0: the models stand on the floor; > 0: they may also hang above it (kitchen wall cabinets): the "
                  "model then spans the proposal's own height extent, the bottom, top-view profile and floor terms are "
                  "dropped (a sensor below a wall cabinet rarely sees its top) and this cost is added to the energy")
          .DetectionOnly()
          .Number("wall_mount_bottom_m", base(&ClassParams::mount_bottom), 0, 100, "m",
                  "with wall_mount: the lowest a hanging model's bottom sits above the ground (kitchen wall units hang "
                  "~1.35 m up, 18 in above a 36 in counter); a hanging proposal whose bottom is lower by d costs "
                  "(d / sig_bottom)^2 / 2 more (0 = any height)")
          .DetectionOnly()
          .Number("view_edge", base(&ClassParams::view_edge), 0, 100, "1",
                  "on scans with a sensor origin (single views): a cost added to the energy of a proposal that the "
                  "left or right end of the view cuts (3 or more of its points within edge_band_deg of the end of "
                  "their row of the view): what the camera saw of it may be part of a larger object, e.g. a sofa's "
                  "end looking like an armchair (0 = off)")
          .DetectionOnly()
          .Number("max_top_m", base(&ClassParams::max_top), 0, 100, "m",
                  "the highest a proposal's top may stand above the ground for the class to be scored on it (a "
                  "table's top is not 1.5 m up, even where a catalog holds a desk with a hutch; 0 = any height)")
          .DetectionOnly()
          .Number("edge_band_deg", &O::edge_band_deg, 0.01, 20, "deg",
                  "angular band at the left and right ends of each 1 deg row of a single view whose points count as "
                  "at the view's edge (view_edge)")
          .DetectionOnly()
          .Bool("model_index", &O::model_index,
                "score each class's candidate models only: a k-d tree over the models' log sizes, open floor and "
                "profile means, searched best first, skips every model whose size, bottom and floor terms and "
                "profile mean's distance alone exceed the best energy found (the same choice and scores as scoring "
                "all models, in time sublinear in the catalog); false scores every model")
          .DetectionOnly()
          , DecisionFields{&O::thresholds, &O::default_threshold, &O::min_score, &O::nms_iou, &O::nms_whole},
          {"in [0, 1]; below the threshold kept as rejected candidates", "", true})
          .Number("profile_cell_m", &O::cell, 0.005, 1, "m", "column size of the top-view height profile")
          .Number("tall_class_m", &O::tall_class, 0, 10, "m",
                  "classes whose catalog models are mostly taller are made of large vertical faces: source 'catalog' "
                  "scores them on the proposals that keep such faces (rule 'segs')")
          .DetectionOnly();
  return b;
}

}  // namespace furnihost::catalog_shape

FURNIHOST_PLUGIN(furnihost::catalog_shape::CatalogShapeVoter, "voters.catalog_shape", "1.8.0",
                 "recognises object proposals by the catalog models' metric sizes and top-view height profiles")
