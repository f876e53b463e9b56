// Line plots (cairo): the precision-recall plots of `furnihost eval`, recall (y) against
// 1 - precision (x), the axes of the paper's Fig. 5/6, both fixed to [0, 1] so plots of
// different runs compare; and the distributions `furnihost gap` draws.
#pragma once
#include <array>
#include <functional>
#include <string>
#include <vector>

typedef struct _cairo cairo_t;  // as cairo.h declares it

namespace furnihost::app {

struct PlotSeries {
  std::string label;                         // legend text ("" = no legend entry)
  std::vector<std::array<double, 2>> points; // (1 - precision, recall), in threshold order
  int color = 0;                             // palette index (one per config)
  double alpha = 1.0;                        // < 1 for the extra seeds of a config
};

// Writes `<stem>.svg` and `<stem>.png` (640 x 480 plus one 20 px legend row per labelled
// series below the plot), each atomically. InputError when a file
// cannot be written.
void WritePrPlot(const std::string& stem, const std::string& title, const std::vector<PlotSeries>& series);

// The axes of a line plot: labels and ranges (series points are in these units), and whether
// the points are marked as well as joined.
struct PlotAxes {
  std::string x_label, y_label;
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  bool markers = true;
};
// As WritePrPlot, on the given axes (5 grid intervals each).
void WriteLinePlot(const std::string& stem, const std::string& title, const PlotAxes& axes,
                   const std::vector<PlotSeries>& series);

// Writes `<stem>.svg` and `<stem>.png` of a `width` x `height` px drawing, each atomically,
// `draw` painting the whole page of each. InputError when a file cannot be written.
void WriteDrawing(const std::string& stem, double width, double height, const std::function<void(cairo_t*)>& draw);

}  // namespace furnihost::app
