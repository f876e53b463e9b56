// The git revision of a checkout for run records, read from the files of its .git folder (HEAD,
// refs, packed-refs, a worktree's commondir, the index) and never by running git: git reads the
// repository's own config and runs commands it names (core.fsmonitor, filters), and eval reads
// graphs from folders that may be anyone's repository.
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace furnihost::app {

// {"revision": 40 hex digits, "dirty": true/false/null, "dir": the folder it was found for} of
// the first of `dirs` inside a git checkout (searched upwards), else {"revision": "unknown",
// "dirty": null}. "dirty": a tracked file's size or modification time differs from the index's
// record (null when the index cannot be read).
nlohmann::json GitInfo(const std::vector<std::string>& dirs);

}  // namespace furnihost::app
