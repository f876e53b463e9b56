// furnihost::app::WriteBirdsEye: both files written atomically, classes in their colours at
// the right places (x right, y up), scan points grey by their height above the ground, errors
// on unwritable paths.
#include <cairo.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <vector>
#include <sstream>

#include "birdseye.hpp"
#include "png_writer.hpp"
#include "test_support.hpp"

namespace furnihost {
namespace {

namespace fs = std::filesystem;

struct Pixel {
  int r, g, b;
};

TEST(BirdsEye, WritesSvgAndPngWithClassColoursWhereTheObjectsAre) {
  const std::string dir = testing::TempDir("birdseye");
  const std::string stem = dir + "/votes";

  // A wall of points along x = 0 seen by a scan shifted by +0.5 m in x (pose applied).
  Scan scan;
  for (int i = 0; i <= 300; ++i) scan.points.emplace_back(-0.5f, 0.01f * i, 1.f);
  scan.pose = Eigen::Translation3f(0.5f, 0.f, 0.f) * Eigen::Isometry3f::Identity();

  VoteResult votes;
  votes.classes = {"chair", "table"};
  VoteGrid g;
  g.cls = "chair";
  g.origin = Eigen::Vector2f(0.f, 0.f);
  g.cell = 0.1f;
  g.width = 40;
  g.height = 30;
  g.values.assign(static_cast<size_t>(g.width) * g.height, 0.f);
  g.values[10 * g.width + 10] = 2.f;  // cell around (1.05, 1.05)
  votes.grids.push_back(g);
  Hypothesis h;
  h.cls = "chair";
  h.center = Eigen::Vector3f(1.f, 1.f, 0.4f);
  h.score = 2.f;
  votes.hypotheses.push_back(h);

  Detection chair;
  chair.cls = "chair";
  chair.center = Eigen::Vector3f(1.f, 1.f, 0.4f);
  chair.score = 2.f;
  Detection table;
  table.cls = "table";
  table.center = Eigen::Vector3f(3.f, 2.5f, 0.4f);
  table.score = 2.f;
  app::WriteBirdsEye(stem, {&scan}, votes, {chair, table});

  ASSERT_TRUE(fs::is_regular_file(stem + ".svg"));
  ASSERT_TRUE(fs::is_regular_file(stem + ".png"));
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << "left over: " << e.path();
  std::ifstream svg(stem + ".svg");
  std::stringstream text;
  text << svg.rdbuf();
  EXPECT_NE(text.str().find("<svg"), std::string::npos);

  cairo_surface_t* png = cairo_image_surface_create_from_png((stem + ".png").c_str());
  ASSERT_EQ(cairo_surface_status(png), CAIRO_STATUS_SUCCESS);
  const int w = cairo_image_surface_get_width(png), hgt = cairo_image_surface_get_height(png);
  const int stride = cairo_image_surface_get_stride(png);
  const unsigned char* data = cairo_image_surface_get_data(png);
  auto at = [&](int x, int y) {
    const uint32_t p = reinterpret_cast<const uint32_t*>(data + static_cast<size_t>(y) * stride)[x];
    return Pixel{static_cast<int>((p >> 16) & 255), static_cast<int>((p >> 8) & 255), static_cast<int>(p & 255)};
  };
  // Centroids of bluish, reddish and wall-grey (1 m up: 90) pixels left of the legend (the legend
  // column is the rightmost 190 px).
  const int plot_right = w - 200;
  double bx = 0, by = 0, rx = 0, ry = 0, gx = 0;
  int nb = 0, nr = 0, ng = 0;
  for (int y = 0; y < hgt; ++y)
    for (int x = 0; x < plot_right; ++x) {
      const Pixel p = at(x, y);
      if (p.b > 120 && p.b > p.r + 60 && p.b > p.g + 60) bx += x, by += y, ++nb;
      if (p.r > 120 && p.r > p.g + 60 && p.r > p.b + 60) rx += x, ry += y, ++nr;
      if (p.r == 90 && p.g == 90 && p.b == 90) gx += x, ++ng;  // 1 m above the floor
    }
  ASSERT_GT(nb, 20);
  ASSERT_GT(nr, 20);
  ASSERT_GT(ng, 100);
  bx /= nb, by /= nb, rx /= nr, ry /= nr, gx /= ng;
  EXPECT_LT(bx, rx);  // chair (x = 1) left of the table (x = 3)
  EXPECT_GT(by, ry);  // chair (y = 1) below the table (y = 2.5): y axis up
  EXPECT_LT(gx, bx);  // the wall (world x = 0) left of both
  // Metric check: world distance chair -> table is sqrt(2^2 + 1.5^2) = 2.5 m; the wall is
  // 3 m long in y. The pixel ratio must agree (same scale in x and y), within 5 %.
  const double d_px = std::hypot(rx - bx, ry - by);
  int ymin = hgt, ymax = -1;
  for (int y = 0; y < hgt; ++y)
    for (int x = 0; x < plot_right; ++x) {
      const Pixel p = at(x, y);
      if (p.r == 90 && p.g == 90 && p.b == 90) ymin = std::min(ymin, y), ymax = std::max(ymax, y);
    }
  EXPECT_NEAR(d_px / (ymax - ymin), 2.5 / 3.0, 0.05 * 2.5 / 3.0);
  cairo_surface_destroy(png);
  fs::remove_all(dir);
}

// Votes are drawn only within the scan's outline (parts also vote for centres beyond walls);
// the scan's points stay visible under them.
TEST(BirdsEye, VotesOutsideTheScanAreNotDrawn) {
  const std::string dir = testing::TempDir("birdseye_outline");
  Scan room;  // floor points of a 4 m x 3 m room, 5 cm apart
  for (int i = 0; i <= 80; ++i)
    for (int j = 0; j <= 60; ++j) room.points.emplace_back(0.05f * i, 0.05f * j, 0.f);
  VoteResult votes;
  VoteGrid g;
  g.cls = "sofa";  // the palette's first colour: green
  g.origin = Eigen::Vector2f(0.f, 0.f);
  g.cell = 0.1f;
  g.width = 70;
  g.height = 30;
  g.values.assign(static_cast<size_t>(g.width) * g.height, 0.f);
  g.values[15 * g.width + 20] = 1.f;  // (2.05, 1.55): inside the room
  g.values[15 * g.width + 55] = 1.f;  // (5.55, 1.55): 1.5 m beyond its wall
  votes.grids.push_back(g);
  Detection table;  // widens the picture to x = 6.5
  table.cls = "table";
  table.center = Eigen::Vector3f(6.5f, 1.5f, 0.4f);
  table.score = 1.f;
  app::WriteBirdsEye(dir + "/votes", {&room}, votes, {table});

  cairo_surface_t* png = cairo_image_surface_create_from_png((dir + "/votes.png").c_str());
  ASSERT_EQ(cairo_surface_status(png), CAIRO_STATUS_SUCCESS);
  const int w = cairo_image_surface_get_width(png), hgt = cairo_image_surface_get_height(png);
  const int stride = cairo_image_surface_get_stride(png);
  const unsigned char* data = cairo_image_surface_get_data(png);
  // The view: x from -0.25 to 6.75 m (0.25 m padding), 1000 px / 7 m, 40 px margin.
  const double ppm = 1000.0 / 7.0;
  auto px = [&](double x) { return 40.0 + (x + 0.25) * ppm; };
  int green_in = 0, green_out = 0, floor_px = 0;
  for (int y = 0; y < hgt; ++y)
    for (int x = 0; x < w - 200; ++x) {
      const uint32_t p = reinterpret_cast<const uint32_t*>(data + static_cast<size_t>(y) * stride)[x];
      const int r = (p >> 16) & 255, gg = (p >> 8) & 255, b = p & 255;
      if (gg > 120 && gg > r + 30 && gg > b + 30) (x < px(4.1) ? green_in : green_out)++;
      if (x > px(0.5) && x < px(1.5) && r < 235 && b > r && std::abs(gg - (r + b) / 2) < 12) ++floor_px;
    }
  EXPECT_GT(green_in, 100);  // the vote in the room (a 0.1 m cell is ~14 x 14 px)
  EXPECT_EQ(green_out, 0);   // the one beyond the wall is clipped
  EXPECT_GT(floor_px, 2000);  // floor points drawn as blocks, not dust
  cairo_surface_destroy(png);
  fs::remove_all(dir);
}

TEST(BirdsEye, EmptyInputStillDrawsAndUnwritablePathThrows) {
  const std::string dir = testing::TempDir("birdseye_empty");
  EXPECT_NO_THROW(app::WriteBirdsEye(dir + "/empty", {}, VoteResult{}, {}));
  EXPECT_TRUE(fs::is_regular_file(dir + "/empty.png"));
  fs::remove_all(dir);
  EXPECT_THROW(app::WriteBirdsEye("/dev/null/not_a_dir/votes", {}, VoteResult{}, {}), InputError);
}

}  // namespace
}  // namespace furnihost

namespace furnihost {
namespace {

// The plots' fast PNG encoder against cairo's own writer: the same pixels once read back, for
// opaque, translucent (premultiplied) and fully transparent pixels and for an RGB24 surface.
TEST(PngWriter, SamePixelsAsCairosWriter) {
  const std::string dir = testing::TempDir("png_writer");
  for (const cairo_format_t format : {CAIRO_FORMAT_ARGB32, CAIRO_FORMAT_RGB24}) {
    cairo_surface_t* img = cairo_image_surface_create(format, 37, 23);
    cairo_t* cr = cairo_create(img);
    cairo_set_source_rgba(cr, 0.2, 0.5, 0.9, 0.35);  // translucent
    cairo_rectangle(cr, 3, 2, 20, 15);
    cairo_fill(cr);
    cairo_set_source_rgba(cr, 1.0, 0.1, 0.0, 1.0);  // opaque
    cairo_arc(cr, 25, 12, 8, 0, 6.3);
    cairo_fill(cr);
    cairo_set_source_rgba(cr, 0.7, 0.7, 0.1, 0.02);  // nearly transparent
    cairo_rectangle(cr, 0, 18, 37, 5);
    cairo_fill(cr);
    cairo_destroy(cr);
    const std::string ours = dir + "/ours.png", theirs = dir + "/cairo.png";
    app::WritePng(img, ours);
    ASSERT_EQ(cairo_surface_write_to_png(img, theirs.c_str()), CAIRO_STATUS_SUCCESS);
    cairo_surface_t* a = cairo_image_surface_create_from_png(ours.c_str());
    cairo_surface_t* b = cairo_image_surface_create_from_png(theirs.c_str());
    ASSERT_EQ(cairo_surface_status(a), CAIRO_STATUS_SUCCESS);
    ASSERT_EQ(cairo_image_surface_get_width(a), 37);
    ASSERT_EQ(cairo_image_surface_get_height(a), 23);
    int differ = 0, translucent = 0;
    for (int y = 0; y < 23; ++y)
      for (int x = 0; x < 37; ++x) {
        const auto pa = reinterpret_cast<const uint32_t*>(cairo_image_surface_get_data(a) + y * cairo_image_surface_get_stride(a))[x];
        const auto pb = reinterpret_cast<const uint32_t*>(cairo_image_surface_get_data(b) + y * cairo_image_surface_get_stride(b))[x];
        differ += pa != pb;
        translucent += format == CAIRO_FORMAT_ARGB32 && (pb >> 24) > 0 && (pb >> 24) < 255;
      }
    EXPECT_EQ(differ, 0) << (format == CAIRO_FORMAT_ARGB32 ? "ARGB32" : "RGB24");
    if (format == CAIRO_FORMAT_ARGB32) {
      EXPECT_GT(translucent, 100);  // the un-premultiplying was exercised
    }
    cairo_surface_destroy(a);
    cairo_surface_destroy(b);
    cairo_surface_destroy(img);
  }
  // A surface that is not an image is refused with the path named, nothing written.
  cairo_surface_t* rec = cairo_recording_surface_create(CAIRO_CONTENT_COLOR_ALPHA, nullptr);
  try {
    app::WritePng(rec, dir + "/nothing.png");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nothing.png"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir + "/nothing.png"));
  cairo_surface_destroy(rec);
}

}  // namespace
}  // namespace furnihost
