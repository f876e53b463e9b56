// Copies of one point for the segmenters built on PCL and CGAL. Their neighbour searches use
// k-d trees whose leaves cannot split identical points, so N copies of one point (a driver's
// (0, 0, 0) for every invalid return) cost N^2. They segment the distinct positions instead,
// and the result is spread back over the copies: each copy gets its position's normal,
// curvature and part. A scan without copies is segmented as it is. With copies, the size
// rules (min_points, max_points) count distinct positions.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include <limits>

#include "furnihost/geometry.hpp"
#include "furnihost/stage.hpp"
#include "furnihost/types.hpp"

namespace furnihost {

struct ScanCopies {
  bool any = false;
  std::vector<uint32_t> of;  // per scan point: its distinct position (an index of distinct.points)
  Scan distinct;             // the scan with one point per position (origin, ground, frame kept)
};

// Groups equal points (GroupEqualPoints: bit patterns, -0 folded onto +0; linear time).
inline ScanCopies FindCopies(const Scan& scan) {
  ScanCopies c;
  const Points& p = scan.points;
  Points distinct = GroupEqualPoints(p, &c.of);
  c.any = distinct.size() < p.size();
  if (!c.any) {
    c.of.clear();
    return c;
  }
  c.distinct.source = scan.source;
  c.distinct.origin = scan.origin;
  c.distinct.pose = scan.pose;
  c.distinct.frame = scan.frame;
  c.distinct.ground = scan.ground;
  c.distinct.points = std::move(distinct);
  return c;
}

// The segmentation of `c.distinct` spread over the scan's points (index order kept in parts).
inline Segmentation SpreadOverCopies(const Segmentation& d, const ScanCopies& c, const Scan& scan) {
  const size_t n = c.of.size();
  Segmentation s;
  s.normals.resize(n);
  s.curvature.resize(n);
  for (size_t i = 0; i < n; ++i) {
    s.normals[i] = d.normals[c.of[i]];
    s.curvature[i] = d.curvature[c.of[i]];
  }
  std::vector<int> part_of(c.distinct.points.size(), -1);
  for (size_t k = 0; k < d.parts.size(); ++k)
    for (int u : d.parts[k].indices) part_of[size_t(u)] = int(k);
  s.parts.resize(d.parts.size());
  std::vector<Eigen::Vector3d> sum(d.parts.size(), Eigen::Vector3d::Zero());
  int extra_discarded = 0;  // copies of positions in no part, beyond the one the segmenter saw
  std::vector<uint8_t> seen(c.distinct.points.size(), 0);
  for (size_t i = 0; i < n; ++i) {
    const int k = part_of[c.of[i]];
    if (k < 0) {
      extra_discarded += seen[c.of[i]];
      seen[c.of[i]] = 1;
      continue;
    }
    s.parts[size_t(k)].indices.push_back(int(i));
    sum[size_t(k)] += scan.points[i].cast<double>();
  }
  for (size_t k = 0; k < s.parts.size(); ++k)
    s.parts[k].centroid = s.parts[k].indices.empty() ? d.parts[k].centroid
                                                     : (sum[k] / double(s.parts[k].indices.size())).cast<float>();
  s.discarded_points = d.discarded_points + extra_discarded;
  return s;
}

// A segmenter built on such a library: Segment() finds the copies and hands SegmentDistinct()
// a scan of distinct positions (or the scan itself when it has none).
class DistinctPointsSegmenter : public Segmenter {
 public:
  Segmentation Segment(const Scan& scan, const RunContext& ctx) final {
    const ScanCopies copies = FindCopies(scan);
    if (copies.any) return SpreadOverCopies(SegmentDistinct(copies.distinct, ctx), copies, scan);
    return SegmentDistinct(scan, ctx);
  }

 protected:
  virtual Segmentation SegmentDistinct(const Scan& scan, const RunContext& ctx) = 0;

  // A segmentation of n points with no part yet: NaN normals and curvature.
  static Segmentation Unsegmented(size_t n) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    Segmentation seg;
    seg.normals.assign(n, Eigen::Vector3f::Constant(nan));
    seg.curvature.assign(n, nan);
    return seg;
  }
};

}  // namespace furnihost
