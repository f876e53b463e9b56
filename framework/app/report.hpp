// The Markdown report of `furnihost eval` and `furnihost compare` (report.md), rendered from
// the run figures (furnihost/host/evaluation.hpp) beside the plots of the same report (plots.hpp).
#pragma once
#include <string>
#include <vector>

#include "furnihost/host/evaluation.hpp"

namespace furnihost::app {

struct ReportInfo {
  std::string title = "furnihost evaluation";
  std::string dataset;       // manifest path
  std::string dataset_hash;
  int scenes = 0;
  WidthConvention width = WidthConvention::Max;
  std::vector<std::string> plots;  // image files to embed (relative to the report)
  std::vector<std::string> notes;  // extra lines (warnings) printed under the header
};

// Markdown: a header (dataset, hash, width convention, seeds, configs), then per class and
// for all classes a table `metric | A | B | B − A [| C | C − A ...]` (config 0 is the
// baseline A), values "mean ± std" over seeds when there are several, then time and memory.
std::string RenderReport(const std::vector<ConfigSummary>& configs, const ReportInfo& info);

}  // namespace furnihost::app
