// Evaluation of detections against ground truth (paper Sect. VII-A) and the figures of an
// A/B run (host): dataset manifests (src/eval_dataset.cpp), the matchers (eval_matching.cpp),
// precision-recall curves, average precision, operating points and error statistics
// (eval_metrics.cpp), and run records (eval_records.cpp). The Markdown report rendered from
// them is the app's (framework/app/report.hpp).
//
// Frames and units: world frame of the scan files (metres, z up, floor at z = 0). Matching
// and centre errors are measured on the floor plane (x, y) only: a voter's hypothesis height
// is the mean height of its votes, not the object's box centre.
//
// Dataset manifest (D.json), paths relative to the manifest:
//   {"description"?: "...",
//    "scenes": [{"scan": "a.ply", "gt": "a.gt.json", "origin"?: [x, y, z],
//                "up"?: "-y", "transform"?: "16 or 6 numbers", "shift"?: [x, y, z]}, ...],
//    "class_map"?: {"desk": "table", "sofa": null},   // null = not evaluated
//    "classes": ["chair", "table", "cabinet"],
//    "yaw_symmetry"?: {"table": 2}}   // turns mapping an object of the class onto itself, for
//                                     // ground truth that names none (0 = any, n = n-fold)
// The class map is applied to ground truth AND detections; a class that is neither in
// `classes` nor mapped into it is not evaluated (its ground truth is ignored and its
// detections are counted as ignored, not as false positives).
#pragma once
#include <cmath>
#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/host/frame.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/types.hpp"

namespace furnihost {

// ---- dataset -----------------------------------------------------------------------------
struct DatasetScene {
  std::string scan;  // absolute path
  std::string gt;    // absolute path of the *.gt.json
  std::optional<Eigen::Vector3f> origin;  // sensor origin for scans without one [m]
  FrameOptions frame;                     // "up", "transform", "shift" of the scene (file frame -> z up)
};

struct ClassMap {
  std::map<std::string, std::optional<std::string>> map;  // name -> evaluated class, nullopt = drop
  std::vector<std::string> classes;                        // evaluated classes, in report order
  // Evaluated class -> the turns about up that map its objects onto itself (the manifest's
  // "yaw_symmetry": 0 = any, n = n-fold), for ground-truth objects that declare none.
  std::map<std::string, int> yaw_symmetry;
  // The evaluated class of a ground-truth or detected class name, nullopt when not evaluated.
  FURNIHOST_API std::optional<std::string> Map(const std::string& cls) const;
};

struct Dataset {
  std::string path;  // the manifest
  std::string description;
  std::vector<DatasetScene> scenes;
  ClassMap classes;
};

// Throws InputError "<manifest>:/json/pointer: <what is wrong>" on a bad manifest, including
// scan or gt files that are missing. Unknown keys are errors (a typo must not pass silently).
FURNIHOST_API Dataset LoadDataset(const std::string& path);

// "fnv1a64:<16 hex digits>" over the bytes of the manifest, then each scene's scan and gt
// file in manifest order. InputError when a file cannot be read.
FURNIHOST_API std::string HashDataset(const Dataset& dataset);

// ---- matching ----------------------------------------------------------------------------
// Which horizontal extent of a ground-truth box is "the width of the object" (the paper does
// not say): Max = max(size x, size y), Min = min(size x, size y). The match radius is half of it.
enum class WidthConvention { Max, Min };
FURNIHOST_API const char* ToString(WidthConvention w);  // "max" / "min"
FURNIHOST_API std::optional<WidthConvention> ParseWidthConvention(const std::string& s);
FURNIHOST_API float MatchRadius(const GroundTruthObject& gt, WidthConvention w);  // [m]

// Result of matching the detections of one scene with its ground truth.
struct SceneMatch {
  static constexpr int kIgnored = -2;    // class not evaluated
  static constexpr int kUnmatched = -1;
  std::vector<int> det_to_gt;            // per detection: gt index, kUnmatched or kIgnored
  std::vector<int> gt_to_det;            // per gt object: detection index, kUnmatched or kIgnored
  std::vector<std::string> det_class;    // evaluated class per detection ("" when ignored)
  std::vector<std::string> gt_class;     // evaluated class per gt object ("" when ignored)
};

// Paper Sect. VII-A: a detection is a true positive when its (mapped) class equals the gt
// object's (mapped) class and its centre lies strictly within MatchRadius of the gt centre on
// the floor plane. Detections are taken greedily by descending score (ties: lower index
// first); each takes the nearest still unmatched eligible gt object, so each gt object
// matches at most one detection and a second detection on it is a false positive. Because
// the order is by score, the matching at any score threshold is the prefix of this one,
// which is what makes the threshold sweep of the PR curve consistent.
FURNIHOST_API SceneMatch MatchScene(const std::vector<Detection>& detections,
                                    const std::vector<GroundTruthObject>& truth,
                                    const ClassMap& classes, WidthConvention width);

// The ScanNet / VoteNet rule: 3D IoU of axis-aligned boxes. A detection's box is the AABB of
// Detection::box (none: IoU 0); a gt object's is centre +- size / 2.
FURNIHOST_API float BoxIou(const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b);
FURNIHOST_API Eigen::AlignedBox3f GroundTruthBox(const GroundTruthObject& gt);
FURNIHOST_API Eigen::AlignedBox3f DetectionBox(const Detection& d);  // empty box without Detection::box
// VoteNet's eval_det_cls: detections by descending score; each takes the gt object of its
// (mapped) class with the largest IoU; a TP when that IoU >= `threshold` and the object is not
// taken yet, else a FP. Same SceneMatch layout as MatchScene.
FURNIHOST_API SceneMatch MatchSceneIou(const std::vector<Detection>& detections,
                                       const std::vector<GroundTruthObject>& truth, const ClassMap& classes,
                                       float threshold);

// ---- metrics -----------------------------------------------------------------------------
struct PrPoint {
  float score = 0.f;  // threshold: detections with score >= this are kept
  int tp = 0, fp = 0;
  double precision = 0, recall = 0;
};

// All-point interpolated average precision (PASCAL VOC 2010+): the precision envelope
// p_i(r) = max precision at any recall >= r, integrated over recall:
// AP = sum_k (r_k - r_{k-1}) * p_i(r_k), r_0 = 0. `recall` non-decreasing, same length as
// `precision`. Returns 0 for an empty curve.
FURNIHOST_API double AveragePrecision(const std::vector<double>& recall, const std::vector<double>& precision);

struct ErrorStats {
  int n = 0;
  double median = NAN, p90 = NAN;  // linear interpolation between order statistics; NaN when n = 0
};
FURNIHOST_API ErrorStats Summarise(std::vector<double> values);

// |yaw error| [deg] of a detection whose yaw differs from the gt's by `raw_deg` (in [0, 180]),
// folded by the gt object's turn symmetry: 0 = any turn (error 0), n = n-fold (the distance to
// the nearest multiple of 360/n), none or 1 = raw.
FURNIHOST_API double FoldYawErrorDeg(double raw_deg, std::optional<int> yaw_symmetry);

// The Scan2CAD alignment rule (skanti/Scan2CAD EvaluateBenchmark.py): a detection aligns a
// ground-truth object of its class when its box centre lies within `centre_m` of the object's
// (3D), the way it faces (Detection::yaw) within `yaw_deg` of the object's, folded by the
// object's yaw_symmetry, and its size within `scale` of the object's: |mean over the three axes
// of (detection / object) - 1| <= scale, on the extents of the axis-aligned boxes in the scan's
// frame (GroundTruthObject::size against the detection's box's), so a box turned with the object
// and one along the scan's axes are measured alike.
struct AlignmentRule {
  double centre_m = 0.2, yaw_deg = 20.0, scale = 0.2;
};
// Why `d` does not align `g`: the first criterion it misses ("centre 0.31 m off", "facing 23 deg
// off", "size 27 % off", "no model placed"), "" when it aligns.
FURNIHOST_API std::string AlignmentMiss(const Detection& d, const GroundTruthObject& g, const AlignmentRule& rule = {});
FURNIHOST_API bool Aligned(const Detection& d, const GroundTruthObject& g, const AlignmentRule& rule = {});
// Alignment accuracy: the share of the ground-truth objects with a known yaw that an accepted
// detection (verified != false) with a placed model aligns; each detection aligns at most one
// object (detections by descending score, each the nearest object it aligns).
struct AlignmentFigures {
  int objects = 0;  // evaluated gt objects with a yaw
  int aligned = 0;
  double accuracy = NAN;  // aligned / objects, NaN when objects = 0
};

// Counts at one operating point plus the errors of its true positives.
struct OperatingPoint {
  int tp = 0, fp = 0, fn = 0;
  double precision = NAN, recall = NAN;  // NaN when undefined (no detections / no gt)
  ErrorStats centre_error_m;             // floor-plane distance of TPs to the gt centre
  ErrorStats yaw_error_deg;              // |yaw - gt yaw| in [0, 180] of fitted TPs with gt yaw,
                                         // folded by the gt's yaw_symmetry when it declares one
};

// How well detections' confidences (Detection::confidence, a calibrated graph's) say how often
// they are right: the detections of a class that carry a confidence, labelled true when AP25's
// matching (MatchSceneIou at 0.25) takes them, in 10 equal-width confidence bins; the expected
// calibration error is the detection-weighted mean |share true - mean confidence| over the bins.
struct Reliability {
  struct Bin {
    double lo = 0, hi = 0;  // confidence range [lo, hi) (the last bin includes 1)
    int n = 0;               // detections in it
    double confidence = NAN, accuracy = NAN;  // their mean confidence and share true; NaN when n = 0
  };
  int detections = 0;  // with a confidence
  double ece = NAN;    // NaN when detections = 0
  std::vector<Bin> bins;
};
FURNIHOST_API Reliability MakeReliability(const std::vector<std::pair<float, bool>>& confidence_true, int bins = 10);

// Verification as a filter of the voter's hypotheses: each hypothesis is matched at the centre
// the voter gave it (before a fitter moved it), then counted by whether the fitter kept it.
struct VerificationFigures {
  int tp = 0, tp_kept = 0;     // hypotheses that matched a gt object / of those, verified
  int fp = 0, fp_removed = 0;  // hypotheses that matched none / of those, rejected
  double tp_kept_rate = NAN;     // tp_kept / tp, NaN when tp = 0
  double fp_removal_rate = NAN;  // fp_removed / fp, NaN when fp = 0
};

// One ground-truth object and what became of it (for the per-object table of the report).
struct ObjectRecord {
  std::string scene;     // scene label (the scan file's stem)
  int index = 0;         // object index in the scene's gt file
  std::string cls;       // evaluated class
  std::string gt_model;  // catalog model of the ground truth, "" when unknown
  // "verified": a verified detection matched it; "rejected": a voter hypothesis matched it but
  // the fitter rejected every such detection; "missed": no hypothesis; "hypothesis": matched
  // when no fitter ran.
  std::string status;
  // Of the detection shown (the verified one, else the rejected hypothesis):
  std::string model;                                 // fitted model id, "" when none
  double centre_error_m = NAN, yaw_error_deg = NAN;  // floor-plane centre distance; raw yaw in [0, 180]
  int yaw_symmetry = -1;                             // the gt's yaw_symmetry, -1 when not declared
  double yaw_error_folded_deg = NAN;                 // yaw error folded by yaw_symmetry (= raw without)
  double coverage = NAN;
  std::string rejection;
  // Of an object with a known yaw: "aligned" when the shown detection aligns it by the Scan2CAD
  // rule (Aligned), else what it misses (AlignmentMiss); "" without a yaw or a detection.
  std::string alignment;
};

struct ClassMetrics {
  std::string cls;
  int gt = 0;          // evaluated gt objects
  int detections = 0;  // evaluated detections (all scores)
  std::vector<PrPoint> curve;  // one point per distinct score, descending score
  double ap = NAN;             // NaN when the class has no gt object
  // The same detections matched by box IoU >= 0.25 / >= 0.5 (ScanNet's AP25 / AP50).
  std::vector<PrPoint> curve25, curve50;
  double ap25 = NAN, ap50 = NAN;
  // "hypotheses": everything the pipeline output (the voter already applied its threshold).
  OperatingPoint hypotheses;
  // "verified": only detections with verified != false, matched again on their own; present
  // when a fitter ran.
  std::optional<OperatingPoint> verified;
  std::optional<VerificationFigures> verification;  // present when a fitter ran
  AlignmentFigures alignment;  // the Scan2CAD rule on the accepted detections
  // The accepted detections (verified != false; of a calibrated graph: at its min_confidence)
  // matched on their own by box IoU >= 0.25: the working point's precision and recall by the
  // ScanNet rule.
  OperatingPoint accepted25;
  std::optional<Reliability> reliability;  // when its detections carry a confidence
};

struct EvalMetrics {
  std::vector<ClassMetrics> classes;  // in ClassMap::classes order
  double map = NAN;                   // mean AP over classes with gt objects
  double map25 = NAN, map50 = NAN;    // mean AP25 / AP50 over classes with gt objects
  OperatingPoint hypotheses, verified;  // micro totals over the classes (verified: fitted only)
  bool fitted = false;
  std::map<std::string, int> ignored_gt, ignored_detections;  // original class -> count
  VerificationFigures verification;  // micro totals (fitted only)
  AlignmentFigures alignment;         // micro totals
  OperatingPoint accepted25;          // micro totals
  std::optional<Reliability> reliability;  // every class's detections with a confidence pooled
  std::vector<ObjectRecord> objects;  // every evaluated gt object, scene by scene
};

struct SceneEval {
  std::vector<Detection> detections;
  std::vector<GroundTruthObject> truth;
  bool fitted = false;  // a fitter ran (Detection::verified is meaningful)
  std::string name;     // label in the per-object records (e.g. the scan's stem)
  // The voter's centre of each detection before a fitter moved it (same order and size as
  // `detections`); empty = the detections' own centres. Used for the verification figures.
  std::vector<Eigen::Vector3f> voter_centres;
};

FURNIHOST_API EvalMetrics Evaluate(const std::vector<SceneEval>& scenes, const ClassMap& classes,
                                   WidthConvention width);

// ---- run figures and records ----------------------------------------------------------
struct SceneRecord {
  std::string scan;
  double total_ms = 0;
  int detections = 0;
  std::vector<std::pair<std::string, double>> timings_ms;  // stage tag -> ms
};

// One config run once (one seed) over the dataset.
struct RunFigures {
  uint64_t seed = 0;
  EvalMetrics metrics;
  std::vector<SceneRecord> scenes;
  std::vector<std::pair<std::string, double>> stage_ms;  // stage tag -> ms summed over scenes
  double wall_ms = 0;      // detection of all scenes, wall clock
  double model_ms = 0;     // EnsureModel (load or train)
  std::string model_source;  // "cache", "trained" or "none"
  double peak_rss_mb = NAN;  // peak resident memory while this run was going
  int jobs = 1;              // scenes processed in parallel
};

struct ConfigSummary {
  std::string name;   // short label, e.g. the graph's file stem
  std::string graph;  // graph file
  std::vector<RunFigures> runs;  // one per seed
};

FURNIHOST_API nlohmann::json ToJson(const EvalMetrics& m);
FURNIHOST_API nlohmann::json ToJson(const RunFigures& r);
FURNIHOST_API nlohmann::json ToJson(const ConfigSummary& s);
// Inverses (for `furnihost compare`); InputError "<where>: ..." on a malformed value.
FURNIHOST_API EvalMetrics EvalMetricsFromJson(const nlohmann::json& j, const std::string& where);
FURNIHOST_API RunFigures RunFiguresFromJson(const nlohmann::json& j, const std::string& where);
FURNIHOST_API ConfigSummary ConfigSummaryFromJson(const nlohmann::json& j, const std::string& where);

// Scalar figures of one run by key ("chair/ap", "chair/hypotheses/precision",
// "all/map", "time/scene_ms", "time/stage/segment_ms", "memory/peak_rss_mb", ...).
FURNIHOST_API std::map<std::string, double> FlatFigures(const RunFigures& r);

struct MeanStd {
  double mean = NAN, std = NAN;  // sample std (n - 1); 0 for one value; NaN values skipped
  int n = 0;
};
FURNIHOST_API MeanStd MeanAndStd(const std::vector<double>& values);

}  // namespace furnihost
