// furnihost catalog: what a catalog holds after import, to check before training on it: each
// model's class, size and the way it faces (catalog.json's "front", else EstimateFront's guess),
// as a table, fronts.json and a contact sheet (fronts.svg/.png: every model from above and from
// its side turned to face right, with an arrow the way it faces).
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/host/catalog.hpp"
#include "furnihost/host/io.hpp"
#include "plots.hpp"

namespace fs = std::filesystem;

namespace furnihost::app {

namespace {

constexpr double kCell = 220, kLabel = 40, kColumns = 3, kMargin = 10, kHeader = 46;

void Label(cairo_t* cr, double x, double y, const std::string& s, double size) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  cairo_move_to(cr, x - 0.5 * e.width - e.x_bearing, y);
  cairo_show_text(cr, s.c_str());
}

// An arrow from (x, y) along the picture direction (dx, dy) (unit, y down), `len` long: solid red
// for a front from the catalog, dashed orange for an estimated one.
void Arrow(cairo_t* cr, double x, double y, double dx, double dy, double len, bool given) {
  const double ex = x + dx * len, ey = y + dy * len;
  if (given) cairo_set_source_rgb(cr, 0.85, 0.1, 0.1);
  else cairo_set_source_rgb(cr, 0.95, 0.55, 0.0);
  const double dash[] = {6.0, 4.0};
  cairo_set_dash(cr, dash, given ? 0 : 2, 0);
  cairo_set_line_width(cr, 3);
  cairo_move_to(cr, x, y);
  cairo_line_to(cr, ex, ey);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  const double a = std::atan2(dy, dx);
  cairo_move_to(cr, ex, ey);
  cairo_line_to(cr, ex - 14 * std::cos(a - 0.4), ey - 14 * std::sin(a - 0.4));
  cairo_line_to(cr, ex - 14 * std::cos(a + 0.4), ey - 14 * std::sin(a + 0.4));
  cairo_close_path(cr);
  cairo_fill(cr);
}

// The mesh projected on the plane of the model-frame axes `u` (picture right) and `v` (picture
// up), centred at (cx, cy) at `ppm` pixels per metre: triangles far from the viewer first and
// darker the nearer they are (the viewer looks along -(u x v)), then the projection's bounding
// box. Returns that box's half size in pixels.
Eigen::Vector2d DrawProjection(cairo_t* cr, const Mesh& mesh, const Eigen::Vector3f& u, const Eigen::Vector3f& v,
                               double cx, double cy, double ppm) {
  const Eigen::Vector3f d = u.cross(v);
  float lo_u = INFINITY, hi_u = -INFINITY, lo_v = INFINITY, hi_v = -INFINITY, lo_d = INFINITY, hi_d = -INFINITY;
  for (const auto& p : mesh.vertices) {
    lo_u = std::min(lo_u, p.dot(u)), hi_u = std::max(hi_u, p.dot(u));
    lo_v = std::min(lo_v, p.dot(v)), hi_v = std::max(hi_v, p.dot(v));
    lo_d = std::min(lo_d, p.dot(d)), hi_d = std::max(hi_d, p.dot(d));
  }
  const double mu = 0.5 * (double(lo_u) + hi_u), mv = 0.5 * (double(lo_v) + hi_v);
  auto px = [&](const Eigen::Vector3f& p) { return cx + (p.dot(u) - mu) * ppm; };
  auto py = [&](const Eigen::Vector3f& p) { return cy - (p.dot(v) - mv) * ppm; };
  std::vector<std::pair<float, size_t>> order;
  order.reserve(mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    order.emplace_back((mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]).dot(d) / 3.f, t);
  }
  std::sort(order.begin(), order.end());
  const double depth = std::max(1e-3, double(hi_d) - lo_d);
  cairo_set_line_width(cr, 0.3);
  for (const auto& [near, t] : order) {
    const auto& tri = mesh.triangles[t];
    const double shade = 0.85 - 0.6 * std::clamp((near - lo_d) / depth, 0.0, 1.0);
    cairo_set_source_rgb(cr, shade, shade, shade);
    cairo_move_to(cr, px(mesh.vertices[tri[0]]), py(mesh.vertices[tri[0]]));
    cairo_line_to(cr, px(mesh.vertices[tri[1]]), py(mesh.vertices[tri[1]]));
    cairo_line_to(cr, px(mesh.vertices[tri[2]]), py(mesh.vertices[tri[2]]));
    cairo_close_path(cr);
    cairo_fill_preserve(cr);
    cairo_stroke(cr);
  }
  const Eigen::Vector2d half(0.5 * (double(hi_u) - lo_u) * ppm, 0.5 * (double(hi_v) - lo_v) * ppm);
  cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
  cairo_set_line_width(cr, 1);
  cairo_rectangle(cr, cx - half.x(), cy - half.y(), 2 * half.x(), 2 * half.y());
  cairo_stroke(cr);
  return half;
}

// One model in a cell two kCell wide at (x0, y0), both halves at one scale. Left: from above
// (+x right, +y up, darker = higher) with an arrow from the centre the way it faces. Right: from
// its side, turned so that it faces right (up is up, darker = nearer), with the arrow under it:
// a chair's back stands at the left, its seat opens to the right. Solid red arrows for a front
// from the catalog, dashed orange for an estimated one.
void DrawModel(cairo_t* cr, const CatalogModel& m, const ModelFront& front, double x0, double y0) {
  const double draw = kCell - 2 * kMargin;
  const Eigen::Vector3f ext = m.mesh.Bounds().sizes();
  const double ppm = 0.8 * draw / std::max(double(ext.maxCoeff()), 1e-3);
  const double cy = y0 + kMargin + draw / 2;
  const bool given = front.source == "catalog";
  const Eigen::Vector3f f = Eigen::Vector3f(front.front.x(), front.front.y(), 0.f).normalized();
  const double top_x = x0 + kCell / 2, side_x = x0 + 1.5 * kCell;
  DrawProjection(cr, m.mesh, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY(), top_x, cy, ppm);
  Arrow(cr, top_x, cy, f.x(), -f.y(), 0.45 * draw, given);
  const Eigen::Vector2d half = DrawProjection(cr, m.mesh, f, Eigen::Vector3f::UnitZ(), side_x, cy, ppm);
  Arrow(cr, side_x - 0.4 * draw, std::min(cy + half.y() + 10, y0 + kCell - 4), 1, 0, 0.8 * draw, given);
  cairo_set_source_rgb(cr, 0, 0, 0);
  Label(cr, x0 + kCell, y0 + kCell + 12, m.id, 12);
  char size[64];
  std::snprintf(size, sizeof(size), "%.2f x %.2f x %.2f m", m.size.x(), m.size.y(), m.size.z());
  Label(cr, x0 + kCell, y0 + kCell + 27, m.cls + ", " + size, 10);
}

}  // namespace

int RunCatalog(const std::vector<std::string>& args) {
  CLI::App app{"Show what a catalog holds after import: each model's class, size and the way it faces "
               "(catalog.json's \"front\", else estimated from the mesh), as a table, fronts.json and a contact "
               "sheet fronts.svg/.png (every model from above and from its side turned to face right, an arrow the way "
               "it faces: solid from the catalog, dashed when estimated). Check the estimates before training; write a \"front\" where one is wrong.\n"
               "usage: furnihost catalog CATALOG.json [--out DIR] [--strict]",
               "catalog"};
  CommonOptions common;
  std::string path, out = "furnihost-out/catalog";
  bool strict = false;
  common.Add(app, false);
  app.add_option("catalog", path, "catalog.json")->required();
  app.add_option("--out,-o", out, "output folder (fronts.json, fronts.svg, fronts.png)");
  app.add_flag("--strict", strict, "an invalid model entry is an error (default: skipped with a warning)");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  if (fs::exists(out) && !fs::is_directory(out)) throw InputError("--out " + out + ": exists and is not a folder");
  const Catalog catalog = LoadCatalog(path, strict);
  if (catalog.models.empty()) throw InputError(path + ": no model could be loaded");
  nlohmann::json models = nlohmann::json::array();
  std::cout << "model                     class      size [m]              front   source\n";
  for (const auto& m : catalog.models) {
    const ModelFront* f = catalog.FrontOf(m.id);
    const ModelFront front = f ? *f : ModelFront{};
    models.push_back({{"id", m.id},
                      {"class", m.cls},
                      {"size_m", {m.size.x(), m.size.y(), m.size.z()}},
                      {"front", {front.front.x(), front.front.y()}},
                      {"front_deg", std::atan2(front.front.y(), front.front.x()) * 180.0 / M_PI},
                      {"source", front.source}});
    char line[256];
    std::snprintf(line, sizeof(line), "%-25s %-10s %.2f x %.2f x %.2f   %+4.0f°  %s\n", m.id.c_str(), m.cls.c_str(),
                  m.size.x(), m.size.y(), m.size.z(), std::atan2(front.front.y(), front.front.x()) * 180.0 / M_PI,
                  front.source == "catalog" ? "catalog" : "estimated");
    std::cout << line;
  }
  fs::create_directories(out);
  WriteJson((fs::path(out) / "fronts.json").string(),
            {{"catalog", catalog.path}, {"frame", "catalog frame: z up, metres, +x right, +y up in the picture"},
             {"models", models}, {"skipped", catalog.skipped.size()}});
  const size_t n = catalog.models.size();
  const size_t cols = std::min<size_t>(n, size_t(kColumns)), rows = (n + cols - 1) / cols;
  const double width = double(cols) * 2 * kCell, height = kHeader + double(rows) * (kCell + kLabel);
  WriteDrawing((fs::path(out) / "fronts").string(), width, height, [&](cairo_t* cr) {
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_source_rgb(cr, 0, 0, 0);
    Label(cr, width / 2, 18, catalog.path, 12);
    Label(cr, width / 2, 36,
          "each model from above (+x right, +y up, darker = higher) and from its side, facing right (darker = "
          "nearer); arrow: the way it faces, solid red from catalog.json, dashed orange estimated", 12);
    for (size_t i = 0; i < n; ++i) {
      const ModelFront* f = catalog.FrontOf(catalog.models[i].id);
      DrawModel(cr, catalog.models[i], f ? *f : ModelFront{}, double(i % cols) * 2 * kCell,
                kHeader + double(i / cols) * (kCell + kLabel));
    }
  });
  std::cout << "-> " << (fs::path(out) / "fronts.png").string() << ", fronts.svg, fronts.json\n";
  return 0;
}

}  // namespace furnihost::app
