// Stable 64-bit FNV-1a hashing, the one hash of the host and the plugins (dataset hashes, model
// and model-cloud cache keys, sampling and RANSAC seeds), and SplitMix64 to derive seeds from
// it: unlike std::hash, their values do not depend on the standard library, the build or the run.
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

// SplitMix64's finaliser (Steele, Lea & Flood 2014): a bijection of 64-bit words whose outputs
// for related inputs (x, x + 1, a seed xor an index) are independent for practical purposes.
// Derives seeds and counter-based random numbers: the same value on every build and run.
inline uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// The home slot of `key` in an open-addressing table of `mask + 1` slots (a power of two).
// Keys pack voxel coordinates (21 bits per axis) or a point's float bits, so two keys often
// differ in one field only: a run of voxels along x, y or z. The finaliser above carries every
// key bit into every slot bit, so such a run spreads over the table whatever its size (a
// multiply alone leaves the low product bits blind to the high key bits: a run along the axis
// packed highest lands on one slot, and linear probing turns quadratic).
inline size_t HashSlot(uint64_t key, size_t mask) { return size_t(SplitMix64(key)) & mask; }

// The top 53 bits of `bits` as a uniform double in (0, 1], never 0 (log-safe; 1 only where the
// half-step rounds up): a draw from a SplitMix64 output (JitterPoints, sensors.simulated_laser).
inline double UnitOpen(uint64_t bits) { return (double(bits >> 11) + 0.5) * (1.0 / 9007199254740992.0); }

// The folder where results keyed by such hashes are kept between runs: $FURNIHOST_CACHE_DIR,
// else $XDG_CACHE_HOME/furnihost, else $HOME/.cache/furnihost, + "/" + `sub`; empty when none
// of the three is set (then nothing is cached). Used by the catalog's parsed meshes ("meshes")
// and fitters.ransac_upright's model clouds ("model_clouds").
FURNIHOST_API std::string CacheFolder(const std::string& sub);

}  // namespace furnihost
