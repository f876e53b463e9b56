// Bird's-eye view of a detection run (as the paper's Fig. 4 f/h): the scans from above (grey
// by height above the ground), the vote density of each class as translucent coloured cells
// within the scan's outline, hypotheses as
// circle outlines and detections as filled circles, both sized by score, each accepted one with
// its box and an arrow the way it faces, a legend and a 1 m scale bar. The user's frame (Scan::pose, then `display`), x to the right, y up.
#pragma once
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::app {

// Writes <stem>.svg and <stem>.png (each atomically). Classes are coloured chair blue, table
// red, cabinet yellow, others from a fixed palette. Throws InputError when a file cannot be
// written.
// `display` maps the world frame of the run to the frame drawn (Pipeline::Result::world_to_user:
// the user's z-up frame, whatever working frame the stages used).
void WriteBirdsEye(const std::string& stem, const std::vector<const furnihost::Scan*>& scans,
                   const furnihost::VoteResult& votes,
                   const std::vector<furnihost::Detection>& detections,
                   const Eigen::Isometry3f& display = Eigen::Isometry3f::Identity());

// Loads the plots' font (fontconfig's set-up and the face: ~6 ms the first text of a process
// costs) without a surface, so it can run on a worker while the scan is read and the SVG's
// surface numbering stays as it is.
void WarmUpPlotFonts();

}  // namespace furnihost::app
