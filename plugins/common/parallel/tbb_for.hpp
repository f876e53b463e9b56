// The `parallel_for` callable of furnihost::VoxelIndex::Build over TBB, for the plugins that
// link TBB (the framework header itself stays free of it).
#pragma once
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>

namespace furnihost {

struct TbbFor {
  template <class Body>
  void operator()(size_t begin, size_t end, size_t grain, Body&& body) const {
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, grain),
                      [&](const tbb::blocked_range<size_t>& r) { body(r.begin(), r.end()); });
  }
};

}  // namespace furnihost
