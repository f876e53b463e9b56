// Bird's-eye view of a detection run (as the paper's Fig. 4 f/h): the scans from above in
// light grey, the vote density of each class as translucent coloured cells, hypotheses as
// circle outlines and detections as filled circles, both sized by score, a legend and a 1 m
// scale bar. World frame (Scan::pose applied), x to the right, y up.
#pragma once
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::app {

// Writes <stem>.svg and <stem>.png (each atomically). Classes are coloured chair blue, table
// red, cabinet yellow, others from a fixed palette. Throws InputError when a file cannot be
// written.
void WriteBirdsEye(const std::string& stem, const std::vector<const furnihost::Scan*>& scans,
                   const furnihost::VoteResult& votes,
                   const std::vector<furnihost::Detection>& detections);

}  // namespace furnihost::app
