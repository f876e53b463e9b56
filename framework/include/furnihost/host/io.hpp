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
// j.dump(indent), bytes that are not UTF-8 (file names) shown as U+FFFD instead of throwing.
FURNIHOST_API std::string DumpJson(const nlohmann::json& j, int indent = -1);

// Reads a JSON file; InputError "<path>: ..." on a missing file or a parse error (with line).
// Nesting deeper than kMaxJsonDepth levels is refused before parsing.
FURNIHOST_API nlohmann::json ReadJson(const std::string& path);
constexpr size_t kMaxJsonDepth = 256;
// InputError "<what>: not UTF-8 text ..." when `text` holds a NUL byte or invalid UTF-8.
FURNIHOST_API void RequireUtf8(const std::string& text, const std::string& what);
// The deepest bracket nesting of `text` (brackets in strings not counted).
FURNIHOST_API size_t JsonDepth(const std::string& text);
// JSON text from wherever (a file's content, a command-line value); errors start with `where`.
FURNIHOST_API nlohmann::json ParseJsonText(const std::string& text, const std::string& where);
// A JSON value given on the command line (--set's VALUE, gap --sensor's PARAMS, simulate
// --sensor-params): UTF-8 without NUL bytes, bounded as config files are (kMaxJsonDepth). With `bare_words`, text that
// is not JSON is the string itself (--set vote.kind=fast); otherwise it is an InputError.
// Errors start with `option`.
FURNIHOST_API nlohmann::json ParseCliJson(const std::string& text, const std::string& option, bool bare_words = false);
// A file or folder name made from an input's name (a scan's stem, an eval --name): one path
// component of at most 100 bytes, never "", "." or "..": bytes other than letters, digits, '.',
// '-' and '_' become '_', and so do leading dots. Outputs named by it stay in their folder.
FURNIHOST_API std::string SafeName(const std::string& name);
// SafeName of each, made distinct (compared without case): a name met before gets "_2", "_3",
// ... in order, so two scans named room.pcd in different folders never share an output.
FURNIHOST_API std::vector<std::string> UniqueSafeNames(const std::vector<std::string>& names);

// Reads a *.gt.json file.
FURNIHOST_API std::vector<GroundTruthObject> ReadGroundTruth(const std::string& path);
FURNIHOST_API nlohmann::json GroundTruthToJson(const std::vector<GroundTruthObject>& objects);

}  // namespace furnihost
