// Logging (spdlog to stderr) and a progress bar for long work.
#pragma once
#include <spdlog/spdlog.h>

#include <chrono>
#include <string>

#include "furnihost/error.hpp"

namespace furnihost {

FURNIHOST_API void SetupLogging(int verbosity);  // 0 warn, 1 info (default), 2 debug

// A progress line on stderr ("train: [=====>    ] 12/38 views 3.1 s"); redraws only on a
// terminal, logs every 10 % otherwise. Thread-safe Tick().
class FURNIHOST_API Progress {
 public:
  Progress(std::string label, size_t total);
  ~Progress();
  void Tick(size_t n = 1);
  void Done();

 private:
  struct Impl;
  Impl* impl_;
};

// Wall-clock stopwatch in milliseconds.
class Stopwatch {
 public:
  Stopwatch() : t0_(std::chrono::steady_clock::now()) {}
  double Ms() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count();
  }

 private:
  std::chrono::steady_clock::time_point t0_;
};

}  // namespace furnihost
