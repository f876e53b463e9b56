#include "birdseye.hpp"

#include <cairo-svg.h>
#include <cairo.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>

#include "furnihost/error.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/host/pipeline.hpp"
#include "cancel_on_unwind.hpp"
#include "png_writer.hpp"

namespace furnihost::app {

namespace {

constexpr double kTwoPi = 6.283185307179586;
// Density cells below this share of their class maximum are not drawn (alpha < ~0.1).
constexpr float kVisible = 0.02f;

struct Rgb {
  double r, g, b;
};

// Fixed colours for the paper's classes (Fig. 1), then a palette in order of appearance.
class Colours {
 public:
  Rgb Of(const std::string& cls) {
    static const std::map<std::string, Rgb> fixed = {{"chair", {0.10, 0.35, 0.95}},
                                                     {"table", {0.90, 0.12, 0.12}},
                                                     {"cabinet", {0.95, 0.78, 0.05}},
                                                     {"sideboard", {0.95, 0.78, 0.05}}};
    static const std::array<Rgb, 6> palette = {{{0.10, 0.65, 0.25},
                                                {0.55, 0.20, 0.75},
                                                {0.95, 0.50, 0.05},
                                                {0.05, 0.70, 0.75},
                                                {0.85, 0.20, 0.65},
                                                {0.50, 0.33, 0.15}}};
    if (auto it = fixed.find(cls); it != fixed.end()) return it->second;
    auto it = other_.find(cls);
    if (it == other_.end()) it = other_.emplace(cls, palette[other_.size() % palette.size()]).first;
    return it->second;
  }

 private:
  std::map<std::string, Rgb> other_;
};

using SurfacePtr = std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)>;

// A scan as drawn: its points through `pose` (the scan's pose, then the display transform).
struct Shown {
  const Scan* scan;
  Eigen::Isometry3f pose;
};
using ContextPtr = std::unique_ptr<cairo_t, decltype(&cairo_destroy)>;

// World window [lo, hi] mapped to pixels with `ppm` pixels per metre, y flipped.
struct View {
  Eigen::Vector2d lo, hi;
  double ppm = 100.0;
  double margin = 40.0, legend = 170.0;
  double PlotWidth() const { return (hi.x() - lo.x()) * ppm; }
  double PlotHeight() const { return (hi.y() - lo.y()) * ppm; }
  int Width() const { return static_cast<int>(std::ceil(PlotWidth() + 2 * margin + legend)); }
  int Height() const { return static_cast<int>(std::ceil(std::max(PlotHeight() + 2 * margin, 260.0))); }
  double X(double x) const { return margin + (x - lo.x()) * ppm; }
  double Y(double y) const { return margin + (hi.y() - y) * ppm; }
};

View MakeView(const std::vector<Shown>& scans, const VoteResult& votes,
              const std::vector<Detection>& detections) {
  Eigen::AlignedBox2d box;
  for (const auto& [s, pose] : scans) {
    for (const auto& p : s->points) {
      const Eigen::Vector3f w = pose * p;
      if (w.allFinite()) box.extend(w.head<2>().cast<double>());
    }
  }
  // The picture is the scan and its detections: votes that fall outside it (parts voting for
  // centres beyond a wall) are clipped, hypotheses only widen it when there are no points.
  for (const auto& d : detections)
    if (d.center.allFinite()) box.extend(d.center.head<2>().cast<double>());
  if (box.isEmpty())
    for (const auto& h : votes.hypotheses) box.extend(h.center.head<2>().cast<double>());
  if (box.isEmpty()) box = Eigen::AlignedBox2d(Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(0.5, 0.5));
  View v;
  const Eigen::Vector2d pad = Eigen::Vector2d::Constant(0.25);
  v.lo = box.min() - pad;
  v.hi = box.max() + pad;
  // About 1000 px along the longer side, at most 200 px/m (small scenes stay small).
  const double ext = std::max(v.hi.x() - v.lo.x(), v.hi.y() - v.lo.y());
  v.ppm = std::min(200.0, 1000.0 / ext);
  return v;
}

// Scan points as one raster (embedded as an image in the SVG, not 50k shapes), each block of
// ~2 cm shaded by the highest point above the ground that falls in it: the floor light
// blue-grey (where the ground model saw it), objects from mid grey (low) to near black (2 m
// and up), so furniture stands out from the floor it stands on. Blocks rather than single
// pixels: a 50k-point room drawn 1000 px wide is otherwise a faint dust.
// `extent` receives the scan's outline: the convex hull of the drawn blocks, in plot pixels.
SurfacePtr PointsRaster(const std::vector<Shown>& scans, const View& v, std::vector<Eigen::Vector2d>* extent) {
  const int w = std::max(1, static_cast<int>(std::ceil(v.PlotWidth())));
  const int h = std::max(1, static_cast<int>(std::ceil(v.PlotHeight())));
  SurfacePtr img(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, w, h), cairo_surface_destroy);
  cairo_surface_flush(img.get());
  unsigned char* data = cairo_image_surface_get_data(img.get());
  const int stride = cairo_image_surface_get_stride(img.get());
  const int block = std::max(1, static_cast<int>(std::lround(0.02 * v.ppm)));
  const int bw = (w + block - 1) / block, bh = (h + block - 1) / block;
  std::vector<float> top(static_cast<size_t>(bw) * bh, -INFINITY);
  for (const auto& [s, pose] : scans) {
    for (const auto& p : s->points) {
      const Eigen::Vector3f wp = pose * p;
      if (!wp.allFinite()) continue;
      const double px = v.X(wp.x()) - v.margin, py = v.Y(wp.y()) - v.margin;
      if (px < 0 || py < 0 || px >= w || py >= h) continue;
      const float above = s->ground ? s->ground->Above(p) : wp.z();
      float& t = top[static_cast<size_t>(py / block) * bw + static_cast<size_t>(px / block)];
      t = std::max(t, above);
    }
  }
  // Each row's first and last drawn block bound the hull (<= 2 points per row).
  std::vector<Eigen::Vector2f> ends;
  for (int by = 0; by < bh; ++by) {
    int first = -1, last = -1;
    for (int bx = 0; bx < bw; ++bx) {
      const float t = top[static_cast<size_t>(by) * bw + bx];
      if (!std::isfinite(t)) continue;
      if (first < 0) first = bx;
      last = bx;
      if (!data) continue;
      // Premultiplied ARGB: the floor half transparent, objects opaque.
      uint32_t argb;
      if (t < 0.05f) {
        argb = 0xB0000000u | (0x8Au << 16) | (0x91u << 8) | 0x98u;  // 0xC8D2DC at alpha 0.69
      } else {
        const int g = static_cast<int>(std::lround(150.0 - 120.0 * std::clamp(double(t) / 2.0, 0.0, 1.0)));
        argb = 0xFF000000u | (uint32_t(g) << 16) | (uint32_t(g) << 8) | uint32_t(g);
      }
      for (int y = by * block; y < std::min(h, (by + 1) * block); ++y)
        for (int x = bx * block; x < std::min(w, (bx + 1) * block); ++x)
          reinterpret_cast<uint32_t*>(data + static_cast<size_t>(y) * stride)[x] = argb;
    }
    if (first < 0) continue;
    for (float y : {float(by * block), float((by + 1) * block)}) {
      ends.emplace_back(float(first * block), y);
      ends.emplace_back(float((last + 1) * block), y);
    }
  }
  extent->clear();
  for (const Eigen::Vector2f& p : ConvexHull2D(std::move(ends))) extent->push_back(p.cast<double>());
  cairo_surface_mark_dirty(img.get());
  return img;
}

// One class's density as translucent cells: alpha grows with sqrt(value / class maximum).
void DrawGrid(cairo_t* cr, const VoteGrid& g, Rgb c, const View& v, const Eigen::Isometry3f& display) {
  if (g.width <= 0 || g.height <= 0 || g.values.size() != static_cast<size_t>(g.width) * g.height) return;
  const float vmax = *std::max_element(g.values.begin(), g.values.end());
  if (!(vmax > 0.f)) return;
  SurfacePtr img(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, g.width, g.height), cairo_surface_destroy);
  cairo_surface_flush(img.get());
  unsigned char* data = cairo_image_surface_get_data(img.get());
  if (!data) return;
  const int stride = cairo_image_surface_get_stride(img.get());
  for (int iy = 0; iy < g.height; ++iy)
    for (int ix = 0; ix < g.width; ++ix) {
      const float value = g.values[static_cast<size_t>(iy) * g.width + ix];
      if (!(value > kVisible * vmax)) continue;
      const double a = 0.45 * std::sqrt(value / vmax);
      auto ch = [&](double x) { return static_cast<uint32_t>(std::lround(255.0 * x * a)); };
      reinterpret_cast<uint32_t*>(data + static_cast<size_t>(iy) * stride)[ix] =
          (static_cast<uint32_t>(std::lround(255.0 * a)) << 24) | (ch(c.r) << 16) | (ch(c.g) << 8) | ch(c.b);
    }
  cairo_surface_mark_dirty(img.get());
  cairo_save(cr);
  // Image row iy is world y = origin.y + iy * cell, which runs up: flip. The grid's axes are
  // the world's, turned by the display transform (the screen's y runs down: the other way).
  const Eigen::Vector3f o = display * Eigen::Vector3f(g.origin.x(), g.origin.y(), 0.f);
  cairo_translate(cr, v.X(o.x()), v.Y(o.y()));
  cairo_rotate(cr, -std::atan2(display.linear()(1, 0), display.linear()(0, 0)));
  cairo_scale(cr, g.cell * v.ppm, -g.cell * v.ppm);
  cairo_set_source_surface(cr, img.get(), 0, 0);
  cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_NEAREST);
  cairo_paint(cr);
  cairo_restore(cr);
}

double Radius(float score, float max_score, const View& v) {
  // Area proportional to score; the strongest is 0.3 m across, none below 5 px.
  const double r = 0.15 * std::sqrt(std::max(0.f, score) / std::max(max_score, 1e-6f)) * v.ppm;
  return std::max(5.0, r);
}

void Text(cairo_t* cr, double x, double y, const std::string& s, double size = 12.0) {
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
  cairo_move_to(cr, x, y);
  cairo_show_text(cr, s.c_str());
}

// `points` and `outline`: PointsRaster's image and outline of `scans`, drawn once for both files.
void Draw(cairo_t* cr, const std::vector<Shown>& scans, cairo_surface_t* points, const std::vector<Eigen::Vector2d>& outline,
          const VoteResult& votes, const std::vector<Detection>& detections, const View& v,
          const Eigen::Isometry3f& display) {
  Colours colours;
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);

  // Everything of the scene stays inside the plot rectangle; the legend is beside it.
  cairo_save(cr);
  cairo_rectangle(cr, v.margin, v.margin, v.PlotWidth(), v.PlotHeight());
  cairo_clip(cr);
  std::vector<std::string> classes;
  auto note_class = [&](const std::string& c) {
    if (std::find(classes.begin(), classes.end(), c) == classes.end()) classes.push_back(c);
  };
  // The scan first, the translucent vote densities over it (the points show through), each
  // drawn only within the scan's outline: parts vote for centres beyond walls too, and those
  // votes say nothing about the room.
  cairo_set_source_surface(cr, points, v.margin, v.margin);
  cairo_paint(cr);
  double area = 0.0;  // [px^2]; a scan seen edge-on (one wall) outlines nothing
  for (size_t i = 0; i < outline.size(); ++i) {
    const auto& a = outline[i];
    const auto& b = outline[(i + 1) % outline.size()];
    area += 0.5 * (a.x() * b.y() - b.x() * a.y());
  }
  cairo_save(cr);
  if (std::fabs(area) > 0.25 * v.ppm * v.ppm) {
    cairo_new_path(cr);
    for (const auto& p : outline) cairo_line_to(cr, v.margin + p.x(), v.margin + p.y());
    cairo_close_path(cr);
    cairo_clip(cr);
  }
  for (const auto& g : votes.grids) {
    DrawGrid(cr, g, colours.Of(g.cls), v, display);
    note_class(g.cls);
  }
  cairo_restore(cr);

  float max_score = 0.f;
  for (const auto& h : votes.hypotheses) max_score = std::max(max_score, h.score);
  for (const auto& d : detections) max_score = std::max(max_score, d.score);

  cairo_set_line_width(cr, 1.5);
  for (const auto& h : votes.hypotheses) {
    const Rgb c = colours.Of(h.cls);
    note_class(h.cls);
    cairo_new_path(cr);
    cairo_arc(cr, v.X(h.center.x()), v.Y(h.center.y()), Radius(h.score, max_score, v), 0, kTwoPi);
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_stroke(cr);
  }
  for (const auto& d : detections) {
    const Rgb c = colours.Of(d.cls);
    note_class(d.cls);
    const bool rejected = d.verified.has_value() && !*d.verified;
    const double x = v.X(d.center.x()), y = v.Y(d.center.y()), r = Radius(d.score, max_score, v);
    cairo_new_path(cr);
    cairo_arc(cr, x, y, r, 0, kTwoPi);
    cairo_set_source_rgba(cr, c.r, c.g, c.b, rejected ? 0.15 : 0.6);
    cairo_fill_preserve(cr);
    cairo_set_source_rgb(cr, c.r * 0.6, c.g * 0.6, c.b * 0.6);
    cairo_set_line_width(cr, 2.0);
    const double dash[] = {4.0, 3.0};
    cairo_set_dash(cr, dash, rejected ? 2 : 0, 0);
    cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
    // The object's box footprint, and what it is: class, fitted model, score.
    if (d.box && !rejected) {
      const auto corners = d.box->Corners();
      cairo_new_path(cr);
      for (int k = 0; k < 4; ++k) cairo_line_to(cr, v.X(corners[k].x()), v.Y(corners[k].y()));
      cairo_close_path(cr);
      cairo_set_source_rgb(cr, c.r * 0.7, c.g * 0.7, c.b * 0.7);
      cairo_set_line_width(cr, 2.0);
      cairo_stroke(cr);
    }
    // The way it faces (its placed model's front, Detection::yaw): an arrow from the box centre
    // across the box and beyond.
    if (d.box && !rejected && !d.model.empty()) {
      const double len = 0.5 * std::max<double>(d.box->size.x(), d.box->size.y()) + 0.25;
      const double cx = v.X(d.box->center.x()), cy = v.Y(d.box->center.y());
      const double ex = v.X(d.box->center.x() + len * std::cos(d.yaw)), ey = v.Y(d.box->center.y() + len * std::sin(d.yaw));
      cairo_set_source_rgb(cr, c.r * 0.45, c.g * 0.45, c.b * 0.45);
      cairo_set_line_width(cr, 2.0);
      cairo_move_to(cr, cx, cy);
      cairo_line_to(cr, ex, ey);
      cairo_stroke(cr);
      const double a = std::atan2(ey - cy, ex - cx), head = 8.0;
      cairo_move_to(cr, ex, ey);
      cairo_line_to(cr, ex - head * std::cos(a - 0.45), ey - head * std::sin(a - 0.45));
      cairo_line_to(cr, ex - head * std::cos(a + 0.45), ey - head * std::sin(a + 0.45));
      cairo_close_path(cr);
      cairo_fill(cr);
    }
    char score[32];
    std::snprintf(score, sizeof score, " %.2f", d.score);
    const std::string label = rejected ? std::string(score + 1) : d.cls + (d.model.empty() ? "" : " " + d.model) + score;
    cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
    Text(cr, x + r + 2, y + 4, label, rejected ? 9 : 11);
  }

  cairo_restore(cr);
  cairo_set_line_width(cr, 1.0);
  cairo_set_source_rgb(cr, 0.6, 0.6, 0.6);
  cairo_rectangle(cr, v.margin, v.margin, v.PlotWidth(), v.PlotHeight());
  cairo_stroke(cr);

  // Scale bar: 1 m, bottom left.
  const double bx = v.margin, by = v.Height() - v.margin / 2;
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 2.0);
  cairo_move_to(cr, bx, by);
  cairo_line_to(cr, bx + v.ppm, by);
  cairo_move_to(cr, bx, by - 5);
  cairo_line_to(cr, bx, by + 5);
  cairo_move_to(cr, bx + v.ppm, by - 5);
  cairo_line_to(cr, bx + v.ppm, by + 5);
  cairo_stroke(cr);
  Text(cr, bx + v.ppm + 6, by + 4, "1 m");

  // Legend, right of the plot.
  double lx = v.margin + v.PlotWidth() + 20, ly = v.margin;
  cairo_set_source_rgb(cr, 0, 0, 0);
  Text(cr, lx, ly, "top view (x right, y up)", 11);
  ly += 16;
  Text(cr, lx, ly, "arrow: the way it faces", 10);
  ly += 20;
  for (const auto& cls : classes) {
    const Rgb c = colours.Of(cls);
    cairo_rectangle(cr, lx, ly - 10, 14, 12);
    cairo_set_source_rgba(cr, c.r, c.g, c.b, 0.75);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    Text(cr, lx + 20, ly, cls);
    ly += 18;
  }
  ly += 6;
  cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
  cairo_set_line_width(cr, 1.5);
  cairo_new_path(cr);
  cairo_arc(cr, lx + 7, ly - 4, 6, 0, kTwoPi);
  cairo_stroke(cr);
  Text(cr, lx + 20, ly, "hypothesis");
  ly += 18;
  cairo_new_path(cr);
  cairo_arc(cr, lx + 7, ly - 4, 6, 0, kTwoPi);
  cairo_fill(cr);
  Text(cr, lx + 20, ly, "detection");
  ly += 18;
  const double dash[] = {3.0, 2.0};
  cairo_set_dash(cr, dash, 2, 0);
  cairo_new_path(cr);
  cairo_arc(cr, lx + 7, ly - 4, 6, 0, kTwoPi);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  Text(cr, lx + 20, ly, "rejected");
  ly += 18;
  cairo_rectangle(cr, lx, ly - 10, 14, 12);
  cairo_set_source_rgba(cr, 0.784, 0.824, 0.863, 0.69);
  cairo_fill(cr);
  cairo_set_source_rgb(cr, 0, 0, 0);
  Text(cr, lx + 20, ly, "floor (< 5 cm)");
  ly += 18;
  for (const auto& [g, what] : {std::pair{0.55, "points, low"}, std::pair{0.15, "points, 2 m up"}}) {
    cairo_rectangle(cr, lx, ly - 10, 14, 12);
    cairo_set_source_rgb(cr, g, g, g);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    Text(cr, lx + 20, ly, what);
    ly += 18;
  }
  for (const auto& [s, pose] : scans)
    if (s->ground) {
      Text(cr, lx, ly + 4, std::string("ground: ") + ToString(s->ground->kind) + " (" + s->ground->source + ")", 10);
      ly += 16;
      break;
    }
  Text(cr, lx, ly + 6, "circle area ~ score", 10);
}

void Check(cairo_status_t st, const std::string& path) {
  if (st != CAIRO_STATUS_SUCCESS)
    throw InputError(path + ": cannot write (" + cairo_status_to_string(st) + ")");
}

}  // namespace

void WarmUpPlotFonts() {
  cairo_font_face_t* face = cairo_toy_font_face_create("sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_matrix_t size, identity;
  cairo_matrix_init_scale(&size, 12.0, 12.0);
  cairo_matrix_init_identity(&identity);
  cairo_font_options_t* options = cairo_font_options_create();
  cairo_scaled_font_t* font = cairo_scaled_font_create(face, &size, &identity, options);
  cairo_text_extents_t extents;
  cairo_scaled_font_text_extents(font, "chair 0.5", &extents);
  cairo_scaled_font_destroy(font);
  cairo_font_options_destroy(options);
  cairo_font_face_destroy(face);
}

void WriteBirdsEye(const std::string& stem, const std::vector<const Scan*>& scan_list, const VoteResult& world_votes,
                   const std::vector<Detection>& world_detections, const Eigen::Isometry3f& display) {
  // Everything into the frame drawn: scans by their poses, hypotheses, votes and detections.
  std::vector<Shown> scans;
  for (const Scan* s : scan_list)
    if (s) scans.push_back({s, display * s->pose});
  VoteResult votes = world_votes;
  for (auto& h : votes.hypotheses) h.center = display * h.center;
  std::vector<Detection> detections;
  for (const auto& d : world_detections) detections.push_back(TransformDetection(d, display));
  const View v = MakeView(scans, votes, detections);
  std::vector<Eigen::Vector2d> outline;
  SurfacePtr points = PointsRaster(scans, v, &outline);
  // Opaque (Draw paints it white first): RGB, not RGBA, so the PNG carries no alpha channel (the
  // same pixels, smaller and quicker to encode).
  SurfacePtr png(cairo_image_surface_create(CAIRO_FORMAT_RGB24, v.Width(), v.Height()), cairo_surface_destroy);
  Check(cairo_surface_status(png.get()), stem + ".png");
  // Every cairo call stays on this thread, in this order, so the SVG's element ids (cairo numbers
  // its surfaces process-wide) are the same every run; the PNG encodings, which only read pixels,
  // run beside the drawing (the two files took ~85 ms one after the other on a 50k-point room).
  const Pixels raster = PixelsOf(points.get(), stem + ".svg");
  std::vector<unsigned char> raster_png;  // the SVG embeds the raster as this PNG (fast, not cairo's)
  Pixels image;
  // Declared after everything its tasks use: when a drawing throws (a full disk fails the SVG
  // while the PNG is written beside it), `unwind` cancels and waits for them before those go.
  tbb::task_group side;
  CancelOnUnwind unwind(side);
  side.run([&] { raster_png = EncodePixels(raster, "bird's-eye raster"); });
  {
    ContextPtr cr(cairo_create(png.get()), cairo_destroy);
    Draw(cr.get(), scans, points.get(), outline, votes, detections, v, display);
    Check(cairo_status(cr.get()), stem + ".png");
  }
  side.wait();
  AttachPng(points.get(), std::move(raster_png), "bird's-eye raster");
  image = PixelsOf(png.get(), stem + ".png");
  side.run([&] { WriteBytes(EncodePixels(image, stem + ".png"), stem + ".png"); });
  AtomicWrite(stem + ".svg", [&](const std::string& tmp) {
    SurfacePtr s(cairo_svg_surface_create(tmp.c_str(), v.Width(), v.Height()), cairo_surface_destroy);
    Check(cairo_surface_status(s.get()), stem + ".svg");
    {
      ContextPtr cr(cairo_create(s.get()), cairo_destroy);
      Draw(cr.get(), scans, points.get(), outline, votes, detections, v, display);
      Check(cairo_status(cr.get()), stem + ".svg");
    }
    cairo_surface_finish(s.get());  // flushes the file
    Check(cairo_surface_status(s.get()), stem + ".svg");
  });
  side.wait();  // rethrows the PNG's error
}

}  // namespace furnihost::app
