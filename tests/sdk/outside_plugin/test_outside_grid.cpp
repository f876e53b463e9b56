// The example grid segmenter built outside furnihost's tree, run through the installed host:
// found by type name in this build's plugin folder, its declared parameter applied.
#include <gtest/gtest.h>

#include "furnihost/stage.hpp"
#include "test_stages.hpp"

namespace {

TEST(OutsidePlugin, GridSegmenterRunsThroughTheInstalledHost) {
  auto seg = furnihost::testing::MakeStage<furnihost::Segmenter>("segmenters.example_grid", {{"cell_m", 0.5}});
  furnihost::Scan scan;
  for (int i = 0; i < 40; ++i)  // 20 points in each of two cells 2 m apart
    scan.points.emplace_back(float(i % 2) * 2.f + 0.01f * float(i), 0.1f, 0.1f);
  const furnihost::Segmentation s = seg->Segment(scan, furnihost::RunContext{});
  EXPECT_EQ(s.parts.size(), 2u);
}

}  // namespace
