#include "furnihost/log.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <mutex>

namespace furnihost {

void SetupLogging(int verbosity) {
  static std::once_flag once;
  std::call_once(once, [] {
    auto logger = spdlog::stderr_color_mt("furnihost");
    logger->set_pattern("[%H:%M:%S.%e] [%^%l%$] %v");
    spdlog::set_default_logger(logger);
  });
  spdlog::set_level(verbosity <= 0 ? spdlog::level::warn
                    : verbosity == 1 ? spdlog::level::info
                    : verbosity == 2 ? spdlog::level::debug
                                     : spdlog::level::trace);
}

struct Progress::Impl {
  std::string label;
  size_t total;
  std::atomic<size_t> done{0};
  std::mutex mu;
  Stopwatch clock;
  bool tty = ::isatty(2) != 0;
  int last_decile = -1;
  bool finished = false;
};

Progress::Progress(std::string label, size_t total) : impl_(new Impl) {
  impl_->label = std::move(label);
  impl_->total = total;
}

Progress::~Progress() {
  Done();
  delete impl_;
}

void Progress::Tick(size_t n) {
  size_t d = impl_->done += n;
  if (spdlog::get_level() > spdlog::level::info) return;
  std::lock_guard<std::mutex> lock(impl_->mu);
  const size_t total = std::max<size_t>(impl_->total, 1);
  if (impl_->tty) {
    const int width = 30;
    int fill = static_cast<int>(width * std::min(d, total) / total);
    std::fprintf(stderr, "\r%s: [%s%s] %zu/%zu %.1f s", impl_->label.c_str(),
                 std::string(fill, '=').c_str(), std::string(width - fill, ' ').c_str(), d,
                 impl_->total, impl_->clock.Ms() / 1000.0);
    std::fflush(stderr);
  } else {
    int decile = static_cast<int>(10 * std::min(d, total) / total);
    if (decile != impl_->last_decile) {
      impl_->last_decile = decile;
      spdlog::info("{}: {}/{} ({:.1f} s)", impl_->label, d, impl_->total, impl_->clock.Ms() / 1000.0);
    }
  }
}

void Progress::Done() {
  std::lock_guard<std::mutex> lock(impl_->mu);
  if (impl_->finished) return;
  impl_->finished = true;
  if (impl_->tty && spdlog::get_level() <= spdlog::level::info) std::fprintf(stderr, "\n");
}

}  // namespace furnihost
