// A fitter that returns its input unchanged (test plugin: fitter chains and cycles).
#include "furnihost/plugin.hpp"

class Passthrough : public furnihost::Fitter {
 public:
  static furnihost::ParamSchema Schema() { return {}; }
  explicit Passthrough(const nlohmann::json&) {}
  std::vector<furnihost::Detection> Fit(const std::vector<furnihost::Detection>& in,
                                        const furnihost::FitContext&) override {
    return in;
  }
};

FURNIHOST_PLUGIN(Passthrough, "fitters.passthrough", "0.1.0", "test fitter: returns its input")
