// voters.catalog_shape — recognises object proposals (proposals.<name>) by the catalog's
// metric sizes and top-view shapes: for every class, the catalog model whose length, width and
// height and whose top-view height profile the proposal matches best gives the class score;
// one detection per proposal and plausible class, the proposal's box, non-maximum suppressed.
//
// Why size and top view (measured on the ScanNet dev rooms, docs/experiments/): the metric size
// of an object survives the gap between simulated CAD views and real reconstructions, which
// part features and global descriptors do not (ESF on real segments: 45 % correct, size and
// height alone: 66-71 %); the top-view height profile (the distribution of each floor column's
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
//   when the left or right end of a single view cuts the proposal (ViewEdges), else 0,
// then optionally class competition (score_c * (score_c / best class score of the proposal's
// group)^compete): one object is one class, whatever variant of its cluster is looked at.
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

namespace furnihost {
namespace {

// Per output class: the spreads of the score (defaults: the shared values).
struct ClassParams {
  float long_small = 0.35f, long_big = 0.2f, short_small = 0.35f, short_big = 0.2f;
  float top_small = 0.15f, top_big = 0.1f, bottom = 0.15f, profile = 0.05f, surround = 0.3f;
  float floor_under = 0.5f, floor_over = 0.2f;
  float compete = 0.f;
  float wall_mount = 0.f;  // 0: models stand on the floor; > 0: they may also hang above it, at this extra cost
  float mount_bottom = 0.f;  // lowest bottom of a hanging model above the ground (m); lower costs as the bottom term
  float view_edge = 0.f;   // cost of a proposal the left or right edge of a single view cuts (0 = off)
  std::string source = "catalog";  // proposals scored: "catalog" (from the class's model heights), "any", or a rule name
};

const std::vector<std::pair<std::string, float ClassParams::*>>& Fields() {
  static const std::vector<std::pair<std::string, float ClassParams::*>> f = {
      {"sig_long_small", &ClassParams::long_small}, {"sig_long_big", &ClassParams::long_big},
      {"sig_short_small", &ClassParams::short_small}, {"sig_short_big", &ClassParams::short_big},
      {"sig_top_small", &ClassParams::top_small},   {"sig_top_big", &ClassParams::top_big},
      {"sig_bottom", &ClassParams::bottom},          {"sig_profile", &ClassParams::profile},
      {"sig_surround", &ClassParams::surround},      {"sig_floor_less", &ClassParams::floor_under},
      {"sig_floor_more", &ClassParams::floor_over},  {"compete", &ClassParams::compete},
      {"wall_mount", &ClassParams::wall_mount},       {"wall_mount_bottom_m", &ClassParams::mount_bottom},
      {"view_edge", &ClassParams::view_edge}};
  return f;
}

struct Model {
  std::string id, cls;  // cls: the output class (after class_map)
  float length = 0, width = 0, height = 0;
  bool wide = true;     // the model's x extent (width) is its length
  shape::Profile profile{};
  float open = 0.f;     // share of its inner footprint whose floor a sensor around it sees
  std::vector<shape::Profile> views;  // its top-view profile as each single eye around it sees it
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

  const ClassParams& Of(const std::string& c) const {
    auto it = per_class.find(c);
    return it == per_class.end() ? base : it->second;
  }
};

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
          .Number("edge_band_deg", &O::edge_band_deg, 0.01, 20, "deg",
                  "angular band at the left and right ends of each 1 deg row of a single view whose points count as "
                  "at the view's edge (view_edge)")
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

float Pen(float d, float small, float big) {
  const float s = d < 0 ? small : big;
  return d * d / (2 * s * s);
}

// The extra energy of a model hung with its bottom B above the ground: below the lowest mount.
float Hung(float B, const ClassParams& cp) {
  const float d = std::max(cp.mount_bottom - B, 0.f) / cp.bottom;
  return 0.5f * d * d;
}

// Per proposal: the first proposal with exactly its points (in order), box, ground and surround
// (itself when none before it has them).
std::vector<size_t> SameAsEarlier(const std::vector<Proposal>& items) {
  std::vector<size_t> same(items.size());
  std::unordered_map<uint64_t, std::vector<size_t>> by_hash;
  for (size_t i = 0; i < items.size(); ++i) {
    const Proposal& p = items[i];
    const uint64_t h = Fnv1a(p.indices.data(), p.indices.size() * sizeof(int));
    same[i] = i;
    auto& list = by_hash[h];
    for (size_t j : list) {
      const Proposal& q = items[j];
      if (q.indices == p.indices && q.box.min() == p.box.min() && q.box.max() == p.box.max() &&
          q.ground_z == p.ground_z && q.surround == p.surround) {
        same[i] = j;
        break;
      }
    }
    if (same[i] == i) list.push_back(i);
  }
  return same;
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

// The floor cells of a scan that hold ground-level points (within 3 cm of the ground).
class FloorCells {
 public:
  FloorCells() = default;
  explicit FloorCells(const Scan& scan) {
    if (!scan.ground) return;
    for (const auto& p : scan.points)
      if (std::abs(scan.ground->Above(p)) < 0.03f) cells_.insert(Key(p.head<2>()));
  }
  // Share of the footprint's inner cells whose floor is seen.
  float SeenUnder(const shape::Footprint& f) const {
    int n = 0, seen = 0;
    ForEachInnerCell(f.center, f.length, f.width, f.yaw, [&](const Eigen::Vector2f& q) {
      ++n;
      seen += cells_.count(Key(q)) > 0;
    });
    return n ? float(seen) / float(n) : 0.f;
  }

 private:
  static uint64_t Key(const Eigen::Vector2f& q) {
    const int64_t x = int64_t(std::floor(q.x() / kFloorCell)), y = int64_t(std::floor(q.y() / kFloorCell));
    return (uint64_t(x) << 32) ^ (uint64_t(y) & 0xffffffffu);
  }
  std::set<uint64_t> cells_;
};

// Single views (a scan with a sensor origin): 1 for the points at the left or right end of what
// the sensor saw. A camera's image ends left and right; an object the edge cuts is seen in part,
// and its part may look like a smaller object (a sofa's end like an armchair). Each point's
// azimuth and elevation about the origin (azimuth from the points' mean horizontal heading); per
// 1 deg row of elevation holding 10 or more points, those within `band_deg` of the row's smallest
// or largest azimuth (a pitched camera's edges are curves in azimuth: the rows follow them). A
// row also ends where nothing was seen beyond an object (no return from a window, a dark surface,
// open space beyond the range): what lies beside that object is unknown too, so it counts as cut
// as well. Real views are ragged there (SUN RGB-D dev rows end 5-8 deg apart from one degree of
// elevation to the next). All 0 for a scan whose points surround the origin (a panoramic laser:
// 1 % or more of them behind it, or an azimuth span over 150 deg), and for a scan without an
// origin. Linear in the points.
std::vector<uint8_t> ViewEdges(const Scan& scan, float band_deg) {
  const size_t n = scan.points.size();
  std::vector<uint8_t> edge(n, 0);
  if (!scan.origin || !scan.origin->allFinite()) return edge;
  const Eigen::Vector3f o = *scan.origin;
  Eigen::Vector2d heading = Eigen::Vector2d::Zero();
  for (const auto& p : scan.points) {
    const Eigen::Vector2f d = (p - o).head<2>();
    const float len = d.norm();
    if (p.allFinite() && len > 1e-6f) heading += (d / len).cast<double>();
  }
  if (!(heading.norm() > 1e-9)) return edge;
  heading.normalize();
  const float hx = float(heading.x()), hy = float(heading.y());
  constexpr float kDeg = float(180.0 / M_PI);
  std::vector<float> az(n, NAN);
  std::vector<int> row(n, -1);
  size_t finite = 0, behind = 0;
  float lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f d = scan.points[i] - o;
    if (!d.allFinite() || d.squaredNorm() < 1e-12f) continue;
    ++finite;
    const float f = d.x() * hx + d.y() * hy, r = d.y() * hx - d.x() * hy;  // along the heading; to its left
    behind += f <= 0.f;
    az[i] = std::atan2(r, f) * kDeg;
    row[i] = std::clamp(int(std::floor(std::atan2(d.z(), std::hypot(f, r)) * kDeg)) + 90, 0, 179);
    lo = std::min(lo, az[i]), hi = std::max(hi, az[i]);
  }
  if (finite == 0 || double(behind) >= 0.01 * double(finite) || hi - lo > 150.f) return edge;
  std::array<float, 180> row_lo, row_hi;
  std::array<int, 180> count{};
  row_lo.fill(INFINITY), row_hi.fill(-INFINITY);
  for (size_t i = 0; i < n; ++i)
    if (row[i] >= 0) {
      const int b = row[i];
      ++count[size_t(b)];
      row_lo[size_t(b)] = std::min(row_lo[size_t(b)], az[i]), row_hi[size_t(b)] = std::max(row_hi[size_t(b)], az[i]);
    }
  for (size_t i = 0; i < n; ++i)
    if (row[i] >= 0 && count[size_t(row[i])] >= 10)
      edge[i] = az[i] - row_lo[size_t(row[i])] < band_deg || row_hi[size_t(row[i])] - az[i] < band_deg;
  spdlog::debug("catalog_shape: {} of {} points at the view's left or right edge (azimuth span {:.1f} deg)",
                std::count(edge.begin(), edge.end(), uint8_t(1)), n, hi - lo);
  return edge;
}

// The share of a model's inner footprint (model frame: bounding-box bottom centre at the
// origin, size = extents) whose floor one of its training views' sensors sees: the segment
// from the floor cell's centre to the sensor passes no point of that view within 3 cm.
float OpenFloor(const std::vector<const TrainingView*>& views, const Eigen::Vector3f& size) {
  constexpr float clear = 0.03f;
  int cells = 0, open = 0;
  auto key = [&](const Eigen::Vector3f& p, int dx = 0, int dy = 0, int dz = 0) {
    const int64_t x = int64_t(std::floor(p.x() / clear)) + dx, y = int64_t(std::floor(p.y() / clear)) + dy,
                  z = int64_t(std::floor(p.z() / clear)) + dz;
    return (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
  };
  std::vector<std::unordered_map<uint64_t, std::vector<Eigen::Vector3f>>> occupied(views.size());
  for (size_t v = 0; v < views.size(); ++v)
    for (const auto& p : views[v]->scan.points) {
      const Eigen::Vector3f w = views[v]->scan.pose * p;
      occupied[v][key(w)].push_back(w);
    }
  auto near = [&](size_t v, const Eigen::Vector3f& q) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          auto it = occupied[v].find(key(q, dx, dy, dz));
          if (it == occupied[v].end()) continue;
          for (const auto& p : it->second)
            if ((p - q).squaredNorm() < clear * clear) return true;
        }
    return false;
  };
  ForEachInnerCell(Eigen::Vector2f::Zero(), std::max(size.x(), size.y()), std::min(size.x(), size.y()),
                   size.x() >= size.y() ? 0.f : float(M_PI / 2), [&](const Eigen::Vector2f& q) {
                     ++cells;
                     const Eigen::Vector3f g(q.x(), q.y(), 0.01f);
                     for (size_t v = 0; v < views.size(); ++v) {
                       if (!views[v]->scan.origin) continue;
                       const Eigen::Vector3f o = views[v]->scan.pose * *views[v]->scan.origin;
                       const float len = (o - g).norm();
                       bool blocked = false;
                       for (float t = 0.04f; t < len && !blocked; t += 0.02f) blocked = near(v, g + (o - g) * (t / len));
                       if (!blocked) {
                         ++open;
                         return;
                       }
                     }
                   });
  return cells ? float(open) / float(cells) : 0.f;
}

// The same two from the model's mesh, as a sensor around it at 1.4 m sees it (8 eyes 1.5 m
// beyond its footprint): dense surface samples, the visible ones for the profile; the floor
// under a cell is seen when the segment to an eye passes no sample within 3 cm. Noiseless, so
// a column's top is the surface's, not a range error above it.
struct MeshShape {
  shape::Profile profile;
  float open = 0.f;
  std::vector<shape::Profile> views;  // the profile each eye around it sees alone
};
MeshShape FromMesh(const CatalogModel& m, float cell) {
  double area = 0;
  const int nv = int(m.mesh.vertices.size());
  for (const auto& t : m.mesh.triangles)
    if (t.minCoeff() >= 0 && t.maxCoeff() < nv)
      area += 0.5 * double((m.mesh.vertices[t[1]] - m.mesh.vertices[t[0]]).cross(m.mesh.vertices[t[2]] - m.mesh.vertices[t[0]]).norm());
  const Points samples = area > 0 ? SampleSurface(m.mesh, float(40000.0 / area), 0) : Points{};
  const Eigen::Vector3f size = m.size;
  const Points eyes = shape::EyesAround(size);
  // The profile of the samples some eye of `from` sees: all eyes fused, then each alone.
  auto profile_seen = [&](const Points& from) {
    const std::vector<uint8_t> vis = shape::VisibleFrom(samples, from);
    std::vector<Eigen::Vector2f> xy;
    std::vector<float> h;
    for (size_t i = 0; i < samples.size(); ++i)
      if (vis[i]) xy.push_back(samples[i].head<2>()), h.push_back(samples[i].z());
    return shape::TopViewProfile(xy, h, size.z(), cell);
  };
  const shape::Profile prof = profile_seen(eyes);
  std::vector<shape::Profile> views;
  views.reserve(eyes.size());
  for (const auto& e : eyes) views.push_back(profile_seen(Points{e}));
  // Open floor: blockers are every 4th sample, hashed in 3 cm cells.
  constexpr float clear = 0.03f;
  auto key = [&](const Eigen::Vector3f& p, int dx, int dy, int dz) {
    const int64_t x = int64_t(std::floor(p.x() / clear)) + dx, y = int64_t(std::floor(p.y() / clear)) + dy,
                  z = int64_t(std::floor(p.z() / clear)) + dz;
    return (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
  };
  std::unordered_map<uint64_t, std::vector<Eigen::Vector3f>> blockers;
  for (size_t i = 0; i < samples.size(); i += 4) blockers[key(samples[i], 0, 0, 0)].push_back(samples[i]);
  auto near = [&](const Eigen::Vector3f& q) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          auto it = blockers.find(key(q, dx, dy, dz));
          if (it == blockers.end()) continue;
          for (const auto& p : it->second)
            if ((p - q).squaredNorm() < clear * clear) return true;
        }
    return false;
  };
  int cells = 0, open = 0;
  ForEachInnerCell(Eigen::Vector2f::Zero(), size.x(), size.y(), 0.f, [&](const Eigen::Vector2f& q) {
    ++cells;
    const Eigen::Vector3f g(q.x(), q.y(), 0.01f);
    for (const auto& e : eyes) {
      const float len = (e - g).norm();
      const int steps = int(std::ceil(len / 0.02f));
      bool blocked = false;
      for (int s = 0; s < steps && !blocked; ++s) {
        const float t = 0.02f + 0.98f * float(s) / float(std::max(steps - 1, 1));
        blocked = near(g + t * (e - g));
      }
      if (!blocked) {
        ++open;
        return;
      }
    }
  });
  return {prof, cells ? float(open) / float(cells) : 0.f, std::move(views)};
}

class CatalogShapeVoter : public Voter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit CatalogShapeVoter(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext&) override {
    // One entry per model: its size and the profile of all its views fused.
    std::map<std::string, std::pair<const TrainingView*, std::vector<const TrainingView*>>> by_model;
    std::vector<std::string> order;
    for (const auto& v : views) {
      auto [it, fresh] = by_model.try_emplace(v.model_id, &v, std::vector<const TrainingView*>{});
      if (fresh) order.push_back(v.model_id);
      it->second.second.push_back(&v);
    }
    nlohmann::json models = nlohmann::json::array();
    for (const auto& id : order) {
      const auto& [first, vs] = by_model.at(id);
      const Eigen::Vector3f s = first->object_size;
      MeshShape ms;
      if (first->model && !first->model->mesh.triangles.empty()) {
        ms = FromMesh(*first->model, o_.cell);
      } else {  // views without their mesh: what the views saw, fused and one by one
        std::vector<Eigen::Vector2f> xy;
        std::vector<float> h;
        for (const TrainingView* v : vs) {
          const size_t from = xy.size();
          for (const auto& p : v->scan.points) {
            const Eigen::Vector3f w = v->scan.pose * p;
            xy.push_back(w.head<2>());
            h.push_back(v->scan.HeightAboveGround(w));
          }
          if (xy.size() > from)
            ms.views.push_back(shape::TopViewProfile({xy.begin() + long(from), xy.end()},
                                                     {h.begin() + long(from), h.end()}, s.z(), o_.cell));
        }
        ms.profile = shape::TopViewProfile(xy, h, s.z(), o_.cell);
        ms.open = OpenFloor(vs, s);
      }
      const shape::Profile& prof = ms.profile;
      models.push_back({{"id", id},
                        {"class", first->cls},
                        {"size", {s.x(), s.y(), s.z()}},
                        {"profile", std::vector<float>(prof.begin(), prof.end())},
                        {"open", ms.open}});
      if (!ms.views.empty()) {
        nlohmann::json vp = nlohmann::json::array();
        for (const auto& v : ms.views) vp.push_back(std::vector<float>(v.begin(), v.end()));
        models.back()["view_profiles"] = std::move(vp);
      }
    }
    return {{"format", "catalog_shape/1"}, {"profile_cell_m", o_.cell}, {"models", models}};
  }

  void Load(const nlohmann::json& m) override {
    if (!m.is_object() || m.value("format", "") != "catalog_shape/1")
      throw InputError("not a voters.catalog_shape model (format catalog_shape/1)");
    models_.clear();
    for (const auto& j : m.at("models")) {
      Model md;
      md.id = j.at("id").get<std::string>();
      const std::string cls = j.at("class").get<std::string>();
      auto it = o_.class_map.find(cls);
      md.cls = it == o_.class_map.end() ? cls : it->second;
      const auto size = j.at("size").get<std::vector<float>>();
      const auto prof = j.at("profile").get<std::vector<float>>();
      if (size.size() != 3 || prof.size() != size_t(shape::kProfileBins))
        throw InputError("catalog_shape model " + md.id + ": bad size or profile");
      for (float v : size)
        if (!(v > 0.f) || !std::isfinite(v)) throw InputError("catalog_shape model " + md.id + ": bad size");
      md.length = std::max(size[0], size[1]);
      md.width = std::min(size[0], size[1]);
      md.height = size[2];
      md.wide = size[0] >= size[1];
      std::copy(prof.begin(), prof.end(), md.profile.begin());
      md.open = j.value("open", 0.f);
      if (j.contains("view_profiles")) {
        const auto& vs = j.at("view_profiles");
        if (!vs.is_array()) throw InputError("catalog_shape model " + md.id + ": bad view_profiles");
        for (const auto& v : vs) {
          const bool numbers = v.is_array() && std::all_of(v.begin(), v.end(), [](const auto& x) { return x.is_number(); });
          const auto f = numbers ? v.get<std::vector<float>>() : std::vector<float>();
          if (f.size() != size_t(shape::kProfileBins) ||
              !std::all_of(f.begin(), f.end(), [](float x) { return std::isfinite(x) && x >= 0.f; }))
            throw InputError("catalog_shape model " + md.id + ": bad view profile");
          shape::Profile q{};
          std::copy(f.begin(), f.end(), q.begin());
          md.views.push_back(q);
        }
      }
      if (!(md.open >= 0.f && md.open <= 1.f)) throw InputError("catalog_shape model " + md.id + ": bad open share");
      spdlog::debug("catalog_shape: model {} ({}) {:.2f} x {:.2f} x {:.2f} m, open floor {:.2f}, profile {:.3f}", md.id,
                    md.cls, md.length, md.width, md.height, md.open, fmt::join(md.profile, " "));
      models_.push_back(md);
    }
    classes_.clear();
    for (const auto& md : models_)
      if (std::find(classes_.begin(), classes_.end(), md.cls) == classes_.end()) classes_.push_back(md.cls);
    // Which proposals each class is scored on.
    source_.clear();
    for (const auto& c : classes_) {
      std::string src = o_.Of(c).source;
      if (src == "catalog") {
        std::vector<float> h;
        for (const auto& md : models_)
          if (md.cls == c) h.push_back(md.height);
        std::nth_element(h.begin(), h.begin() + h.size() / 2, h.end());
        src = h[h.size() / 2] > o_.tall_class ? "segs" : "all";
      }
      source_[c] = src;
    }
  }

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext&) override {
    VoteResult out;
    out.classes = classes_;
    if (models_.empty()) throw StageError("voters.catalog_shape: no model loaded", false);
    for (size_t s = 0; s < scenes.size(); ++s) {
      const SceneParts& sc = scenes[s];
      if (!sc.proposals || !sc.scan) {
        if (s == 0 && !sc.proposals)
          throw InputError("voters.catalog_shape recognises proposals: give it a proposer as input (e.g. proposals.clusters)");
        continue;
      }
      const Scan& scan = *sc.scan;
      const auto& items = sc.proposals->items;
      const size_t n = items.size();
      const FloorCells floor = o_.floor_term ? FloorCells(scan) : FloorCells();
      const bool views = o_.view_profiles && scan.origin.has_value();
      // The view's edges, where a class uses them.
      bool edges_used = false;
      for (const auto& c : classes_) edges_used = edges_used || o_.Of(c).view_edge > 0.f;
      const std::vector<uint8_t> at_edge =
          edges_used && scan.origin ? ViewEdges(scan, o_.edge_band_deg) : std::vector<uint8_t>();
      const size_t C = classes_.size();
      std::vector<std::vector<float>> score(C, std::vector<float>(n, 0.f));
      std::vector<std::vector<int>> best_model(C, std::vector<int>(n, -1));
      std::vector<std::vector<std::map<std::string, float>>> evidence(C, std::vector<std::map<std::string, float>>(n));
      std::vector<shape::Footprint> foot(n);
      // Each proposal's footprint, profile and scores are its own: scored in parallel (in
      // order when tracing, so the trace reads as before).
      auto score_one = [&](size_t i) {
        const Proposal& p = items[i];
        if (p.indices.size() < 10) return;
        std::vector<Eigen::Vector2f> xy(p.indices.size());
        std::vector<float> h(p.indices.size());
        for (size_t k = 0; k < p.indices.size(); ++k) {
          const Eigen::Vector3f& q = scan.points[size_t(p.indices[k])];
          xy[k] = q.head<2>();
          h[k] = q.z() - p.ground_z;
        }
        foot[i] = shape::OrientedFootprint(xy);
        const float L = std::max(foot[i].length, 0.02f), W = std::max(foot[i].width, 0.02f);
        const float T = std::max(p.box.max().z() - p.ground_z, 0.02f), B = std::max(p.box.min().z() - p.ground_z, 0.f);
        const shape::Profile prof = shape::TopViewProfile(xy, h, T, o_.cell);
        const float seen = o_.floor_term ? floor.SeenUnder(foot[i]) : 0.f;
        // Cut by the view's edge: 3 or more of its points there.
        int edge_points = 0;
        if (!at_edge.empty())
          for (int k : p.indices) edge_points += at_edge[size_t(k)];
        const float cut = edge_points >= 3 ? 1.f : 0.f;
        for (size_t c = 0; c < C; ++c) {
          const ClassParams& cp = o_.Of(classes_[c]);
          float best = INFINITY;
          std::array<float, 6> terms{};  // of the best model: length, width, top, bottom, profile, floor
          for (size_t m = 0; m < models_.size(); ++m) {
            const Model& md = models_[m];
            if (md.cls != classes_[c]) continue;
            const float emd = shape::ProfileDistance(prof, md.profile);
            std::array<float, 6> t = {Pen(std::log(L / md.length), cp.long_small, cp.long_big),
                                      Pen(std::log(W / md.width), cp.short_small, cp.short_big),
                                      Pen(std::log(T / md.height), cp.top_small, cp.top_big),
                                      0.5f * (B / cp.bottom) * (B / cp.bottom),
                                      emd * emd / (2 * cp.profile * cp.profile),
                                      o_.floor_term ? Pen(seen - md.open, cp.floor_under, cp.floor_over) : 0.f};
            // A single view: the profile of the model as the one eye around it that explains the
            // proposal's best, if closer than all eyes fused.
            if (views)
              for (const shape::Profile& v : md.views) {
                const float d = shape::ProfileDistance(prof, v);
                t[4] = std::min(t[4], d * d / (2 * cp.profile * cp.profile));
              }
            float E = t[0] + t[1] + t[2] + t[3] + t[4] + t[5];
            if (cp.wall_mount > 0.f) {
              // Hanging: the model spans the proposal's height extent; no bottom gap, floor or top-view
              // evidence (a sensor below a wall cabinet rarely sees its top).
              const std::array<float, 6> tl = {t[0], t[1],
                                               Pen(std::log(std::max(T - B, 0.02f) / md.height), cp.top_small, cp.top_big),
                                               cp.wall_mount + Hung(B, cp), 0.f, 0.f};
              const float El = tl[0] + tl[1] + tl[2] + tl[3] + tl[4] + tl[5];
              if (El < E) E = El, t = tl;
            }
            if (E < best) best = E, best_model[c][i] = int(m), terms = t;
          }
          score[c][i] = std::exp(-best - p.surround / cp.surround - cut * cp.view_edge);
          evidence[c][i] = {{"length_m", L},          {"width_m", W},         {"top_m", T},
                            {"bottom_m", B},          {"surround", p.surround}, {"floor_seen", seen},
                            {"points", float(p.indices.size())},
                            {"e_length", terms[0]},   {"e_width", terms[1]},  {"e_top", terms[2]},
                            {"e_bottom", terms[3]},   {"e_profile", terms[4]}, {"e_floor", terms[5]},
                            {"e_surround", p.surround / cp.surround}};
          if (!at_edge.empty() && cp.view_edge > 0.f) {
            evidence[c][i]["view_edge_points"] = float(edge_points);
            evidence[c][i]["e_view_edge"] = cut * cp.view_edge;
          }
          if (spdlog::should_log(spdlog::level::trace) && score[c][i] >= o_.min_score)
            spdlog::trace("catalog_shape: {} {} box ({:.2f} {:.2f} {:.2f})-({:.2f} {:.2f} {:.2f}) L {:.3f} W {:.3f} T {:.3f} "
                          "B {:.3f} surround {:.3f} floor seen {:.3f} -> {} {:.4f}",
                          p.how, classes_[c], p.box.min().x(), p.box.min().y(), p.box.min().z(), p.box.max().x(),
                          p.box.max().y(), p.box.max().z(), L, W, T, B, p.surround, seen,
                          models_[size_t(best_model[c][i])].id, score[c][i]);
        }
      };
      if (spdlog::should_log(spdlog::level::trace)) {
        for (size_t i = 0; i < n; ++i) score_one(i);
      } else {
        // A proposal of exactly the points, box, ground and surround of an earlier one (another
        // radius or rule that found the same cluster: half the proposals of some rooms) scores
        // as that one: scored once, copied. Its group, and so its competition, stays its own.
        const std::vector<size_t> same = SameAsEarlier(items);
        std::vector<size_t> first;
        for (size_t i = 0; i < n; ++i)
          if (same[i] == i) first.push_back(i);
        tbb::parallel_for(size_t(0), first.size(), [&](size_t k) { score_one(first[k]); });
        for (size_t i = 0; i < n; ++i) {
          const size_t j = same[i];
          if (j == i) continue;
          foot[i] = foot[j];
          for (size_t c = 0; c < C; ++c)
            score[c][i] = score[c][j], best_model[c][i] = best_model[c][j], evidence[c][i] = evidence[c][j];
        }
      }
      // Class competition within each group (the variants of one cluster are one object).
      std::map<int, float> group_best;
      std::vector<float> best_of(n, 0.f);
      for (size_t i = 0; i < n; ++i) {
        for (size_t c = 0; c < C; ++c) best_of[i] = std::max(best_of[i], score[c][i]);
        float& g = group_best[items[i].group];
        g = std::max(g, best_of[i]);
      }
      for (size_t c = 0; c < C; ++c) {
        const float a = o_.Of(classes_[c]).compete;
        if (a > 0.f)
          for (size_t i = 0; i < n; ++i) {
            const float b = std::max(group_best[items[i].group], 1e-12f);
            evidence[c][i]["compete_factor"] = std::pow(score[c][i] / b, a);
            score[c][i] *= std::pow(score[c][i] / b, a);
          }
        const std::string& src = source_.at(classes_[c]);
        if (src != "any")
          for (size_t i = 0; i < n; ++i)
            if (!RuleListed(src, items[i].source)) score[c][i] = 0.f;
      }
      // Non-maximum suppression per class by box IoU, then the hypotheses.
      for (size_t c = 0; c < C; ++c) {
        std::vector<size_t> order;
        for (size_t i = 0; i < n; ++i)
          if (score[c][i] >= o_.min_score && best_model[c][i] >= 0) order.push_back(i);
        const auto thr = o_.thresholds.find(classes_[c]);
        const float t = thr == o_.thresholds.end() ? o_.default_threshold : thr->second;
        for (size_t i : shape::SuppressOverlaps(std::move(order), score[c], items, o_.nms_iou, o_.nms_whole)) {
          const Model& md = models_[size_t(best_model[c][i])];
          out.hypotheses.push_back(shape::ProposalHypothesis(classes_[c], score[c][i], t, items[i], int(i), int(s),
                                                             foot[i], md.id, md.wide, scan.pose));
          out.hypotheses.back().evidence = std::move(evidence[c][i]);
        }
      }
    }
    return out;
  }

 private:
  Options o_;
  std::vector<Model> models_;
  std::vector<std::string> classes_;
  std::map<std::string, std::string> source_;
};

}  // namespace
}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::CatalogShapeVoter, "voters.catalog_shape", "1.4.0",
                 "recognises object proposals by the catalog models' metric sizes and top-view height profiles")
