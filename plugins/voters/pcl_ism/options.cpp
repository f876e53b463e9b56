// voters.pcl_ism: the wrapper's parameters.
#include "options.hpp"

#include <sstream>

#include "decision/decision_params.hpp"

namespace furnihost::voters {

namespace {

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

}  // namespace

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

}  // namespace furnihost::voters
