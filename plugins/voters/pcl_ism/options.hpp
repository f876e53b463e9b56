// voters.pcl_ism, private to the plugin: the wrapper's options (options.cpp).
#pragma once

#include <string>
#include <vector>

#include "furnihost/plugin.hpp"

namespace furnihost::voters {

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

// Each parameter declared once (options.cpp).
const ParamBinding<IsmOptions>& Binding();

// The options of `p`, with the class list split.
IsmOptions ParseOptions(const nlohmann::json& p);

}  // namespace furnihost::voters
