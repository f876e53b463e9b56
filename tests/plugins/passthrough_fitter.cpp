// A fitter that returns its input unchanged (test plugin: fitter chains, fan-out and cycles).
// With a "note" it appends that note to every detection, so a test can see which fitters a
// detection went through; with "note_proposals" it notes the proposals it was given.
#include "furnihost/plugin.hpp"

class Passthrough : public furnihost::Fitter {
 public:
  static furnihost::ParamSchema Schema() {
    return furnihost::ParamSchema()
        .String("note", "", "appended to every detection's notes (none when empty)")
        .Bool("note_proposals", false, "note \"proposals N\" (the first scene's), or \"proposals none\"");
  }
  explicit Passthrough(const nlohmann::json& p)
      : note_(p.at("note").get<std::string>()), note_proposals_(p.at("note_proposals").get<bool>()) {}
  std::vector<furnihost::Detection> Fit(const std::vector<furnihost::Detection>& in,
                                        const furnihost::FitContext& ctx) override {
    std::vector<furnihost::Detection> out = in;
    const auto* props = ctx.scenes.empty() ? nullptr : ctx.scenes.front().proposals;
    for (auto& d : out) {
      if (!note_.empty()) d.notes.push_back(note_);
      if (note_proposals_)
        d.notes.push_back("proposals " + (props ? std::to_string(props->items.size()) : std::string("none")));
    }
    return out;
  }

 private:
  std::string note_;
  bool note_proposals_;
};

FURNIHOST_PLUGIN(Passthrough, "fitters.passthrough", "0.1.0", "test fitter: returns its input")
