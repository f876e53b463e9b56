// Loads fine but throws from every call: the host must report it with the stage tag and type.
#include <stdexcept>

#include "furnihost/plugin.hpp"

class Throws : public furnihost::Segmenter {
 public:
  static furnihost::ParamSchema Schema() {
    return furnihost::ParamSchema().Bool("throw_in_constructor", false, "throw from the factory");
  }
  explicit Throws(const nlohmann::json& p) {
    if (p.at("throw_in_constructor").get<bool>()) throw std::runtime_error("constructor refuses to work");
  }
  furnihost::Segmentation Segment(const furnihost::Scan&, const furnihost::RunContext&) override {
    throw std::logic_error("segment always throws");
  }
};

FURNIHOST_PLUGIN(Throws, "segmenters.throws", "0.1.0", "test plugin that throws from every call")
