// furnihost::voting — the vocabulary, shape model, Hough voting and hypothesis selection that
// voters.hough_vocabulary and voters.nearest_neighbor share (a static library linked into both
// modules; hidden visibility keeps the two copies apart).
//
// Frames and units: metres, z up. A training shape vector d = p - s is computed in the
// training view's scan frame and stored in the view's viewing frame: rotated about z so that
// +x is the horizontal direction from the sensor (Scan::origin) to the object centroid (kept
// as is when the view has no origin). Scene part centroids l are in their scan frame and
// mapped to the world by Scan::pose; a vote lands at x_v = pose * l + Rz(yaw) * d, where yaw
// is the rotation of Scan::pose about +z (training views are upright, so only the heading of
// the scene scan frame is applied to d; as the words hold d from all around the object, the
// votes of a part form a ring of candidate centres whatever that heading is).
//
// Vote weights (paper eq. 4, 5): a part with feature f activates its `activations` nearest
// words A_i with p(A_i|f) = w_i / sum_j w_j, w = 1 / (||f - mean(A_i)|| + 1e-6); each element
// a of A_i of class o votes with weight p(A_i|f) / #(A_i, o). Hence every part contributes at
// most a mass of 1 per class, and the score below is measured in "parts' worth of evidence".
//
// Score (the quantity compared to the thresholds): for a hypothesis of class o at floor
// position c, score = sum of the weights of all class-o votes whose (x, y) lies within
// distance window_scale * width(o) / 2 of c (a disc, raw votes, not the smoothed grid). With
// several fused scans the votes of all scans add up, as in the paper's Sect. VII-C.
// Because each part brings a mass <= 1 per class whatever the vocabulary or the number of
// training models, the paper's thresholds (chair 0.6, table 1.0, sideboard 1.4) keep their
// meaning ("this much part evidence near the centre"), but how much of a part's mass lands in
// the window depends on the spread of the d vectors of our catalog, so they are re-derived:
//
// Re-deriving the thresholds: selection at threshold t equals the selection at threshold 0
// filtered to score >= t (maxima do not depend on t, and the footprint check is greedy in
// descending score, so its decisions on the hypotheses above t only involve hypotheses above
// t). So run the dev set once with {"thresholds": {}, "default_threshold": 0}, match the
// hypotheses to the ground truth (true positive: centre within half the class width, Sect.
// VII-A), sweep t over the sorted scores per class to get recall / precision, and put the
// chosen working point in the config. scripts/derive_thresholds.py does exactly this (max F1
// per evaluated class over percentile candidates, one threshold shared by the voter classes
// mapping to it; --cross-validate estimates how it carries over to unseen rooms). Note: a
// merge patch `"thresholds": {}` changes nothing (RFC 7386 merges objects); zero each class
// explicitly.
#pragma once
#include <Eigen/Core>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "decision/decision_params.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/params.hpp"
#include "furnihost/stage.hpp"
#include "furnihost/types.hpp"

namespace furnihost::voting {

using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct ClassModel {
  std::string name;
  float width = 0.f;  // median over the class's models of max(size.x, size.y) [m]
  int models = 0;     // training models of the class
  int parts = 0;      // training parts of the class
  float height = 0.f; // max over the class's models of the model height [m] (column check)
};

// Words plus the shape-model elements of each word. Elements of word k are the index range
// [element_begin[k], element_begin[k + 1]).
//
// A pooled codebook holds V vocabularies, each a k-means of the same training parts with its own
// seed: vocabulary v is the words [vocabulary_begin[v], vocabulary_begin[v + 1]), each with its
// own copy of the shape-model elements. A part activates its nearest words in every vocabulary
// (eq. 4 within each) and each vocabulary's votes weigh 1 / V, so a part still brings a mass of at
// most 1 per class and the score is the mean of the V vocabularies' scores: the paper's vote with
// the k-means draw averaged out.
struct Codebook {
  std::vector<std::string> feature_names;  // one per column of `words`
  RowMatrixXf words;                       // K x D word means (normalised feature space)
  std::vector<int> vocabulary_begin;       // V + 1 word offsets ({0, K}: one vocabulary)
  std::vector<ClassModel> classes;
  std::vector<std::string> models;         // training model ids
  std::vector<int> element_begin;          // K + 1
  std::vector<Eigen::Vector3f> d;          // object centroid minus part centroid [m]
  std::vector<int> element_class;          // index into classes
  std::vector<int> element_model;          // index into models
  std::vector<int> element_view;           // TrainingView::view
  std::vector<float> element_norm;         // 1 / #(A_i, o) of the element's word and class
  std::vector<float> element_height;       // part centroid height above the training floor [m]

  int Words() const { return static_cast<int>(words.rows()); }
  int Dim() const { return static_cast<int>(words.cols()); }
  int Vocabularies() const { return static_cast<int>(vocabulary_begin.size()) - 1; }
  // Fills element_norm from element_begin / element_class.
  void ComputeNorms();
  // Compact JSON (flat float arrays) tagged with `format`; FromJson checks the tag.
  nlohmann::json ToJson(const std::string& format) const;
  static Codebook FromJson(const nlohmann::json& j, const std::string& format);
};

// All parts of the training views, flattened.
struct TrainingParts {
  RowMatrixXf features;  // N x D, normalised
  std::vector<std::string> feature_names;
  std::vector<Eigen::Vector3f> d;
  std::vector<float> height;  // part centroid z in the view (catalog models stand on z = 0)
  std::vector<int> cls, model, view;
  std::vector<ClassModel> classes;
  std::vector<std::string> models;
};

// Collects parts and per-class widths; throws StageError on inconsistent views. Parts with
// non-finite features are skipped (and counted in the log).
TrainingParts CollectTrainingParts(const std::vector<TrainingView>& views);

struct KMeansOptions {
  int k = 40;
  int max_iterations = 100;
  int restarts = 3;
  int vocabularies = 1;  // pooled vocabularies (Codebook), each from its own seed
};

struct KMeansResult {
  RowMatrixXf centers;      // K x D (K <= requested k: empty clusters are dropped)
  std::vector<int> labels;  // per row of the data, index into centers
  double inertia = 0.0;     // sum of squared distances to the assigned centre
  int iterations = 0;       // Lloyd iterations of the kept restart
};

// k-means++ seeding then Lloyd iterations; best of `restarts` by inertia. Deterministic for
// `seed` (own uniform draws from std::mt19937_64, no std distributions).
KMeansResult KMeans(const RowMatrixXf& data, const KMeansOptions& opt, uint64_t seed);

// Builds a codebook whose word k holds the training parts with label k.
Codebook BuildCodebook(const TrainingParts& parts, const RowMatrixXf& words,
                       const std::vector<int>& labels);

// One codebook holding the vocabularies of `books` (same parts, classes and models), in order.
Codebook PoolCodebooks(const std::vector<Codebook>& books);

// The codebook of opt.vocabularies k-means vocabularies of `parts`: vocabulary v from seed
// SplitMix64(SplitMix64(seed) ^ v) when there are several (the draws of seeds s and s + 1 share none), from `seed` itself when there is one (the
// single vocabulary of earlier models). `inertia` (optional) receives each vocabulary's.
Codebook TrainCodebook(const TrainingParts& parts, const KMeansOptions& opt, uint64_t seed,
                       std::vector<double>* inertia = nullptr);

// Options of activation, accumulation and hypothesis selection (shared parameter block). The
// defaults are the declared parameters' (BindSelection below reads them from here).
struct SelectionOptions {
  int activations = 2;          // words activated per part (paper: 2)
  float max_distance = 0.f;     // feature distance beyond which a word is not activated (0 = off)
  float max_out_of_range = 0.f; // parts whose raw features exceed the training range by more
                                // than this (in ranges, FeatureMatrix::excess) do not vote (0 = off)
  float height_tolerance = 0.f; // element votes only when |part height - training part height|
                                // <= this [m] (0 = off); heights above the scan's ground (Scan::ground)
  bool unit_weight = false;     // NN baseline: weight 1 per vote instead of eq. 4/5
  bool inverse_distance = false;// NN baseline: weight 1 / (1 + feature distance)
  float cell = 0.05f;           // grid cell [m]
  float smoothing = 0.08f;      // Gaussian sigma of the density [m] (0 = none)
  float window_scale = 1.f;     // search window = window_scale * class width
  float refine_radius = 0.15f;  // mean-shift radius refining a grid maximum [m] (0 = off)
  std::string footprint = "circle";  // "circle" or "square" (axis-aligned), side = scale*width
  float footprint_scale = 1.f;
  // The paper's thresholds (the schema default, what always ran; the struct copy was empty).
  std::map<std::string, float> thresholds{{"cabinet", 1.4f}, {"chair", 0.6f}, {"table", 1.0f}};
  float default_threshold = 1.f;
  std::vector<std::string> classes;  // empty = all
  long long max_grid_cells = 4000000;
  // Column check (not in the paper): the scan points within column_radius (xy) of a hypothesis,
  // heights above the floor. At least column_min_points of them lie between 5 cm and the class
  // height + column_margin, and, for the classes in column_clear_classes (empty = all), at most
  // a share column_max_above of them lie higher (nothing stands on a chair's or a table's centre;
  // walls, shelves and stacked cabinets go on upwards). column_radius = 0: off.
  float column_radius = 0.f;
  float column_margin = 0.1f;
  int column_min_points = 10;
  float column_max_above = 0.1f;
  std::vector<std::string> column_clear_classes;

  float ThresholdFor(const std::string& cls) const;
};

// Declares the shared selection parameters (every one detection-only) on `b`, bound to the
// SelectionOptions member `sel` of the voter's options struct O. `activations` is not among
// them: a voter declares it (hough_vocabulary) or fixes it (nearest_neighbor).
template <class O>
ParamBinding<O>& BindSelection(ParamBinding<O>& b, SelectionOptions O::*sel) {
  using S = SelectionOptions;
  // The SelectionOptions field `f` of an O.
  auto in = [sel](auto S::*f) { return [sel, f](O& o) -> auto& { return (o.*sel).*f; }; };
  return BindDecision(b
      .Number("max_distance", in(&S::max_distance), 0, 100, "1",
              "feature-space distance beyond which a word/part is not activated (0 = off, paper)")
      .DetectionOnly()
      .Number("max_out_of_range", in(&S::max_out_of_range), 0, 1e6, "1",
              "a part whose raw features lie more than this many training ranges outside the range of "
              "the training parts (any column) does not vote: walls and floors clamp to the largest "
              "training part otherwise (0 = off, paper)")
      .DetectionOnly()
      .Number("height_tolerance_m", in(&S::height_tolerance), 0, 100, "m",
              "a shape-model element votes only when the part's height above the floor is within this "
              "of its training part's height (objects stand on the floor, Sect. VI-B) (0 = off, paper)")
      .DetectionOnly()
      .Number("cell", in(&S::cell), 0.005, 1, "m", "vote grid cell size on the floor plane")
      .DetectionOnly()
      .Number("smoothing", in(&S::smoothing), 0, 1, "m",
              "Gaussian sigma smoothing the vote density before the maxima search (0 = none)")
      .DetectionOnly()
      .Number("window_scale", in(&S::window_scale), 0.1, 4, "1",
              "search/score window = window_scale x class width (paper: the class width)")
      .DetectionOnly()
      .Number("refine_radius", in(&S::refine_radius), 0, 2, "m",
              "mean-shift radius moving a grid maximum onto the votes (0 = cell centre)")
      .DetectionOnly()
      .Enum("footprint", in(&S::footprint), {"circle", "square"},
            "2-D hull of a hypothesis for the consistency check (Sect. VI-B)")
      .DetectionOnly()
      .Number("footprint_scale", in(&S::footprint_scale), 0, 4, "1",
              "footprint diameter / side = footprint_scale x class width")
      .DetectionOnly()
      , DecisionFields{in(&S::thresholds), in(&S::default_threshold)},
      {"= the summed vote weight near the centre; paper: chair 0.6, table 1.0, sideboard 1.4", "", true})
      .StringList("classes", in(&S::classes), "comma-separated classes to detect (empty = every trained class)")
      .DetectionOnly()
      .Int("max_grid_cells", in(&S::max_grid_cells), 1000, 1e9, "count",
           "cap on grid cells per class; the cell grows beyond it (far outliers)")
      .DetectionOnly()
      .Number("column_radius_m", in(&S::column_radius), 0, 10, "m",
              "column check (not in the paper): radius of the vertical column of scan points tested around "
              "each hypothesis (0 = off, paper)")
      .DetectionOnly()
      .Number("column_margin_m", in(&S::column_margin), 0, 10, "m",
              "column check: points up to the class height (tallest training model) + this count as the "
              "object, higher ones as 'above'")
      .DetectionOnly()
      .Int("column_min_points", in(&S::column_min_points), 0, 1000000, "count",
           "column check: a hypothesis needs at least this many column points between 5 cm above the "
           "floor and the class height + margin")
      .DetectionOnly()
      .Number("column_max_above", in(&S::column_max_above), 0, 1, "1",
              "column check: largest share of the column's points above the class height + margin (for "
              "column_clear_classes; 1 = no limit)")
      .DetectionOnly()
      .StringList("column_clear_classes", in(&S::column_clear_classes),
                  "comma-separated classes with nothing standing on them for column_max_above (empty = all)")
      .DetectionOnly();
}

// kd-trees over the words of a codebook (nanoflann), one per vocabulary. Keeps its own copy of
// the words. `leaf_size`: points per leaf (larger leaves pay off for thousands of points in
// 24-D). `vocabulary_begin`: word offsets of the vocabularies (empty: one of all words).
class WordIndex {
 public:
  explicit WordIndex(const RowMatrixXf& words, int leaf_size = 10, const std::vector<int>& vocabulary_begin = {});
  ~WordIndex();
  WordIndex(const WordIndex&) = delete;
  WordIndex& operator=(const WordIndex&) = delete;
  int Vocabularies() const;
  // Nearest `k` words of vocabulary `vocabulary` to `query` (D floats): indices into all words
  // and squared distances, nearest first. With `max_dist_sq` > 0 only words closer than that
  // count (fewer may come back): the bound prunes the tree from the start, which is what makes
  // far-off queries cheap in 24-D.
  int Nearest(const float* query, int k, long* indices, float* dist_sq, float max_dist_sq = 0.f,
              int vocabulary = 0) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};


// Votes with every scene part and selects hypotheses (Sect. VI-A, VI-B).
VoteResult VoteAndSelect(const Codebook& book, const WordIndex& index,
                         const std::vector<SceneParts>& scenes, const SelectionOptions& opt);

// A voter whose model is a codebook of part words in `format`: Load() reads it and indexes its
// words (k-d tree leaves of `leaf_size`), Vote() is VoteAndSelect with `opt_`. The voters differ
// in how they train the codebook and set the options.
class CodebookVoter : public Voter {
 public:
  void Load(const nlohmann::json& model) override {
    auto book = std::make_unique<Codebook>(Codebook::FromJson(model, format_));
    index_ = std::make_unique<WordIndex>(book->words, leaf_size_, book->vocabulary_begin);
    book_ = std::move(book);
  }

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext&) override {
    if (!book_) throw StageError("voter has no model: Train or Load it first", false);
    return VoteAndSelect(*book_, *index_, scenes, opt_);
  }

 protected:
  CodebookVoter(const char* format, int leaf_size) : format_(format), leaf_size_(leaf_size) {}
  SelectionOptions opt_;

 private:
  const char* format_;
  int leaf_size_;
  std::unique_ptr<Codebook> book_;
  std::unique_ptr<WordIndex> index_;
};

}  // namespace furnihost::voting
