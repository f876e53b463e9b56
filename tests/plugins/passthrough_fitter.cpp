// A fitter that returns its input unchanged (test plugin: fitter chains, fan-out and cycles);
// with a "note" it appends that note to every detection, so a test can see which fitters a
// detection went through.
#include "furnihost/plugin.hpp"

class Passthrough : public furnihost::Fitter {
 public:
  static furnihost::ParamSchema Schema() {
    return furnihost::ParamSchema().String("note", "", "appended to every detection's notes (none when empty)");
  }
  explicit Passthrough(const nlohmann::json& p) : note_(p.at("note").get<std::string>()) {}
  std::vector<furnihost::Detection> Fit(const std::vector<furnihost::Detection>& in,
                                        const furnihost::FitContext&) override {
    std::vector<furnihost::Detection> out = in;
    if (!note_.empty())
      for (auto& d : out) d.notes.push_back(note_);
    return out;
  }

 private:
  std::string note_;
};

FURNIHOST_PLUGIN(Passthrough, "fitters.passthrough", "0.1.0", "test fitter: returns its input")
