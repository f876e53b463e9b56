// voters.pcl_ism — PCL 1.13's Implicit Shape Model (pcl::ism::ImplicitShapeModelEstimation,
// Knopp et al. 2010) wrapped as a voter: the off-the-shelf Hough-voting baseline a user would
// otherwise pick. It learns on the same simulated views as the paper's voter, but with its own
// pipeline: voxel key points, FPFH descriptors (33 bins), a k-means codebook and, per visual
// word, the direction from the key point to the view's centroid in a frame tied to its normal.
//
// Frames and units: metres, world frame (Scan::pose applied), z up. The object centre ISM
// learns is the centroid of the training cloud we pass (PCL's extractDescriptors averages the
// cloud), i.e. TrainingView::object_centroid up to the few points dropped for undefined normals.
//
// What PCL 1.13 does that this wrapper works around (each checked in the 1.13 sources):
//  * computeKMeansClustering calls srand(time(nullptr)) itself, so srand() before trainISM is
//    overwritten; `time` is redirected, for that header only, to a clock that returns the
//    seed of the run (furnihost_pcl_ism_clock). Its k-means++ then draws rand() from that state. rand()
//    is process-global: training is deterministic as long as no other thread calls rand()
//    while trainISM runs (the host trains one stage at a time).
//  * ISMModel's copy constructor and operator= resize clusters_centers_ to 3 columns and then
//    write descriptors_dimension_ (33) of them: a heap overflow. Models live in shared_ptr only.
//  * calculateSigmas (used when no sigma is given) is O(N^2) per view; we set the sigmas from
//    the catalog sizes: sigma_fraction x half the 3-D diagonal. PCL's rule of thumb (0.1) makes
//    the learned weights exp(-residual^2 / sigma^2) so small that, times the statistical weights,
//    they fall under findObjects' FLT_EPSILON cut: on our synthetic room no table vote survived.
//  * findObjects drops votes of strength <= FLT_EPSILON, an absolute cut, while strengths scale
//    as 1 / #training words: trained on the whole catalog (608 views, 533k words) ISM cast
//    649 votes on a ScanNet room, all classes together. min_vote_weight makes the cut relative
//    to each class's largest statistical weight (a per-class scale, which moves no peak).
//  * findStrongestPeaks runs 100 mean shifts over every vote within 3 sigma: 50k votes on one
//    table took 12 s. Votes are merged per cube of sigma / 4 first (same peaks on the test
//    room, 10-100x faster), and the scene floor is cut (ISM learns isolated objects; a floor
//    matches seat and table-top words and floods the density).
//  * alignYCoordWithNormal divides by |(n_y, n_z)| and |(n_x, n_y)|: a normal exactly along x
//    or z gives NaN directions, which saveModelToFile writes as "nan" and loadModelFromfile
//    cannot read back. Such normals get a fixed 1e-3 n_y nudge, and the model is sanitised.
//  * FPFH returns NaN histograms for points without neighbours and ISM only skips histograms
//    summing to ~0, so NaN would reach the k-means; FiniteFpfh turns them into zeros.
//  * findObjects scans the estimator's number_of_clusters_, not the model's: set it from the
//    model before voting.
#include <pcl/features/fpfh.h>
#include <pcl/features/impl/fpfh.hpp>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/memory.h>
#include <pcl/point_types.h>
#include <pcl/recognition/implicit_shape_model.h>
#include <pcl/search/kdtree.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

namespace furnihost_pcl_ism_clock {
// The value PCL's k-means passes to srand(); set right before trainISM.
thread_local std::time_t seed_value = 0;
inline std::time_t SeededTime(std::time_t*) { return seed_value; }
}  // namespace furnihost_pcl_ism_clock

// Only the k-means' srand(time(nullptr)) in this header uses `time`; every header it includes
// is already included above, so the macro reaches nothing else.
#define time(arg) ::furnihost_pcl_ism_clock::SeededTime(arg)
#include <pcl/recognition/impl/implicit_shape_model.hpp>
#undef time

#include "decision/decision_params.hpp"
#include "furnihost/plugin.hpp"

namespace furnihost::voters {

namespace {

constexpr const char* kFormat = "voters.pcl_ism/1";
constexpr int kBins = 33;
using Hist = pcl::Histogram<kBins>;
using Ism = pcl::ism::ImplicitShapeModelEstimation<kBins, pcl::PointXYZ, pcl::Normal>;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using NormalCloud = pcl::PointCloud<pcl::Normal>;
using VoteList = pcl::features::ISMVoteList<pcl::PointXYZ>;
using IsmModel = pcl::features::ISMModel;
using PeakVector = std::vector<pcl::ISMPeak, Eigen::aligned_allocator<pcl::ISMPeak>>;

// FPFH whose undefined histograms are zeros (ISM skips those) instead of NaN (ISM keeps those).
class FiniteFpfh : public pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, Hist> {
 protected:
  void computeFeature(PointCloudOut& out) override {
    pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, Hist>::computeFeature(out);
    for (auto& h : out.points)
      if (!std::all_of(h.histogram, h.histogram + kBins, [](float v) { return std::isfinite(v); }))
        std::fill(h.histogram, h.histogram + kBins, 0.f);
  }
};

// Reads the votes of an ISMVoteList, which keeps them protected (no getter in 1.13).
struct VoteListAccess : VoteList {
  static const pcl::PointCloud<pcl::InterestPoint>& Votes(const VoteList& list) {
    return *(list.*(&VoteListAccess::votes_));
  }
};

// Everything ISM's voting needs from one model; n_vw = clusters holding words of the class.
struct LoadedModel {
  std::shared_ptr<IsmModel> ism;  // never copied: see the header comment
  std::vector<std::string> classes;
  std::vector<Eigen::Vector3f> sizes;  // mean catalog extents per class [m]
  std::vector<int> n_vw;
  // Factor applied to the class's statistical weights in memory (see min_vote_weight); votes
  // and densities are divided by it again, so they stay in ISM's units.
  std::vector<double> strength_scale;
  float sampling_size_m = 0.05f, normal_radius_m = 0.08f, fpfh_radius_m = 0.15f;
};

// Half the horizontal diagonal: the footprint radius of a class [m].
float FloorRadius(const Eigen::Vector3f& size) { return 0.5f * size.head<2>().norm(); }

// A point cloud with normals ready for ISM: normals oriented towards `viewpoint`, points whose
// normal is undefined dropped, and the nudge that keeps ISM's local frame defined.
struct Oriented {
  Cloud::Ptr points{new Cloud};
  NormalCloud::Ptr normals{new NormalCloud};
  size_t dropped = 0;
};

Oriented Orient(const Points& world, const Eigen::Vector3f& viewpoint, float normal_radius) {
  Cloud::Ptr in(new Cloud);
  in->reserve(world.size());
  for (const auto& p : world)
    if (p.allFinite()) in->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  Oriented o;
  if (in->empty()) return o;
  NormalCloud n;
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  ne.setInputCloud(in);
  ne.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  ne.setRadiusSearch(normal_radius);
  ne.setViewPoint(viewpoint.x(), viewpoint.y(), viewpoint.z());
  ne.compute(n);
  o.points->reserve(in->size());
  o.normals->reserve(in->size());
  for (size_t i = 0; i < in->size(); ++i) {
    pcl::Normal nn = n[i];
    Eigen::Vector3f v(nn.normal_x, nn.normal_y, nn.normal_z);
    if (!v.allFinite() || v.squaredNorm() < 0.5f) {
      ++o.dropped;
      continue;
    }
    if (std::hypot(v.x(), v.y()) < 1e-3f || std::hypot(v.y(), v.z()) < 1e-3f) {
      v.y() = std::copysign(1e-3f, v.y());
      v.normalize();
    }
    nn.normal_x = v.x();
    nn.normal_y = v.y();
    nn.normal_z = v.z();
    o.points->push_back((*in)[i]);
    o.normals->push_back(nn);
  }
  return o;
}

// A unique temp file, removed when this goes out of scope.
class TempFile {
 public:
  TempFile() {
    std::string pattern = (std::filesystem::temp_directory_path() / "furnihost_pcl_ism_XXXXXX").string();
    const int fd = ::mkstemp(pattern.data());
    if (fd < 0) throw StageError("cannot create a temporary file in " + pattern, false);
    ::close(fd);
    path_ = pattern;
  }
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  std::string& path() { return path_; }

 private:
  std::string path_;
};

// PCL writes and reads its model only through files.
std::string ModelToText(IsmModel& model) {
  TempFile f;
  if (!model.saveModelToFile(f.path())) throw StageError("ISM: cannot write " + f.path(), false);
  std::ifstream in(f.path());
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::shared_ptr<IsmModel> ModelFromText(const std::string& text) {
  TempFile f;
  {
    std::ofstream out(f.path());
    out << text;
    if (!out) throw StageError("ISM: cannot write " + f.path(), false);
  }
  auto model = std::make_shared<IsmModel>();
  if (!model->loadModelFromfile(f.path())) throw StageError("ISM: cannot read " + f.path(), false);
  return model;
}

// Zeroes what would not survive PCL's text format (NaN, inf); returns how many values changed.
size_t Sanitize(IsmModel& m) {
  size_t fixed = 0;
  for (unsigned w = 0; w < m.number_of_visual_words_; ++w) {
    const bool ok = std::isfinite(m.learned_weights_[w]) && m.directions_to_center_.row(w).allFinite();
    if (ok) continue;
    // A word without a defined direction must not vote: ISM drops votes of weight ~0.
    m.learned_weights_[w] = 0.f;
    m.directions_to_center_.row(w).setZero();
    ++fixed;
  }
  for (auto& per_class : m.statistical_weights_)
    for (float& s : per_class)
      if (!std::isfinite(s)) s = 0.f, ++fixed;
  for (float& s : m.sigmas_)
    if (!std::isfinite(s)) s = 0.f, ++fixed;
  for (Eigen::Index i = 0; i < m.clusters_centers_.size(); ++i)
    if (!std::isfinite(m.clusters_centers_.data()[i])) m.clusters_centers_.data()[i] = 0.f, ++fixed;
  return fixed;
}

std::vector<std::string> SplitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// Merges the votes falling into one cube of edge `cell` into a vote at their strength-weighted
// mean with the summed strength, in order of first appearance (PCL's peak search starts from
// votes spread evenly through the list). cell <= 0 keeps every vote. Returns x, y, z, strength.
std::vector<Eigen::Vector4f> Aggregate(const pcl::PointCloud<pcl::InterestPoint>& votes, float cell) {
  std::vector<Eigen::Vector4f> out;
  if (!(cell > 0.f)) {
    out.reserve(votes.size());
    for (const auto& v : votes) out.emplace_back(v.x, v.y, v.z, v.strength);
    return out;
  }
  std::unordered_map<uint64_t, size_t> index;
  std::vector<Eigen::Vector4d> sums;  // strength-weighted x, y, z and strength
  for (const auto& v : votes) {
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) continue;
    // 21 bits per axis: cells repeat only 2^21 cells apart (84 km at 4 cm).
    uint64_t key = 0;
    for (float c : {v.x, v.y, v.z})
      key = (key << 21) | (static_cast<uint64_t>(static_cast<int64_t>(std::floor(c / cell))) & 0x1fffffu);
    const auto [it, fresh] = index.emplace(key, sums.size());
    if (fresh) sums.emplace_back(Eigen::Vector4d::Zero());
    const double w = v.strength;
    sums[it->second] += Eigen::Vector4d(w * v.x, w * v.y, w * v.z, w);
  }
  out.reserve(sums.size());
  for (const auto& s : sums)
    out.emplace_back(static_cast<float>(s.x() / s.w()), static_cast<float>(s.y() / s.w()),
                     static_cast<float>(s.z() / s.w()), static_cast<float>(s.w()));
  return out;
}

template <class F>
void RunParallel(int threads, size_t n, F&& f) {
  auto body = [&] { tbb::parallel_for(size_t(0), n, [&](size_t i) { f(i); }); };
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(body);
  } else {
    body();
  }
}

}  // namespace

// Options of the wrapper; training ones are stored in the model, detection ones are not.
struct IsmOptions {
  // Training (ISM's own pipeline).
  float sampling_size_m = 0.05f;  // voxel edge of ISM's key points [m] (ISM's setSamplingSize)
  float normal_radius_m = 0.08f;  // normal estimation radius [m]
  float fpfh_radius_m = 0.15f;    // FPFH support radius [m]
  int number_of_clusters = 40;    // codebook size k
  float sigma_fraction = 0.2f;    // vote kernel sigma / class radius (half 3-D diagonal)
  bool n_vot = true;              // ISM's 1/#votes-of-the-word normalisation of the weights
  // Detection.
  float peak_radius_fraction = 1.0f;  // non-maxima radius / class footprint radius
  std::map<std::string, float> thresholds;
  float default_threshold = 0.f;
  int max_hypotheses = 10;           // per class
  std::string classes_text;          // comma-separated, as given
  std::vector<std::string> classes;  // split classes_text; empty = every trained class
  float viewpoint_height_m = 1.5f;   // normals face (scene centre x, y, this) when no origin
  float floor_cut_m = 0.05f;         // scene points below this world height are dropped
  float grid_cell_m = 0.05f;
  int max_plot_votes = 200000;       // 0 = keep every vote
  double min_vote_weight = 1e-3;     // votes below this x the class's top weight are dropped
  float vote_cell_fraction = 0.25f;  // votes merged per cell of this x sigma; 0 = raw votes
  int max_votes = 200000;            // per class, after merging

  float Threshold(const std::string& cls) const {
    const auto it = thresholds.find(cls);
    return it == thresholds.end() ? default_threshold : it->second;
  }
};

// Each parameter declared once; its default is IsmOptions{}'s.
const ParamBinding<IsmOptions>& Binding() {
  using O = IsmOptions;
  static const auto b =
      BindDecision(ParamBinding<O>()
          .Number("sampling_size_m", &O::sampling_size_m, 0.005, 1.0, "m", "voxel edge of ISM's key points in views and scenes")
          .Number("normal_radius_m", &O::normal_radius_m, 0.005, 2.0, "m", "normal estimation radius")
          .Number("fpfh_radius_m", &O::fpfh_radius_m, 0.01, 2.0, "m", "FPFH support radius [m]; > normal_radius_m")
          .Int("number_of_clusters", &O::number_of_clusters, 2, 100000, "count",
               "ISM codebook size k (paper's vocabulary k = 40; PCL's default 184)")
          .Number("sigma_fraction", &O::sigma_fraction, 0.01, 2.0, "1",
                  "vote kernel sigma = this x class radius (half the 3-D diagonal). PCL's rule of thumb "
                  "0.1 makes ISM's learned weights so small that tables cast no vote at all")
          .Bool("n_vot", &O::n_vot, "ISM's normalisation of vote weights by the number of votes of a word")
          .Number("peak_radius_fraction", &O::peak_radius_fraction, 0.05, 4.0, "1",
                  "non-maxima radius of findStrongestPeaks = this x class footprint radius")
          .DetectionOnly()
          , DecisionFields{&O::thresholds, &O::default_threshold},
          {"= ISM peak density x number of the class's words, about the number of agreeing key points", "", true})
          .Int("max_hypotheses", &O::max_hypotheses, 1, 1000, "count",
               "at most this many hypotheses per class, strongest first")
          .DetectionOnly()
          .String("classes", &O::classes_text, "comma-separated classes to detect (empty = every trained class)")
          .DetectionOnly()
          .Number("floor_cut_m", &O::floor_cut_m, -1e3, 1e3, "m",
                  "scene points below this world height [m] are dropped before voting (the floor: ISM "
                  "learns isolated objects and a floor votes like a huge seat or table top); -1e3 = keep all")
          .DetectionOnly()
          .Number("viewpoint_height_m", &O::viewpoint_height_m, -100.0, 100.0, "m",
                  "scenes without sensor origin: normals face (centroid x, centroid y, this height)")
          .DetectionOnly()
          .Number("grid_cell_m", &O::grid_cell_m, 0.005, 1.0, "m", "cell of the per-class vote density grids")
          .DetectionOnly()
          .Int("max_plot_votes", &O::max_plot_votes, 0, 1e9, "count",
               "raw votes kept for plots (every n-th, weight x n); 0 = all")
          .DetectionOnly()
          .Number("min_vote_weight", &O::min_vote_weight, 0.0, 1.0, "1",
                  "a vote is dropped when its strength is below this x the class's largest statistical "
                  "weight, or below FLT_EPSILON (PCL's own cut), whichever is lower; 0 = PCL's cut only, "
                  "which lets almost no vote through once the training set has ~1e5 words")
          .DetectionOnly()
          .Number("vote_cell_fraction", &O::vote_cell_fraction, 0.0, 1.0, "1",
                  "votes in one cube of this x sigma are merged (mean position, summed strength) before "
                  "ISM's mean shift, whose cost grows with the votes within 3 sigma; 0 = PCL's raw votes")
          .DetectionOnly()
          .Int("max_votes", &O::max_votes, 1000, 2e9, "count",
               "per class, merged votes beyond this are thinned (every n-th, strength x n)")
          .DetectionOnly()
          .Rule([](const O& o) {
            return o.fpfh_radius_m > o.sampling_size_m
                       ? ""
                       : "fpfh_radius_m: must exceed sampling_size_m, or key points have no FPFH neighbours";
          });
  return b;
}

IsmOptions ParseOptions(const nlohmann::json& p) {
  IsmOptions o = Binding().Parse(p);
  o.classes = SplitList(o.classes_text);
  return o;
}

class PclIsmVoter : public Voter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit PclIsmVoter(const nlohmann::json& p) : opt_(ParseOptions(p)) {}

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext& ctx) override {
    const auto t0 = std::chrono::steady_clock::now();
    // Classes in name order: ids do not depend on the order of the views.
    std::map<std::string, int> ids;
    for (const auto& v : views) ids.emplace(v.cls, 0);
    if (ids.empty()) throw StageError("no training views");
    std::vector<std::string> classes;
    for (auto& [name, id] : ids) {
      id = static_cast<int>(classes.size());
      classes.push_back(name);
    }
    std::vector<Eigen::Vector3f> sizes(classes.size(), Eigen::Vector3f::Zero());
    std::vector<int> count(classes.size(), 0);
    for (const auto& v : views) {
      sizes[ids[v.cls]] += v.object_size;
      ++count[ids[v.cls]];
    }
    std::vector<float> sigmas(classes.size());
    for (size_t c = 0; c < classes.size(); ++c) {
      sizes[c] /= static_cast<float>(count[c]);
      sigmas[c] = opt_.sigma_fraction * 0.5f * sizes[c].norm();
      if (!(sigmas[c] > 0.f))
        throw StageError("class '" + classes[c] + "': training views have no object size, cannot set ISM's sigma");
    }

    std::vector<Oriented> prepared(views.size());
    RunParallel(ctx.threads, views.size(), [&](size_t i) {
      const Scan& s = views[i].scan;
      Points world(s.points.size());
      for (size_t k = 0; k < world.size(); ++k) world[k] = s.pose * s.points[k];
      // Training views come from a simulated sensor; without an origin fall back to above.
      const Eigen::Vector3f vp = s.origin ? Eigen::Vector3f(s.pose * *s.origin)
                                          : Eigen::Vector3f(views[i].object_centroid + Eigen::Vector3f(0, 0, 10));
      prepared[i] = Orient(world, vp, opt_.normal_radius_m);
    });
    std::vector<Cloud::Ptr> clouds;
    std::vector<NormalCloud::Ptr> normals;
    std::vector<unsigned> labels;
    size_t points = 0, dropped = 0, skipped = 0;
    for (size_t i = 0; i < views.size(); ++i) {
      dropped += prepared[i].dropped;
      // ISM averages each cloud for its centre: too few points make that centre meaningless.
      if (prepared[i].points->size() < 10) {
        ++skipped;
        continue;
      }
      points += prepared[i].points->size();
      clouds.push_back(prepared[i].points);
      normals.push_back(prepared[i].normals);
      labels.push_back(static_cast<unsigned>(ids[views[i].cls]));
    }
    for (size_t c = 0; c < classes.size(); ++c)
      if (std::find(labels.begin(), labels.end(), static_cast<unsigned>(c)) == labels.end())
        throw StageError("class '" + classes[c] + "': no training view with 10 or more points");
    if (points < static_cast<size_t>(opt_.number_of_clusters))
      throw StageError("ISM: " + std::to_string(points) + " usable training points for " +
                       std::to_string(opt_.number_of_clusters) + " clusters");

    Ism ism;
    ism.setTrainingClouds(clouds);
    ism.setTrainingNormals(normals);
    ism.setTrainingClasses(labels);
    ism.setSamplingSize(opt_.sampling_size_m);
    ism.setNumberOfClusters(static_cast<unsigned>(opt_.number_of_clusters));
    ism.setSigmaDists(sigmas);
    ism.setNVotState(opt_.n_vot);
    ism.setFeatureEstimator(MakeFpfh(opt_.fpfh_radius_m));
    auto model = std::make_shared<IsmModel>();
    furnihost_pcl_ism_clock::seed_value = static_cast<std::time_t>((ctx.seed ^ (ctx.seed >> 32)) & 0x7fffffffu);
    const auto t1 = std::chrono::steady_clock::now();
    if (!ism.trainISM(model)) throw StageError("ISM training failed (no descriptors)", false);
    const auto t2 = std::chrono::steady_clock::now();
    if (model->number_of_visual_words_ < static_cast<unsigned>(opt_.number_of_clusters))
      spdlog::warn("pcl_ism: {} descriptors for {} clusters", model->number_of_visual_words_, opt_.number_of_clusters);
    const size_t fixed = Sanitize(*model);

    nlohmann::json sz = nlohmann::json::array();
    for (const auto& s : sizes) sz.push_back({s.x(), s.y(), s.z()});
    nlohmann::json j = {{"format", kFormat},
                        {"classes", classes},
                        {"class_sizes", sz},
                        {"sampling_size_m", opt_.sampling_size_m},
                        {"normal_radius_m", opt_.normal_radius_m},
                        {"fpfh_radius_m", opt_.fpfh_radius_m},
                        {"number_of_clusters", opt_.number_of_clusters},
                        {"sigma_fraction", opt_.sigma_fraction},
                        {"n_vot", opt_.n_vot},
                        {"seed", ctx.seed},
                        {"ism", ModelToText(*model)}};
    Load(j);
    const auto ms = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
    spdlog::info("pcl_ism: {} views ({} skipped), {} points ({} without normal), {} words, k = {}, "
                 "{} non-finite values zeroed; normals {:.0f} ms, ISM {:.0f} ms",
                 clouds.size(), skipped, points, dropped, model->number_of_visual_words_,
                 opt_.number_of_clusters, fixed, ms(t0, t1), ms(t1, t2));
    return j;
  }

  void Load(const nlohmann::json& j) override {
    if (!j.is_object() || j.value("format", "") != kFormat)
      throw StageError(std::string("not a ") + kFormat + " model (format '" +
                       (j.is_object() ? j.value("format", "") : std::string()) + "')");
    auto m = std::make_unique<LoadedModel>();
    try {
      m->classes = j.at("classes").get<std::vector<std::string>>();
      for (const auto& s : j.at("class_sizes")) m->sizes.emplace_back(s.at(0).get<float>(), s.at(1).get<float>(), s.at(2).get<float>());
      m->sampling_size_m = j.at("sampling_size_m").get<float>();
      m->normal_radius_m = j.at("normal_radius_m").get<float>();
      m->fpfh_radius_m = j.at("fpfh_radius_m").get<float>();
    } catch (const nlohmann::json::exception& e) {
      throw StageError(std::string("pcl_ism model: ") + e.what());
    }
    const std::string& text = j.at("ism").get_ref<const std::string&>();
    // loadModelFromfile reads with operator>> and stops silently at "nan" / "inf".
    for (const char* bad : {"nan", "inf"})
      if (text.find(bad) != std::string::npos)
        throw StageError(std::string("pcl_ism model holds '") + bad + "': PCL cannot read it back");
    m->ism = ModelFromText(text);
    const IsmModel& im = *m->ism;
    size_t in_clusters = 0;
    for (const auto& c : im.clusters_) {
      in_clusters += c.size();
      for (unsigned w : c)
        if (w >= im.number_of_visual_words_) throw StageError("pcl_ism model: word index out of range");
    }
    if (im.number_of_classes_ != m->classes.size() || m->sizes.size() != m->classes.size() ||
        im.descriptors_dimension_ != kBins || im.number_of_visual_words_ == 0 ||
        in_clusters != im.number_of_visual_words_ || im.sigmas_.size() != m->classes.size())
      throw StageError("pcl_ism model is inconsistent (" + std::to_string(im.number_of_classes_) + " classes, " +
                       std::to_string(im.number_of_visual_words_) + " words, " + std::to_string(in_clusters) +
                       " in clusters, dimension " + std::to_string(im.descriptors_dimension_) + ")");
    m->n_vw.assign(m->classes.size(), 0);
    m->strength_scale.assign(m->classes.size(), 1.0);
    for (size_t c = 0; c < m->classes.size(); ++c) {
      float top = 0.f;
      for (float s : im.statistical_weights_[c]) {
        m->n_vw[c] += s > 0.f;
        top = std::max(top, s);
      }
      // findObjects drops votes of strength <= FLT_EPSILON, but strengths scale with
      // 1 / #words: with the whole catalog (533k words) the statistical weights are ~1e-6 and
      // almost no vote passes. Scaling a class's weights by a constant moves no peak; it only
      // turns that absolute cut into one relative to the class's strongest weight.
      const double relative = opt_.min_vote_weight * top;
      if (relative > 0 && relative < std::numeric_limits<float>::epsilon())
        m->strength_scale[c] = std::numeric_limits<float>::epsilon() / relative;
      for (float& s : m->ism->statistical_weights_[c]) s = static_cast<float>(s * m->strength_scale[c]);
    }
    model_ = std::move(m);
  }

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext& ctx) override {
    if (!model_) throw StageError("voter has no model: Train or Load it first", false);
    const LoadedModel& m = *model_;
    std::vector<int> selected;
    if (opt_.classes.empty()) {
      for (size_t c = 0; c < m.classes.size(); ++c) selected.push_back(static_cast<int>(c));
    } else {
      for (const auto& name : opt_.classes) {
        const auto it = std::find(m.classes.begin(), m.classes.end(), name);
        if (it == m.classes.end()) {
          std::string valid;
          for (const auto& c : m.classes) valid += (valid.empty() ? "" : ", ") + c;
          throw StageError("classes: '" + name + "' is not a trained class (trained: " + valid + ")");
        }
        selected.push_back(static_cast<int>(it - m.classes.begin()));
      }
    }

    // Fusion: every scene's points with their own normals in one world cloud; ISM's voxel
    // sampling then merges overlapping views.
    Cloud::Ptr cloud(new Cloud);
    NormalCloud::Ptr normals(new NormalCloud);
    Eigen::AlignedBox2f bounds;
    for (const auto& sp : scenes) {
      if (!sp.scan) throw StageError("scene without a scan", false);
      const Scan& s = *sp.scan;
      Points world(s.points.size());
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      size_t finite = 0;
      for (size_t k = 0; k < world.size(); ++k) {
        world[k] = s.pose * s.points[k];
        if (!world[k].allFinite()) continue;  // Orient drops it
        ++finite;
        centre += world[k].cast<double>();
        bounds.extend(world[k].head<2>());
      }
      if (finite == 0) continue;
      centre /= static_cast<double>(finite);
      const Eigen::Vector3f vp = s.origin ? Eigen::Vector3f(s.pose * *s.origin)
                                          : Eigen::Vector3f(centre.x(), centre.y(), opt_.viewpoint_height_m);
      // Normals first, so that the cut does not tilt those of the points just above it.
      Oriented o = Orient(world, vp, m.normal_radius_m);
      size_t kept = 0;
      for (size_t k = 0; k < o.points->size(); ++k) {
        if ((*o.points)[k].z < opt_.floor_cut_m) continue;
        (*o.points)[kept] = (*o.points)[k];
        (*o.normals)[kept] = (*o.normals)[k];
        ++kept;
      }
      o.points->resize(kept);
      o.normals->resize(kept);
      *cloud += *o.points;
      *normals += *o.normals;
    }

    struct PerClass {
      PeakVector peaks;
      std::vector<Eigen::Vector4f> votes;  // x, y, z, weight
      size_t raw = 0, thinned = 1;
      double ms_find = 0, ms_peaks = 0;
    };
    std::vector<PerClass> out(selected.size());
    RunParallel(ctx.threads, selected.size(), [&](size_t i) {
      const int c = selected[i];
      Ism ism;  // one per class: ISM's estimator keeps state between calls
      ism.setSamplingSize(m.sampling_size_m);
      ism.setNumberOfClusters(m.ism->number_of_clusters_);
      ism.setFeatureEstimator(MakeFpfh(m.fpfh_radius_m));
      const auto t0 = std::chrono::steady_clock::now();
      VoteList::Ptr list = ism.findObjects(m.ism, cloud, normals, c);
      const auto t1 = std::chrono::steady_clock::now();
      out[i].raw = VoteListAccess::Votes(*list).size();
      std::vector<Eigen::Vector4f> votes =
          Aggregate(VoteListAccess::Votes(*list), opt_.vote_cell_fraction * m.ism->sigmas_[c]);
      list.reset();  // the raw votes can take gigabytes on large rooms
      if (votes.size() > static_cast<size_t>(opt_.max_votes)) {
        out[i].thinned = (votes.size() + opt_.max_votes - 1) / opt_.max_votes;
        std::vector<Eigen::Vector4f> kept;
        for (size_t k = 0; k < votes.size(); k += out[i].thinned)
          kept.push_back({votes[k].x(), votes[k].y(), votes[k].z(), votes[k].w() * out[i].thinned});
        votes.swap(kept);
      }
      list = pcl::make_shared<VoteList>();
      const pcl::PointXYZ unused;  // vote origins are not used by the peak search
      for (const auto& v : votes) {
        pcl::InterestPoint p;
        p.x = v.x();
        p.y = v.y();
        p.z = v.z();
        p.strength = v.w();
        list->addVote(p, unused, c);
      }
      const double radius = opt_.peak_radius_fraction * FloorRadius(m.sizes[c]);
      if (!votes.empty()) list->findStrongestPeaks(out[i].peaks, c, radius, m.ism->sigmas_[c]);
      const float scale = static_cast<float>(m.n_vw[c] / m.strength_scale[c]);
      for (auto& v : votes) v.w() *= scale;
      out[i].votes = std::move(votes);
      const auto t2 = std::chrono::steady_clock::now();
      out[i].ms_find = std::chrono::duration<double, std::milli>(t1 - t0).count();
      out[i].ms_peaks = std::chrono::duration<double, std::milli>(t2 - t1).count();
    });

    VoteResult r;
    r.classes = m.classes;
    size_t total = 0;
    for (const auto& pc : out) total += pc.votes.size();
    const size_t stride = opt_.max_plot_votes > 0 && total > static_cast<size_t>(opt_.max_plot_votes)
                              ? (total + opt_.max_plot_votes - 1) / opt_.max_plot_votes
                              : 1;
    for (size_t i = 0; i < selected.size(); ++i) {
      const int c = selected[i];
      const std::string& cls = m.classes[c];
      spdlog::debug("pcl_ism: {}: {} votes in {} cells{}, findObjects {:.0f} ms, peaks {:.0f} ms", cls, out[i].raw,
                    out[i].votes.size(),
                    out[i].thinned > 1 ? fmt::format(" (every {}th kept)", out[i].thinned) : std::string(),
                    out[i].ms_find, out[i].ms_peaks);
      for (size_t k = 0; k < out[i].votes.size(); k += stride) {
        const auto& v = out[i].votes[k];
        r.votes.emplace_back(v.x(), v.y(), static_cast<float>(c), v.w() * static_cast<float>(stride));
      }
      if (!bounds.isEmpty()) r.grids.push_back(Grid(cls, bounds, out[i].votes));

      // findStrongestPeaks returns peaks strongest first. Score = density x n_vw: a key point
      // whose words all agree adds up to 1 / n_vw of the class, so this is about the number
      // of agreeing key points, independent of k.
      const float threshold = opt_.Threshold(cls);
      const float radius = FloorRadius(m.sizes[c]);
      int kept = 0;
      for (const auto& p : out[i].peaks) {
        if (kept >= opt_.max_hypotheses) break;
        Hypothesis h;
        h.cls = cls;
        h.center = Eigen::Vector3f(p.x, p.y, p.z);
        h.score = static_cast<float>(p.density * m.n_vw[c] / m.strength_scale[c]);
        if (!h.center.allFinite() || !(h.score >= threshold)) continue;
        // ISM has no parts; parts near the peak support it so fitters can still run.
        for (size_t s = 0; s < scenes.size(); ++s) {
          if (!scenes[s].segmentation) continue;
          const auto& parts = scenes[s].segmentation->parts;
          for (size_t k = 0; k < parts.size(); ++k) {
            const Eigen::Vector3f w = scenes[s].scan->pose * parts[k].centroid;
            if ((w.head<2>() - h.center.head<2>()).norm() <= radius)
              h.support.push_back({static_cast<int>(s), static_cast<int>(k), 1.f});
          }
        }
        r.hypotheses.push_back(std::move(h));
        ++kept;
      }
    }
    std::stable_sort(r.hypotheses.begin(), r.hypotheses.end(),
                     [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
    spdlog::debug("pcl_ism: {} key-point candidates, {} votes, {} hypotheses", cloud->size(), total,
                  r.hypotheses.size());
    return r;
  }

 private:
  static Ism::FeaturePtr MakeFpfh(float radius) {
    auto f = pcl::make_shared<FiniteFpfh>();
    f->setRadiusSearch(radius);
    return f;
  }

  // Vote weight per floor cell over the scene's extent (votes outside it are not drawn).
  VoteGrid Grid(const std::string& cls, const Eigen::AlignedBox2f& bounds,
                const std::vector<Eigen::Vector4f>& votes) const {
    VoteGrid g;
    g.cls = cls;
    g.cell = opt_.grid_cell_m;
    const Eigen::Vector2f ext = bounds.sizes();
    // Far outliers in a scan would make a huge grid: coarsen beyond 4 M cells.
    while ((ext.x() / g.cell + 1) * (ext.y() / g.cell + 1) > 4e6f) g.cell *= 2.f;
    g.origin = (bounds.min() / g.cell).array().floor().matrix() * g.cell;
    g.width = static_cast<int>(std::floor((bounds.max().x() - g.origin.x()) / g.cell)) + 1;
    g.height = static_cast<int>(std::floor((bounds.max().y() - g.origin.y()) / g.cell)) + 1;
    g.values.assign(static_cast<size_t>(g.width) * g.height, 0.f);
    for (const auto& v : votes) {
      const int ix = static_cast<int>(std::floor((v.x() - g.origin.x()) / g.cell));
      const int iy = static_cast<int>(std::floor((v.y() - g.origin.y()) / g.cell));
      if (ix < 0 || iy < 0 || ix >= g.width || iy >= g.height) continue;
      g.values[static_cast<size_t>(iy) * g.width + ix] += v.w();
    }
    return g;
  }

  IsmOptions opt_;
  std::unique_ptr<LoadedModel> model_;
};

}  // namespace furnihost::voters

FURNIHOST_PLUGIN(furnihost::voters::PclIsmVoter, "voters.pcl_ism", "1.0.0",
                 "PCL's Implicit Shape Model (FPFH, k-means codebook, 3-D mean-shift peaks) as a baseline voter")
