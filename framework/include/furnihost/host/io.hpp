// Scan and output file IO (host). Every writer goes through AtomicWrite (temp file + rename),
// so an interrupted run never leaves a half-written output. The scan readers (ReadScan,
// RequireRegularFile) are in the SDK header scan_reader.hpp, included here.
#pragma once
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "furnihost/scan_reader.hpp"
#include "furnihost/types.hpp"

namespace furnihost {

// Writers. PCD is binary with VIEWPOINT from scan.origin; PLY is binary little endian with
// optional per-point colours.
FURNIHOST_API void WritePcd(const std::string& path, const Scan& scan);
FURNIHOST_API void WritePly(const std::string& path, const Points& points,
                            const std::vector<std::array<uint8_t, 3>>* colors = nullptr);
// Points of a scan's working frame written back in its file's frame (ScanFrame::ToFile):
// float coordinates, or double ones when the frame has a global shift (float would round
// georeferenced coordinates to decimetres), so the output overlays the user's own scan.
FURNIHOST_API void WritePlyInFrame(const std::string& path, const Points& working, const ScanFrame& frame,
                                   const std::vector<std::array<uint8_t, 3>>* colors = nullptr);
FURNIHOST_API void WriteXyz(const std::string& path, const Points& points);
// Chooses the writer from the extension (.pcd, .ply, .xyz/.txt).
FURNIHOST_API void WriteScan(const std::string& path, const Scan& scan);

// Writes via a temp file in the same folder and renames it over `path`. `fill` writes the
// content to the temp path. Creates missing parent folders.
FURNIHOST_API void AtomicWrite(const std::string& path,
                               const std::function<void(const std::string& tmp_path)>& fill);
FURNIHOST_API void AtomicWriteText(const std::string& path, const std::string& text);
FURNIHOST_API void WriteJson(const std::string& path, const nlohmann::json& j);

// Reads a JSON file; InputError "<path>: ..." on a missing file or a parse error (with line).
FURNIHOST_API nlohmann::json ReadJson(const std::string& path);
// Reads a *.gt.json file.
FURNIHOST_API std::vector<GroundTruthObject> ReadGroundTruth(const std::string& path);
FURNIHOST_API nlohmann::json GroundTruthToJson(const std::vector<GroundTruthObject>& objects);

}  // namespace furnihost
