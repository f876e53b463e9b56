// Options shared by the subcommands, and argument parsing helpers (CLI11).
#pragma once
#include <CLI/CLI.hpp>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "furnihost/host/config.hpp"
#include "furnihost/host/frame.hpp"
#include "furnihost/host/registry.hpp"
#include "furnihost/stage.hpp"

namespace furnihost::app {

struct CommonOptions {
  std::vector<std::string> plugin_paths;
  int verbose = 0;
  bool quiet = false;
  int threads = 0;
  std::optional<uint64_t> seed;
  std::vector<std::string> sets;  // --set TAG.PARAM=VALUE
  std::optional<double> min_confidence;  // --min-confidence: calibration.min_confidence

  void Add(CLI::App& app, bool with_run_options = true);
  // --min-confidence (detect, eval).
  void AddMinConfidence(CLI::App& app);
  // Applies logging and thread settings; call after parsing.
  void Apply() const;
  std::unique_ptr<Registry> MakeRegistry() const;
  RunContext Context(uint64_t graph_seed) const;
  // The graph with the --set overrides (and --min-confidence) applied.
  GraphConfig LoadGraph(const std::string& path, const Registry& registry) const;
};

// Scan frame and ground options of detect (--up, --transform, --shift, --ground).
struct FrameCli {
  std::string up = "+z", transform, shift, ground;
  bool level = false;
  void Add(CLI::App& app);
  // The parsed frame; InputError naming the option on a bad value.
  FrameOptions Frame() const;
  // --ground KIND or a number (a fixed floor height in the working frame) into the graph.
  void ApplyGround(GraphConfig& g) const;
};

// Parses `args` (program name and subcommand word excluded). Returns std::nullopt to go on,
// or the exit code (0 after --help, 2 after a usage error, message printed).
std::optional<int> Parse(CLI::App& app, std::vector<std::string> args);

// "x,y,z" -> vector; InputError naming the option on bad text.
std::vector<double> ParseNumbers(const std::string& text, size_t count, const std::string& option);

}  // namespace furnihost::app
