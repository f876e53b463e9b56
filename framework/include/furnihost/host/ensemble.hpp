// The ensemble (graph key "ensemble", EnsembleOptions): Pipeline::Detect runs the chain on the
// scans as read and on jittered copies, and fuses the runs' detections.
#pragma once
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost {

// Fuses the detections of several runs of one chain on (jittered copies of) one scan: per
// class and chain, greedily from the highest score, a detection takes from each other run the
// best-scored one not yet taken whose box (AABB) overlaps its own at IoU >= join_iou. The
// fused detection is the first run's member's (model, pose, checks, proposal, support), or the
// top one's with proposal -1 and no support when the first run has none, with
//   score = the sum of the members' scores / runs.size() (a run without one adds 0),
//   box = the members' mean centre and size (sizes swapped into the fused box's yaw), its
//         centre and model pose moved with the box;
// a "score" check is decided again on the fused score (an accepted detection whose fused score
// falls below its threshold is rejected; a rejected one whose fused score reaches it is accepted
// when no other check failed), evidence "ensemble_runs" counts the members. A
// detection without a box joins none. Sorted by fused score (descending); deterministic.
FURNIHOST_API std::vector<Detection> FuseDetections(const std::vector<std::vector<Detection>>& runs, double join_iou);

}  // namespace furnihost
