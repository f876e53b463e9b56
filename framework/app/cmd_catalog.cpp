// furnihost catalog: what a catalog holds after import, to check before training on it: each
// model's class, size and the way it faces (catalog.json's "front", else EstimateFront's guess),
// as a table, fronts.json and a contact sheet (fronts.svg/.png: every model from above, shaded
// by height, with an arrow the way it faces).
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

constexpr double kCell = 220, kLabel = 40, kColumns = 6, kMargin = 10;

void Label(cairo_t* cr, double x, double y, const std::string& s, double size) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t e;
  cairo_text_extents(cr, s.c_str(), &e);
  cairo_move_to(cr, x - 0.5 * e.width - e.x_bearing, y);
  cairo_show_text(cr, s.c_str());
}

// One model in a kCell-wide cell at (x0, y0): its triangles from above, lower ones first and
// darker the higher they stand, the footprint box, and an arrow from the centre the way it
// faces (solid red from the catalog, dashed orange when estimated).
void DrawModel(cairo_t* cr, const CatalogModel& m, const ModelFront& front, double x0, double y0) {
  const double draw = kCell - 2 * kMargin;
  const Eigen::AlignedBox3f b = m.mesh.Bounds();
  const double span = std::max({double(b.sizes().x()), double(b.sizes().y()), 1e-3});
  const double ppm = 0.8 * draw / span;
  const double cx = x0 + kCell / 2, cy = y0 + kMargin + draw / 2;
  const Eigen::Vector3f mid = b.center();
  auto px = [&](const Eigen::Vector3f& p) { return cx + (p.x() - mid.x()) * ppm; };
  auto py = [&](const Eigen::Vector3f& p) { return cy - (p.y() - mid.y()) * ppm; };
  std::vector<std::pair<float, size_t>> order;
  order.reserve(m.mesh.triangles.size());
  for (size_t t = 0; t < m.mesh.triangles.size(); ++t) {
    const auto& tri = m.mesh.triangles[t];
    order.emplace_back(m.mesh.vertices[tri[0]].z() + m.mesh.vertices[tri[1]].z() + m.mesh.vertices[tri[2]].z(), t);
  }
  std::sort(order.begin(), order.end());
  const double height = std::max(1e-3, double(b.sizes().z()));
  for (const auto& [zsum, t] : order) {
    const auto& tri = m.mesh.triangles[t];
    const double shade = 0.85 - 0.6 * std::clamp((zsum / 3.0 - b.min().z()) / height, 0.0, 1.0);
    cairo_set_source_rgb(cr, shade, shade, shade);
    cairo_move_to(cr, px(m.mesh.vertices[tri[0]]), py(m.mesh.vertices[tri[0]]));
    cairo_line_to(cr, px(m.mesh.vertices[tri[1]]), py(m.mesh.vertices[tri[1]]));
    cairo_line_to(cr, px(m.mesh.vertices[tri[2]]), py(m.mesh.vertices[tri[2]]));
    cairo_close_path(cr);
    cairo_fill_preserve(cr);
    cairo_set_line_width(cr, 0.3);
    cairo_stroke(cr);
  }
  cairo_set_source_rgb(cr, 0.3, 0.3, 0.3);
  cairo_set_line_width(cr, 1);
  cairo_rectangle(cr, px(b.min()), py(b.max()), b.sizes().x() * ppm, b.sizes().y() * ppm);
  cairo_stroke(cr);
  const bool given = front.source == "catalog";
  const Eigen::Vector2d f(front.front.x(), front.front.y());
  const double len = 0.45 * draw;
  const double ex = cx + f.x() * len, ey = cy - f.y() * len;
  if (given) cairo_set_source_rgb(cr, 0.85, 0.1, 0.1);
  else cairo_set_source_rgb(cr, 0.95, 0.55, 0.0);
  const double dash[] = {6.0, 4.0};
  cairo_set_dash(cr, dash, given ? 0 : 2, 0);
  cairo_set_line_width(cr, 3);
  cairo_move_to(cr, cx, cy);
  cairo_line_to(cr, ex, ey);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  const double a = std::atan2(-f.y(), f.x());
  cairo_move_to(cr, ex, ey);
  cairo_line_to(cr, ex - 14 * std::cos(a - 0.4), ey - 14 * std::sin(a - 0.4));
  cairo_line_to(cr, ex - 14 * std::cos(a + 0.4), ey - 14 * std::sin(a + 0.4));
  cairo_close_path(cr);
  cairo_fill(cr);
  cairo_set_source_rgb(cr, 0, 0, 0);
  Label(cr, cx, y0 + kCell + 12, m.id, 12);
  char size[64];
  std::snprintf(size, sizeof(size), "%.2f x %.2f x %.2f m", m.size.x(), m.size.y(), m.size.z());
  Label(cr, cx, y0 + kCell + 27, m.cls + ", " + size, 10);
}

}  // namespace

int RunCatalog(const std::vector<std::string>& args) {
  CLI::App app{"Show what a catalog holds after import: each model's class, size and the way it faces "
               "(catalog.json's \"front\", else estimated from the mesh), as a table, fronts.json and a contact "
               "sheet fronts.svg/.png (every model from above, an arrow the way it faces: solid from the catalog, "
               "dashed when estimated). Check the estimates before training; write a \"front\" where one is wrong.\n"
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
  const double width = double(cols) * kCell, height = 30 + double(rows) * (kCell + kLabel);
  WriteDrawing((fs::path(out) / "fronts").string(), width, height, [&](cairo_t* cr) {
    cairo_set_source_rgb(cr, 1, 1, 1);
    cairo_paint(cr);
    cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_source_rgb(cr, 0, 0, 0);
    Label(cr, width / 2, 20,
          catalog.path + ": each model from above (darker = higher); arrow: the way it faces, solid red from "
          "catalog.json, dashed orange estimated (+x right, +y up)", 12);
    for (size_t i = 0; i < n; ++i) {
      const ModelFront* f = catalog.FrontOf(catalog.models[i].id);
      DrawModel(cr, catalog.models[i], f ? *f : ModelFront{}, double(i % cols) * kCell,
                30 + double(i / cols) * (kCell + kLabel));
    }
  });
  std::cout << "-> " << (fs::path(out) / "fronts.png").string() << ", fronts.svg, fronts.json\n";
  return 0;
}

}  // namespace furnihost::app
