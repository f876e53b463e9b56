#include "plots.hpp"

#include <cairo-svg.h>
#include <cairo.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>

#include "furnihost/error.hpp"
#include "furnihost/host/io.hpp"

namespace furnihost::app {

namespace {

// The plot area is fixed; the legend goes below it (never over a curve), one row per entry.
constexpr double kWidth = 640, kPlotHeight = 480, kLegendRow = 20;
constexpr double kLeft = 70, kRight = 20, kTop = 40, kBottom = 55;

int LegendRows(const std::vector<PlotSeries>& series) {
  int n = 0;
  for (const auto& s : series) n += s.label.empty() ? 0 : 1;
  return n;
}
double TotalHeight(const std::vector<PlotSeries>& series) {
  const int n = LegendRows(series);
  return kPlotHeight + (n ? n * kLegendRow + 10 : 0);
}

// Colour-blind-safe palette (Okabe-Ito order), one colour per config.
constexpr double kPalette[][3] = {{0.000, 0.447, 0.698}, {0.835, 0.369, 0.000}, {0.000, 0.620, 0.451},
                                  {0.800, 0.475, 0.655}, {0.337, 0.706, 0.914}, {0.902, 0.624, 0.000},
                                  {0.941, 0.894, 0.259}, {0.000, 0.000, 0.000}};
constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);

// Plot coordinates of [0, 1] on each axis.
double X(double v) { return kLeft + v * (kWidth - kLeft - kRight); }
double Y(double v) { return kPlotHeight - kBottom - v * (kPlotHeight - kTop - kBottom); }

// A tick's text: few digits, scientific when tiny or huge.
std::string Tick(double v, double span) {
  char buf[16];
  if (v != 0.0 && (std::abs(v) < 1e-3 || std::abs(v) >= 1e5)) std::snprintf(buf, sizeof(buf), "%.1e", v);
  else std::snprintf(buf, sizeof(buf), span >= 5 ? "%.0f" : span >= 0.5 ? "%.1f" : span >= 0.05 ? "%.2f" : "%.3f", v);
  return buf;
}

void Text(cairo_t* cr, double x, double y, const std::string& s, double size, double align_x, double align_y) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  cairo_move_to(cr, x - align_x * e.width - e.x_bearing, y - align_y * e.height - e.y_bearing);
  cairo_show_text(cr, s.c_str());
}

void Draw(cairo_t* cr, const std::string& title, const PlotAxes& ax, const std::vector<PlotSeries>& series) {
  const double sx = ax.x1 > ax.x0 ? ax.x1 - ax.x0 : 1.0, sy = ax.y1 > ax.y0 ? ax.y1 - ax.y0 : 1.0;
  auto px = [&](double v) { return X((v - ax.x0) / sx); };
  auto py = [&](double v) { return Y((v - ax.y0) / sy); };
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);

  // Grid and ticks every 0.2.
  cairo_set_line_width(cr, 1.0);
  for (int i = 0; i <= 5; ++i) {
    const double v = i / 5.0;
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, X(v), Y(0));
    cairo_line_to(cr, X(v), Y(1));
    cairo_move_to(cr, X(0), Y(v));
    cairo_line_to(cr, X(1), Y(v));
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
    Text(cr, X(v), Y(0) + 8, Tick(ax.x0 + v * sx, sx), 12, 0.5, 0.0);
    Text(cr, X(0) - 8, Y(v), Tick(ax.y0 + v * sy, sy), 12, 1.0, 0.5);
  }
  cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
  cairo_rectangle(cr, X(0), Y(1), X(1) - X(0), Y(0) - Y(1));
  cairo_stroke(cr);
  Text(cr, (X(0) + X(1)) / 2, kPlotHeight - 18, ax.x_label, 14, 0.5, 0.5);
  cairo_save(cr);
  cairo_translate(cr, 20, (Y(0) + Y(1)) / 2);
  cairo_rotate(cr, -M_PI / 2);
  Text(cr, 0, 0, ax.y_label, 14, 0.5, 0.5);
  cairo_restore(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_BOLD);
  Text(cr, (X(0) + X(1)) / 2, kTop / 2, title, 15, 0.5, 0.5);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);

  // Curves, clipped to the plot area.
  cairo_save(cr);
  cairo_rectangle(cr, X(0) - 4, Y(1) - 4, X(1) - X(0) + 8, Y(0) - Y(1) + 8);
  cairo_clip(cr);
  for (const auto& s : series) {
    const double* c = kPalette[((s.color % kPaletteSize) + kPaletteSize) % kPaletteSize];
    cairo_set_source_rgba(cr, c[0], c[1], c[2], s.alpha);
    cairo_set_line_width(cr, s.alpha < 1 ? 1.2 : 2.0);
    bool first = true;
    for (const auto& p : s.points) {
      if (!std::isfinite(p[0]) || !std::isfinite(p[1])) continue;
      if (first) cairo_move_to(cr, px(p[0]), py(p[1]));
      else cairo_line_to(cr, px(p[0]), py(p[1]));
      first = false;
    }
    cairo_stroke(cr);
    for (const auto& p : s.points) {
      if (!ax.markers || !std::isfinite(p[0]) || !std::isfinite(p[1])) continue;
      cairo_arc(cr, px(p[0]), py(p[1]), s.alpha < 1 ? 1.8 : 2.6, 0, 2 * M_PI);
      cairo_fill(cr);
    }
  }
  cairo_restore(cr);

  // Legend below the x axis label.
  int k = 0;
  for (const auto& s : series) {
    if (s.label.empty()) continue;
    const double y = kPlotHeight + kLegendRow * (k++ + 0.5);
    const double* c = kPalette[((s.color % kPaletteSize) + kPaletteSize) % kPaletteSize];
    cairo_set_source_rgb(cr, c[0], c[1], c[2]);
    cairo_set_line_width(cr, 2.5);
    cairo_move_to(cr, X(0), y);
    cairo_line_to(cr, X(0) + 24, y);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
    Text(cr, X(0) + 32, y, s.label, 12, 0.0, 0.5);
  }
}

void Check(cairo_status_t st, const std::string& path) {
  if (st != CAIRO_STATUS_SUCCESS) throw InputError(path + ": cannot write plot (" + cairo_status_to_string(st) + ")");
}

}  // namespace

void WritePrPlot(const std::string& stem, const std::string& title, const std::vector<PlotSeries>& series) {
  PlotAxes pr;
  pr.x_label = "1 - precision";
  pr.y_label = "recall";
  WriteLinePlot(stem, title, pr, series);
}

void WriteLinePlot(const std::string& stem, const std::string& title, const PlotAxes& axes,
                   const std::vector<PlotSeries>& series) {
  WriteDrawing(stem, kWidth, TotalHeight(series), [&](cairo_t* cr) { Draw(cr, title, axes, series); });
}

void WriteDrawing(const std::string& stem, double width, double height, const std::function<void(cairo_t*)>& draw) {
  const std::string svg = stem + ".svg", png = stem + ".png";
  AtomicWrite(svg, [&](const std::string& tmp) {
    std::unique_ptr<cairo_surface_t, void (*)(cairo_surface_t*)> s(cairo_svg_surface_create(tmp.c_str(), width, height),
                                                                   cairo_surface_destroy);
    std::unique_ptr<cairo_t, void (*)(cairo_t*)> cr(cairo_create(s.get()), cairo_destroy);
    draw(cr.get());
    Check(cairo_status(cr.get()), svg);
    cr.reset();
    cairo_surface_finish(s.get());  // flushes the SVG to the file
    Check(cairo_surface_status(s.get()), svg);
  });
  AtomicWrite(png, [&](const std::string& tmp) {
    std::unique_ptr<cairo_surface_t, void (*)(cairo_surface_t*)> s(
        cairo_image_surface_create(CAIRO_FORMAT_ARGB32, static_cast<int>(width), static_cast<int>(height)),
        cairo_surface_destroy);
    std::unique_ptr<cairo_t, void (*)(cairo_t*)> cr(cairo_create(s.get()), cairo_destroy);
    draw(cr.get());
    Check(cairo_status(cr.get()), png);
    cairo_surface_flush(s.get());
    Check(cairo_surface_write_to_png(s.get(), tmp.c_str()), png);
  });
}

}  // namespace furnihost::app
