// The runners of the stage kinds. Each reads its stage's inputs by slot from the run, calls the
// plugin once per scan (or once for all scans: voters fuse them, fitters fit what they voted),
// times it by stage tag and keeps the output in the run.
#include "runners.hpp"

#include <spdlog/spdlog.h>

#include "furnihost/log.hpp"

namespace furnihost::graph {

void RunSegmenter(const StageConfig& s, StageInstance& instance, Run& run) {
  auto& segmenter = instance.As<Segmenter>(s);
  StageOutput& o = run.Out(s);
  for (const auto& scan : run.scans) {
    Stopwatch one;
    o.segmentations.push_back(CallStage(s, [&] { return segmenter.Segment(scan, run.ctx); }));
    run.Timed(s.tag, one.Ms());
    if (run.log)
      spdlog::info("{}: {} points -> {} parts ({} points discarded)", scan.source, scan.points.size(),
                   o.segmentations.back().parts.size(), o.segmentations.back().discarded_points);
  }
}

void RunProposer(const StageConfig& s, StageInstance& instance, Run& run) {
  auto& proposer = instance.As<Proposer>(s);
  StageOutput& o = run.Out(s);
  for (size_t i = 0; i < run.scans.size(); ++i) {
    Stopwatch one;
    const Segmentation* parts = run.Parts(s, i);
    o.proposals.push_back(CallStage(s, [&] { return proposer.Propose(run.scans[i], parts, run.ctx); }));
    run.Timed(s.tag, one.Ms());
    if (run.log)
      spdlog::info("{}: {} proposals (spacing {:.3f} m)", run.scans[i].source, o.proposals.back().items.size(),
                   o.proposals.back().spacing);
  }
}

void RunFeatures(const StageConfig& s, StageInstance& instance, Run& run) {
  auto& features = instance.As<Features>(s);
  StageOutput& o = run.Out(s);
  for (size_t i = 0; i < run.scans.size(); ++i) {
    Stopwatch one;
    const Segmentation& parts = *run.Parts(s, i);  // a features stage takes a segmenter
    o.features.push_back(CallStage(s, [&] { return features.Compute(run.scans[i], parts, run.ctx); }));
    run.Timed(s.tag, one.Ms());
    if (o.features.back().values.rows() != static_cast<Eigen::Index>(parts.parts.size()))
      throw StageError("stage '" + s.tag + "': returned " + std::to_string(o.features.back().values.rows()) +
                           " rows for " + std::to_string(parts.parts.size()) + " parts",
                       false);
  }
}

namespace {
// A voter's hypothesis as a detection. Without a box of the voter's, the object stands in its
// class's typical catalog box (the median of the class's models) on the ground at the centre.
Detection FromHypothesis(const Hypothesis& h, Run& run, bool* decided) {
  Detection d;
  d.cls = h.cls;
  d.center = h.center;
  d.score = h.score;
  d.support = h.support;
  d.proposal = h.proposal;
  d.proposal_scene = h.scene;
  d.model = h.model;
  d.evidence = h.evidence;
  if (h.model_pose) d.model_pose = *h.model_pose;
  if (h.accepted) {
    d.verified = *h.accepted;
    d.checks = h.checks;
    *decided = true;  // the eval counts accepted detections as verified
  }
  if (h.box) {
    d.box = h.box;
    d.box_source = "voter";
  } else if (run.catalog && !run.scans.empty()) {
    const auto& sizes = run.ClassSizes();
    if (auto it = sizes.find(h.cls); it != sizes.end()) {
      OrientedBox b;
      b.size = it->second;
      const float g = run.scans.front().GroundZ(h.center.x(), h.center.y());
      b.center = Eigen::Vector3f(h.center.x(), h.center.y(), g + 0.5f * b.size.z());
      d.box = b;
      d.box_source = "class_size";
    }
  }
  return d;
}
}  // namespace

void RunVoter(const StageConfig& s, StageInstance& instance, Run& run) {
  if (!run.model) return;  // its inputs computed, nothing to vote with
  const std::string fix = run.graph.model_cache.empty()
                              ? std::string(" (retrain with --retrain)")
                              : " (model " + run.graph.model_cache + "; retrain with --retrain)";
  const TrainedModel& model = *run.model;
  const bool several = run.graph.Trained().size() > 1;
  const TrainedVoter* trained = model.FindVoter(s.tag);
  if (!trained) throw InputError("stage '" + s.tag + "' (" + s.type + "): the model has no model for this voter" + fix);
  const StageConfig* features = run.graph.Input(s, InputRole::Features);
  const StageConfig* proposals = run.graph.Input(s, InputRole::Proposals);
  StageOutput& o = run.Out(s);
  size_t clamped = 0;
  if (features) {
    o.features = run.Of(*features).features;  // normalised by this voter's model
    for (auto& f : o.features) clamped += trained->normaliser.Apply(f);
  }
  run.clamped_features += clamped;
  if (clamped)
    spdlog::info("features{}: {} values outside the training range were clamped",
                 several ? " of voter '" + s.tag + "'" : std::string(), clamped);
  auto& voter = instance.As<Voter>(s);
  const std::string id = model.catalog_hash + model.training_config.dump();
  if (instance.loaded_model != id) {
    // A model its voter cannot load is a corrupt or foreign cache file: bad input (exit 2),
    // whatever the plugin threw, with the way out in the message.
    try {
      CallStage(s, [&] {
        voter.Load(trained->voter_model);
        return 0;
      });
    } catch (const std::exception& e) {
      throw InputError(std::string(e.what()) + fix);
    }
    instance.loaded_model = id;
  }
  for (size_t i = 0; i < run.scans.size(); ++i)
    o.scenes.push_back({&run.scans[i], run.Parts(s, i), features ? &o.features[i] : nullptr,
                        proposals ? &run.Of(*proposals).proposals.at(i) : nullptr});
  Stopwatch sv;
  o.votes = CallStage(s, [&] { return voter.Vote(o.scenes, run.ctx); });
  run.Timed(s.tag, sv.Ms());
  o.ran = true;
  run.voted = true;
  for (const auto& h : o.votes.hypotheses) o.detections.push_back(FromHypothesis(h, run, &o.decided));
}

void RunFitter(const StageConfig& s, StageInstance& instance, Run& run) {
  // Fitters verify against the catalog; without one the chain stops at what ran before.
  const StageOutput& in = run.Of(*run.graph.Input(s, InputRole::Detections));
  if (!run.catalog || !in.ran) return;
  // The scenes its chain's voter voted with; a proposer among its inputs gives the proposals.
  const StageConfig* root = run.graph.ChainRoot(s);
  const StageConfig* proposals = run.graph.Input(s, InputRole::Proposals);
  const std::string key = root->tag + (proposals ? "/" + proposals->tag : std::string());
  auto fc = run.fit_contexts.find(key);
  if (fc == run.fit_contexts.end()) {
    FitContext c;
    c.scenes = run.Of(*root).scenes;
    for (size_t i = 0; i < c.scenes.size(); ++i) {
      c.scenes[i].segmentation = run.Parts(s, i);
      if (proposals) c.scenes[i].proposals = &run.Of(*proposals).proposals.at(i);
    }
    for (const auto& m : run.catalog->models) c.catalog.push_back(&m);
    c.run = run.ctx;
    fc = run.fit_contexts.emplace(key, std::move(c)).first;
  }
  auto& fitter = instance.As<Fitter>(s);
  StageOutput& o = run.Out(s);
  Stopwatch sf;
  o.detections = CallStage(s, [&] { return fitter.Fit(in.detections, fc->second); });
  run.Timed(s.tag, sf.Ms());
  o.ran = o.decided = true;
}

}  // namespace furnihost::graph
