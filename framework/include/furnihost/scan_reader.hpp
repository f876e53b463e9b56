// Reading scan files: the part of the file IO that is in the SDK, because a sensor plugin
// (sensors.scan_file) reads scans. The writers, JSON and ground-truth files are host IO
// (io.hpp, which includes this header).
#pragma once
#include <optional>
#include <string>

#include "furnihost/types.hpp"

namespace furnihost {

struct ReadStats {
  size_t read = 0;         // points in the file
  size_t non_finite = 0;   // dropped NaN/inf points
};

// Reads .pcd (ascii/binary/binary_compressed with the project's own reader: the header is
// checked whole against itself and the file before any data is read; VIEWPOINT becomes the
// sensor origin unless it is PCL's default of 0,0,0 with identity rotation; packed rgb/rgba
// and integer fields such as label / instance kept; organised clouds' NaN padding dropped),
// .ply (ascii / binary little or big endian; x y z required, red green blue / label /
// instance kept) and .xyz/.txt (x y z [more columns]). Non-finite points are dropped and
// counted.
// `max_points` refuses larger scans with an InputError (0 = no cap).
// Throws InputError "<path>: <what is wrong>".
// Coordinates are read in double and the global shift (ShiftOption) subtracted before they
// are rounded to float.
FURNIHOST_API Scan ReadScan(const std::string& path, ReadStats* stats = nullptr,
                            size_t max_points = 0, const ShiftOption& shift = {});

// The sensor origin a scan file declares, from its header alone: a PCD's VIEWPOINT (unless it
// is PCL's default, as ReadScan); nullopt for a PCD without one and for the other formats.
// InputError as ReadScan on a missing file or a bad PCD header.
FURNIHOST_API std::optional<Eigen::Vector3d> ScanFileOrigin(const std::string& path);

// A scan from points in memory, named `name` in messages: `n` rows of x, y, z (in the caller's
// frame; `xyz` holds 3 n values, row after row) and, when `rgb` is not null, 3 n colour bytes.
// The rules of ReadScan: the global shift subtracted in double before rounding to float,
// non-finite rows and rows farther than 1e6 m dropped and counted; InputError "<name>: ..."
// when none is left.
FURNIHOST_API Scan ScanFromPoints(const std::string& name, const double* xyz, size_t n, const uint8_t* rgb = nullptr,
                                  ReadStats* stats = nullptr, const ShiftOption& shift = {});

// Checks that `path` names a readable regular file (not a directory, FIFO, ...).
FURNIHOST_API void RequireRegularFile(const std::string& path, const std::string& what);

}  // namespace furnihost
