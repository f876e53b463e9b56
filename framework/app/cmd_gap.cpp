// furnihost gap — how far a graph's training views are from real scans (issue 20, item 3):
// the part features of the catalog's simulated views, taken by the graph's training sensor and
// by each --sensor variant (a preset, say), against the features of the parts of the real
// objects in a dataset's scans, segmented and described by the same stages.
//
// Per variant and feature: the 1-D Wasserstein distance between the simulated and the real
// parts' values in units of the real values' standard deviation (0 = the same distribution);
// and, over all features z-scored by the real parts, each real part's distance to the nearest
// simulated part (how far a real part is from anything trained on). Histograms per feature.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>

#include <tbb/parallel_for.h>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/host/catalog.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"
#include "furnihost/host/pipeline.hpp"
#include "plots.hpp"

namespace fs = std::filesystem;

namespace furnihost::app {
namespace {

// Parts' raw feature rows (the features stage's columns, then the part's point count).
struct PartSet {
  std::string name;
  std::vector<std::vector<double>> rows;
  size_t objects = 0;              // real objects / simulated views the parts come from
  std::vector<std::string> cls;    // per row: the evaluated class of its object or model
};

void AddParts(const Segmentation& seg, const FeatureMatrix& f, const std::vector<size_t>& which,
              const std::vector<std::string>& cls, PartSet& out) {
  for (size_t n = 0; n < which.size(); ++n) {
    const size_t k = which[n];
    std::vector<double> r(size_t(f.values.cols()) + 1);
    for (Eigen::Index c = 0; c < f.values.cols(); ++c) r[size_t(c)] = f.values(Eigen::Index(k), c);
    r.back() = double(seg.parts[k].indices.size());
    bool finite = true;
    for (double v : r) finite = finite && std::isfinite(v);
    if (!finite) continue;
    out.rows.push_back(std::move(r));
    out.cls.push_back(cls[n]);
  }
}

// The rows of one class.
PartSet OfClass(const PartSet& s, const std::string& c) {
  PartSet o{s.name, {}, 0, {}};
  for (size_t i = 0; i < s.rows.size(); ++i)
    if (s.cls[i] == c) o.rows.push_back(s.rows[i]), o.cls.push_back(c);
  return o;
}

std::vector<double> Column(const PartSet& s, size_t c) {
  std::vector<double> v;
  v.reserve(s.rows.size());
  for (const auto& r : s.rows) v.push_back(r[c]);
  return v;
}

// 1-D Wasserstein-1 distance of two samples: the area between their empirical CDFs.
double Wasserstein1(std::vector<double> a, std::vector<double> b) {
  if (a.empty() || b.empty()) return NAN;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  size_t i = 0, j = 0;
  double x = std::min(a[0], b[0]), w = 0;
  while (i < a.size() || j < b.size()) {
    const double next = j == b.size() || (i < a.size() && a[i] <= b[j]) ? a[i] : b[j];
    w += std::abs(double(i) / a.size() - double(j) / b.size()) * (next - x);
    x = next;
    while (i < a.size() && a[i] == x) ++i;
    while (j < b.size() && b[j] == x) ++j;
  }
  return w;
}

double Median(std::vector<double> v) { return Summarise(std::move(v)).median; }

// A column's scale for z-scores and W1/sd: the evaluation's mean and (sample) deviation, 1 for a
// constant column.
MeanStd Moments(const std::vector<double>& v) {
  MeanStd m = MeanAndStd(v);
  if (!(m.std > 1e-12)) m.std = 1.0;
  if (!std::isfinite(m.mean)) m.mean = 0.0;
  return m;
}

// Median over the real parts of the distance to the nearest of `n` simulated parts (every
// k-th, so variants of different sizes compare: a bigger set is nearer by its size alone),
// features z-scored by the real parts' moments.
double MedianNearest(const PartSet& real, const PartSet& all, const std::vector<MeanStd>& z, size_t n) {
  if (real.rows.empty() || all.rows.empty() || n == 0) return NAN;
  PartSet sim;
  for (size_t k = 0; k < n; ++k) sim.rows.push_back(all.rows[k * all.rows.size() / n]);
  const size_t d = z.size();
  auto scaled = [&](const PartSet& s) {
    std::vector<float> m(s.rows.size() * d);
    for (size_t i = 0; i < s.rows.size(); ++i)
      for (size_t c = 0; c < d; ++c) m[i * d + c] = float((s.rows[i][c] - z[c].mean) / z[c].std);
    return m;
  };
  const std::vector<float> r = scaled(real), q = scaled(sim);
  std::vector<double> nearest(real.rows.size());
  tbb::parallel_for(size_t(0), real.rows.size(), [&](size_t i) {
    float best = INFINITY;
    for (size_t k = 0; k < sim.rows.size(); ++k) {
      float s = 0;
      for (size_t c = 0; c < d && s < best; ++c) {
        const float e = r[i * d + c] - q[k * d + c];
        s += e * e;
      }
      best = std::min(best, s);
    }
    nearest[i] = std::sqrt(double(best));
  });
  return Median(nearest);
}

// "NAME=JSON" of a --sensor variant.
std::pair<std::string, nlohmann::json> ParseVariant(const std::string& text) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--sensor " + text + ": expected NAME=PARAMS, e.g. room='{\"preset\": \"room_reconstruction\"}'");
  const std::string name = text.substr(0, eq);
  if (name == "real" || name == "graph") throw InputError("--sensor " + text + ": '" + name + "' is taken; use another name");
  const nlohmann::json j = ParseCliJson(text.substr(eq + 1), "--sensor " + name);
  if (!j.is_object())
    throw InputError("--sensor " + name + ": PARAMS must be a JSON object of the training sensor's parameters");
  return {name, j};
}

}  // namespace

int RunGap(const std::vector<std::string>& args) {
  CLI::App app{"How far a graph's training views are from real scans: part features of the catalog's simulated views\n"
               "(the graph's training sensor and each --sensor variant) against those of the real objects' parts\n"
               "in a dataset, segmented and described by the graph's stages. Writes gap.md, gap.json and\n"
               "hist/<feature>.svg/.png.\n"
               "usage: furnihost gap --graph G.json --dataset D.json [--sensor NAME=PARAMS ...] [--out DIR]",
               "gap"};
  CommonOptions common;
  std::string graph, dataset_path, out = "furnihost-out/gap";
  std::vector<std::string> variant_args;
  double inside = 0.8, margin = 0.05;
  common.Add(app);
  app.add_option("--graph,-g", graph, "graph config with a training sensor, a segmenter and a features stage")->required();
  app.add_option("--dataset,-d", dataset_path, "dataset manifest of real scans with ground truth")->required();
  app.add_option("--sensor", variant_args,
                 "a training-view variant NAME=PARAMS: the training sensor's parameters (JSON) instead of the graph's, "
                 "e.g. room='{\"preset\": \"room_reconstruction\"}' (repeatable; the graph's own is 'graph')");
  app.add_option("--out,-o", out, "output folder");
  app.add_option("--inside", inside, "a real part is an object's when this share of its points lies in the object's box")
      ->check(CLI::Range(0.01, 1.0));
  app.add_option("--margin", margin, "margin added around the ground-truth boxes [m]")->check(CLI::Range(0.0, 1.0));
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  auto reg = common.MakeRegistry();
  std::vector<std::pair<std::string, nlohmann::json>> variants;
  for (const auto& v : variant_args) variants.push_back(ParseVariant(v));
  GraphConfig g = common.LoadGraph(graph, *reg);
  const Dataset dataset = LoadDataset(dataset_path);
  const StageConfig* train = g.Find(g.training_sensor);
  const StageConfig* feat = g.FirstOfKind(StageKind::Features);
  const StageConfig* seg = feat ? g.InputOfKind(*feat, StageKind::Segmenter) : nullptr;
  if (!train || !feat || !seg)
    throw InputError(graph + ": gap needs a training sensor and a features stage fed by a segmenter (a part-based graph "
                             "such as scannet_hough.json)");
  if (g.catalog.empty()) throw InputError(graph + ":/catalog: missing (gap scans the catalog's models)");
  if (fs::exists(out) && !fs::is_directory(out)) throw InputError("--out " + out + ": exists and is not a folder");
  RunContext ctx = common.Context(g.seed);
  // Sensor variants: the graph's own first, each resolved against the sensor's schema.
  const ParamSchema& sensor_schema = reg->Find(train->type)->params;
  std::vector<std::pair<std::string, nlohmann::json>> sensors = {{"graph", train->params}};
  for (const auto& [name, params] : variants)
    sensors.emplace_back(name, sensor_schema.Resolve(params, "--sensor " + name));

  // Real parts: each scan through the graph (no model: segmentation and features only).
  Pipeline pipeline(g, *reg);
  PartSet real{"real", {}, 0, {}};
  std::vector<std::string> feature_names;
  {
    Progress progress("gap: real scans", dataset.scenes.size());
    for (const DatasetScene& sc : dataset.scenes) {
      Pipeline::SceneInput in;
      in.path = sc.scan;
      in.origin = sc.origin;
      in.frame = sc.frame;
      Pipeline::Result r = pipeline.Detect({in}, nullptr, nullptr, ctx);
      if (r.segmentations.empty() || r.features.empty()) throw StageError("gap: the graph gave no parts for " + sc.scan, false);
      const Segmentation& s = r.segmentations[0];
      const FeatureMatrix& f = r.features[0];
      feature_names = f.names;
      const Eigen::Isometry3f to_user = r.world_to_user;
      std::vector<std::pair<Eigen::AlignedBox3f, std::string>> boxes;
      for (const auto& gt : ReadGroundTruth(sc.gt))
        if (const auto c = dataset.classes.Map(gt.cls)) {
          Eigen::AlignedBox3f b = GroundTruthBox(gt);
          b.min().array() -= float(margin);
          b.max().array() += float(margin);
          boxes.emplace_back(b, *c);
        }
      real.objects += boxes.size();
      std::vector<size_t> ours;
      std::vector<std::string> their;
      for (size_t k = 0; k < s.parts.size(); ++k) {
        const auto& idx = s.parts[k].indices;
        if (idx.empty()) continue;
        for (const auto& [b, c] : boxes) {
          size_t in_box = 0;
          for (int i : idx) in_box += b.contains(to_user * r.scans[0].points[size_t(i)]);
          if (double(in_box) >= inside * double(idx.size())) {
            ours.push_back(k);
            their.push_back(c);
            break;
          }
        }
      }
      AddParts(s, f, ours, their, real);
      progress.Tick();
    }
    progress.Done();
  }
  if (real.rows.empty()) throw InputError(dataset_path + ": no segmented part lies in a ground-truth box of an evaluated class");

  // Simulated parts: every catalog model of an evaluated class, through each sensor variant.
  const Catalog catalog = LoadCatalog(g.catalog);
  if (std::none_of(catalog.models.begin(), catalog.models.end(), [&](const CatalogModel& m) { return dataset.classes.Map(m.cls); }))
    throw InputError(g.catalog + ": no model of a class " + dataset_path + " evaluates");
  auto segmenter = reg->CreateAs<Segmenter>(seg->type, seg->params);
  auto features = reg->CreateAs<Features>(feat->type, feat->params);
  std::vector<PartSet> sims;
  for (const auto& [name, params] : sensors) {
    auto sensor = reg->CreateAs<Sensor>(train->type, params);
    PartSet set{name, {}, 0, {}};
    Progress progress("gap: training views '" + name + "'", catalog.models.size());
    for (const CatalogModel& m : catalog.models) {
      progress.Tick();
      if (!dataset.classes.Map(m.cls)) continue;
      SensorRequest req;
      req.objects.push_back({&m, Eigen::Isometry3f::Identity()});
      for (const Scan& view : sensor->Acquire(req, ctx)) {
        if (view.points.size() < 3) continue;
        const Segmentation s = segmenter->Segment(view, ctx);
        const FeatureMatrix f = features->Compute(view, s, ctx);
        std::vector<size_t> all(s.parts.size());
        for (size_t k = 0; k < all.size(); ++k) all[k] = k;
        AddParts(s, f, all, std::vector<std::string>(all.size(), *dataset.classes.Map(m.cls)), set);
        ++set.objects;
      }
    }
    progress.Done();
    if (set.rows.empty()) throw InputError("--sensor " + name + ": the training views gave no parts");
    sims.push_back(std::move(set));
  }

  // Distances to the real parts.
  feature_names.push_back("points");
  const size_t d = feature_names.size();
  std::vector<MeanStd> z(d);
  for (size_t c = 0; c < d; ++c) z[c] = Moments(Column(real, c));
  size_t common_n = real.rows.size();
  for (const auto& s : sims) common_n = std::min(common_n, s.rows.size());
  nlohmann::json report = {{"graph", graph}, {"dataset", dataset_path}, {"real_parts", real.rows.size()},
                           {"real_objects", real.objects}, {"features", feature_names}, {"variants", nlohmann::json::array()}};
  std::ostringstream md;
  md << std::fixed << std::setprecision(3);
  md << "# Training views against real parts\n\n"
     << "`furnihost gap --graph " << graph << " --dataset " << dataset_path << "`: " << real.rows.size()
     << " real parts of " << real.objects << " ground-truth objects. Training views: `graph`, the graph's own sensor";
  for (const auto& [name, params] : variants) md << "; `" << name << "`, " << params.dump();
  md << ".\n\n"
     << "W1/sd: the 1-D Wasserstein distance between the variant's and the real parts' values, in real standard "
        "deviations (mean over the " << d << " columns; 0 = the same distributions). NN: median over the real parts "
        "of the distance to the nearest of " << common_n << " simulated parts (every k-th part of each variant, so "
        "their sizes do not decide), all columns z-scored by the real parts.\n\n"
     << "| training views | views | parts | points per part (median) | W1/sd mean | NN median | farthest columns (W1/sd) |\n"
     << "|---|---:|---:|---:|---:|---:|---|\n";
  std::vector<std::vector<double>> w1(sims.size(), std::vector<double>(d));
  for (size_t v = 0; v < sims.size(); ++v) {
    const PartSet& s = sims[v];
    double mean = 0;
    for (size_t c = 0; c < d; ++c) mean += (w1[v][c] = Wasserstein1(Column(s, c), Column(real, c)) / z[c].std);
    mean /= double(d);
    const double nn = MedianNearest(real, s, z, common_n);
    std::vector<size_t> order(d);
    for (size_t c = 0; c < d; ++c) order[c] = c;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return w1[v][a] > w1[v][b]; });
    md << "| " << s.name << " | " << s.objects << " | " << s.rows.size() << " | " << std::setprecision(0)
       << Median(Column(s, d - 1)) << std::setprecision(3) << " | " << mean << " | " << nn << " | ";
    for (size_t k = 0; k < std::min<size_t>(3, d); ++k)
      md << (k ? ", " : "") << feature_names[order[k]] << " " << std::setprecision(2) << w1[v][order[k]] << std::setprecision(3);
    md << " |\n";
    nlohmann::json per;
    for (size_t c = 0; c < d; ++c) per[feature_names[c]] = w1[v][c];
    report["variants"].push_back({{"name", s.name}, {"sensor", sensors[v].second}, {"views", s.objects},
                                  {"parts", s.rows.size()}, {"w1_over_sd", per}, {"w1_over_sd_mean", mean},
                                  {"nearest_median", nn}});
  }
  md << "| real | " << real.objects << " objects | " << real.rows.size() << " | " << std::setprecision(0)
     << Median(Column(real, d - 1)) << std::setprecision(3) << " | 0 | - | |\n\n";
  md << "W1/sd per column:\n\n| column |";
  for (const auto& s : sims) md << " " << s.name << " |";
  md << "\n|---|";
  for (size_t v = 0; v < sims.size(); ++v) md << "---:|";
  md << "\n";
  for (size_t c = 0; c < d; ++c) {
    md << "| " << feature_names[c] << " |";
    for (size_t v = 0; v < sims.size(); ++v) md << " " << std::setprecision(2) << w1[v][c] << " |";
    md << "\n";
  }

  // Per class: W1/sd (the real parts' overall deviations) between the class's real parts and the
  // parts of its models' views.
  std::vector<std::string> classes;
  for (const auto& c : dataset.classes.classes)
    if (!OfClass(real, c).rows.empty()) classes.push_back(c);
  md << "\nW1/sd mean per class (the class's real parts against the views of its catalog models):\n\n| training views |";
  for (const auto& c : classes) md << " " << c << " (" << OfClass(real, c).rows.size() << ") |";
  md << "\n|---|";
  for (size_t k = 0; k < classes.size(); ++k) md << "---:|";
  md << "\n";
  for (size_t v = 0; v < sims.size(); ++v) {
    md << "| " << sims[v].name << " |";
    nlohmann::json per = nlohmann::json::object();
    for (const auto& c : classes) {
      const PartSet rc = OfClass(real, c), sc = OfClass(sims[v], c);
      double mean = NAN;
      if (!sc.rows.empty()) {
        mean = 0;
        for (size_t col = 0; col < d; ++col) mean += Wasserstein1(Column(sc, col), Column(rc, col)) / z[col].std;
        mean /= double(d);
        per[c] = mean;
      }
      md << " " << std::setprecision(3) << mean << " |";
    }
    md << "\n";
    report["variants"][v]["w1_over_sd_mean_per_class"] = per;
  }

  // Histograms: each column over the real parts' 1st-99th percentiles, 30 bins, share of parts.
  fs::create_directories(fs::path(out) / "hist");
  for (size_t c = 0; c < d; ++c) {
    std::vector<double> rv = Column(real, c);
    std::sort(rv.begin(), rv.end());
    double lo = rv[size_t(0.01 * double(rv.size() - 1))], hi = rv[size_t(0.99 * double(rv.size() - 1))];
    if (!(hi > lo)) hi = lo + 1.0;
    constexpr int kBins = 30;
    auto histogram = [&](const PartSet& s, int color, const std::string& label) {
      std::vector<double> h(kBins, 0.0);
      for (const auto& r : s.rows) {
        const int b = int(std::floor((r[c] - lo) / (hi - lo) * kBins));
        h[size_t(std::clamp(b, 0, kBins - 1))] += 1.0 / double(s.rows.size());
      }
      PlotSeries p;
      p.label = label;
      p.color = color;
      for (int b = 0; b < kBins; ++b) {
        p.points.push_back({lo + (hi - lo) * b / kBins, h[size_t(b)]});
        p.points.push_back({lo + (hi - lo) * (b + 1) / kBins, h[size_t(b)]});
      }
      return p;
    };
    std::vector<PlotSeries> series = {histogram(real, 7, "real parts (" + std::to_string(real.rows.size()) + ")")};
    for (size_t v = 0; v < sims.size(); ++v) {
      std::ostringstream label;
      label << sims[v].name << " (" << sims[v].rows.size() << " parts, W1/sd " << std::setprecision(2) << std::fixed
            << w1[v][c] << ")";
      series.push_back(histogram(sims[v], int(v), label.str()));
    }
    double top = 0;
    for (const auto& s : series)
      for (const auto& p : s.points) top = std::max(top, p[1]);
    PlotAxes ax;
    ax.x_label = feature_names[c] + " (ends: all beyond the real 1st-99th percentiles)";
    ax.y_label = "share of parts";
    ax.x0 = lo;
    ax.x1 = hi;
    ax.y1 = top > 0 ? top * 1.05 : 1.0;
    ax.markers = false;
    WriteLinePlot((fs::path(out) / "hist" / feature_names[c]).string(), feature_names[c], ax, series);
  }
  AtomicWriteText((fs::path(out) / "gap.md").string(), md.str());
  WriteJson((fs::path(out) / "gap.json").string(), report);
  if (!common.quiet) std::cout << md.str() << "-> " << out << "/gap.md, gap.json, hist/<column>.svg/.png\n";
  return 0;
}

}  // namespace furnihost::app
