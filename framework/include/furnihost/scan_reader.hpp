// Reading scan files: the part of the file IO that is in the SDK, because a sensor plugin
// (sensors.scan_file) reads scans. The writers, JSON and ground-truth files are host IO
// (io.hpp, which includes this header).
#pragma once
#include <optional>
#include <string>

#include "furnihost/types.hpp"

namespace furnihost {

// Scans are metres in a local frame: points farther than this from the (shifted) origin are
// dropped as garbage [m]. It bounds every other position given with a scan too (a sensor
// origin, a --transform's translation, a --pose).
constexpr double kMaxScanCoordinate = 1e6;
// A global shift (--shift, or the automatic one) is at most this per axis [m]: ECEF and every
// map projection stay below it.
constexpr double kMaxGlobalShift = 1e8;

struct ReadStats {
  size_t read = 0;         // points in the file
  size_t non_finite = 0;   // dropped NaN/inf points
};

// Reads .pcd (ascii/binary/binary_compressed with the project's own reader: the header is
// checked whole against itself and the file before any data is read; VIEWPOINT becomes the
// sensor origin unless it is PCL's default of 0,0,0 with identity rotation; packed rgb/rgba
// and integer fields such as label / instance kept; organised clouds' NaN padding dropped;
// binary_compressed: the compressed size no more than the file holds, the uncompressed size the
// header's points x point size, the points within `max_points`, and the data decoded as a
// stream that keeps only the x, y, z, colour and attribute columns, so what is allocated is
// bounded by the file and the point cap, never by a declared size),
// .ply (ascii / binary little or big endian; x y z required, red green blue / label /
// instance kept) and .xyz/.txt/.pts/.asc (one point per line: x y z [more columns], the same
// columns on every line; blanks, commas or semicolons between values, a decimal comma read as
// such with semicolons or blanks; a UTF-8 byte-order mark skipped, UTF-16 refused; .pts count
// lines skipped). Non-finite points are dropped and counted, and so are points farther than
// kMaxScanCoordinate from the origin and stray returns (points a gap of more than 100 m along an
// axis separates from the largest group of the scan), with a warning.
// `max_points` refuses larger scans with an InputError (0 = no cap).
// Throws InputError "<path>: <what is wrong>".
// Coordinates are read in double and the global shift (ShiftOption) subtracted before they
// are rounded to float. The automatic shift follows the bulk of the scan: a file whose first
// point is a stray return is read again with the shift the rest calls for.
FURNIHOST_API Scan ReadScan(const std::string& path, ReadStats* stats = nullptr,
                            size_t max_points = 0, const ShiftOption& shift = {});

// The sensor origin a scan file declares, from its header alone: a PCD's VIEWPOINT (unless it
// is PCL's default, as ReadScan); nullopt for a PCD without one and for the other formats.
// InputError as ReadScan on a missing file or a bad PCD header.
FURNIHOST_API std::optional<Eigen::Vector3d> ScanFileOrigin(const std::string& path);

// A scan from points in memory, named `name` in messages: `n` rows of x, y, z (in the caller's
// frame; `xyz` holds 3 n values, row after row) and, when `rgb` is not null, 3 n colour bytes.
// The rules of ReadScan: the global shift (the automatic one following the bulk of the points)
// subtracted in double before rounding to float, non-finite rows, rows farther than
// kMaxScanCoordinate and stray returns dropped and counted; InputError "<name>: ..." when none
// is left.
FURNIHOST_API Scan ScanFromPoints(const std::string& name, const double* xyz, size_t n, const uint8_t* rgb = nullptr,
                                  ReadStats* stats = nullptr, const ShiftOption& shift = {});

// Checks that `path` names a readable regular file (not a directory, FIFO, ...).
FURNIHOST_API void RequireRegularFile(const std::string& path, const std::string& what);

}  // namespace furnihost
