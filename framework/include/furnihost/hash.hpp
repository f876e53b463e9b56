// Stable 64-bit FNV-1a hashing, the one hash of the host and the plugins (dataset hashes, model
// and model-cloud cache keys, sampling and RANSAC seeds): unlike std::hash, its values do not
// depend on the standard library, the build or the run.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

#include "furnihost/error.hpp"

namespace furnihost {

// The FNV-1a 64 offset basis.
constexpr uint64_t kFnvOffset = 14695981039346656037ull;
// The offset basis without its last digit. The catalog hash (part of every model file's cache
// key), ransac_upright's model-cloud cache keys and its sampling and RANSAC seeds, and
// icp_refine's sampling seeds have always started from it. It hashes as well as the standard
// one; changing it would change those keys and seeds, and with the seeds the detections, so
// those uses keep it (pass it explicitly).
constexpr uint64_t kFnvOffsetTruncated = 1469598103934665603ull;

// 64-bit FNV-1a over `size` bytes, continuing from `h` (start with one of the offsets above).
FURNIHOST_API uint64_t Fnv1a(const void* data, size_t size, uint64_t h = kFnvOffset);
inline uint64_t Fnv1a(const std::string& s, uint64_t h = kFnvOffset) { return Fnv1a(s.data(), s.size(), h); }

// The folder where results keyed by such hashes are kept between runs: $FURNIHOST_CACHE_DIR,
// else $XDG_CACHE_HOME/furnihost, else $HOME/.cache/furnihost, + "/" + `sub`; empty when none
// of the three is set (then nothing is cached). Used by the catalog's parsed meshes ("meshes")
// and fitters.ransac_upright's model clouds ("model_clouds").
FURNIHOST_API std::string CacheFolder(const std::string& sub);

}  // namespace furnihost
