#include "npfkct/object_search/search_planner.h"

#include <cmath>

#include "npfkct/object_search/proposals.h"
#include "npfkct/solver/advt.h"
#include "npfkct/solver/kct.h"
#include "npfkct/solver/option_setters.h"
#include "npfkct/solver/pomcp.h"
#include "npfkct/solver/pomcpow.h"

namespace npfkct::object_search {
namespace {

// Shared defaults of the object-search experiments (appendix J): the search depth and the root
// belief's particles are the same for every planner.
constexpr int kMaxDepth = 12;
constexpr int kParticles = 300;
// Draws a continuous planner may spend to find a new action that passes the reasonability check
// (the base in a base region and free of the map); kCT's Action_sam uses the same number.
constexpr int kFeasibilityTries = 100;

template <class Options>
Status ApplyAll(Options* o, const std::vector<std::pair<std::string, double>>& options) {
  for (const auto& [key, value] : options) {
    if (Status s = SetOption(o, key, value); !s.ok()) return s;
  }
  return o->Validate();
}

// Planners over the hybrid model.
template <class P, class Options>
class HybridPlanner final : public SearchPlanner {
 public:
  HybridPlanner(std::string name, const ObjectSearchModel& model, Options options)
      : name_(std::move(name)),
        planner_(model, options),
        reuse_(options.search.reuse_tree),
        threads_(options.search.threads) {}
  HybridPlanner(std::string name, const ObjectSearchModel& model, Options options,
                std::shared_ptr<CandidateSampler<State>> sampler)
      : name_(std::move(name)),
        planner_(model, options, std::move(sampler)),
        reuse_(options.search.reuse_tree),
        threads_(options.search.threads) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override { planner_.SetBelief(std::move(belief)); }
  using SearchPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) override {
    return planner_.Plan(stop, rng);
  }
  void AdvanceTo(const HybridAction& a, const Observation& o,
                 ParticleBelief<State> belief) override {
    planner_.AdvanceTo(a, o, std::move(belief));
  }
  void DropTree() override { planner_.DropTree(); }
  int64_t TreeSize() const override { return planner_.TreeSize(); }
  bool ReusesTree() const override { return reuse_; }
  int SearchThreads() const override { return threads_; }
  CandidateStats candidate_stats() const override {
    if constexpr (requires { planner_.candidate_stats(); }) {
      return planner_.candidate_stats();
    } else {
      return {};
    }
  }

 private:
  std::string name_;
  P planner_;
  bool reuse_;
  int threads_;
};

// POMCP-family planners over a manual discrete action set.
class DiscretePlanner final : public SearchPlanner {
 public:
  DiscretePlanner(std::string name, const ObjectSearchModel& model, DiscreteActionSet set,
                  bool guessed_target, PomcpOptions options)
      : name_(std::move(name)),
        model_(model),
        discrete_(model, set),
        planner_(discrete_, options),
        guessed_target_(guessed_target),
        reuse_(options.search.reuse_tree) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override {
    planner_.SetBelief(Prepare(std::move(belief)));
  }
  using SearchPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) override {
    Decision<int> d = planner_.Plan(stop, rng);
    const RobotConfig& at = model_.world().robot_config;
    Decision<HybridAction> out;
    out.status = d.status;
    out.value = d.value;
    out.stats = d.stats;
    if (d.status.ok() || d.status.code() == StatusCode::kCancelled) {
      out.action = discrete_.ToHybrid(d.action, at);
      last_action_ = d.action;
      last_hybrid_ = out.action;
    }
    for (const auto& r : d.root) {
      out.root.push_back({discrete_.ToHybrid(r.action, at), r.visits, r.value});
    }
    return out;
  }
  void AdvanceTo(const HybridAction& a, const Observation& o,
                 ParticleBelief<State> belief) override {
    int index = -1;
    if (last_action_ >= 0 && a == last_hybrid_) {
      index = last_action_;
    } else if (a.kind != kMoveKind) {
      index = discrete_.FromKind(a.kind);
    }
    last_action_ = -1;
    if (index < 0) {
      planner_.SetBelief(Prepare(std::move(belief)));
    } else {
      planner_.AdvanceTo(index, o, Prepare(std::move(belief)));
    }
  }
  void OnWorldChanged() override { discrete_.Refresh(); }
  void DropTree() override { planner_.DropTree(); }
  int64_t TreeSize() const override { return planner_.TreeSize(); }
  bool ReusesTree() const override { return reuse_; }

 private:
  // Without the guessed target (the paper's POMCP), object 0 takes no part in the search: it is
  // marked removed in every particle, so it is neither seen nor declared.
  ParticleBelief<State> Prepare(ParticleBelief<State> belief) const {
    if (guessed_target_) return belief;
    std::vector<State> particles = belief.particles();
    for (State& s : particles) {
      if (!s.objects.empty()) s.objects[0].status = kRemoved;
    }
    return ParticleBelief<State>(std::move(particles), belief.weights());
  }

  std::string name_;
  const ObjectSearchModel& model_;
  DiscreteObjectSearch discrete_;
  Pomcp<DiscreteObjectSearch> planner_;
  bool guessed_target_;
  bool reuse_;
  int last_action_ = -1;
  HybridAction last_hybrid_;
};

StatusOr<std::unique_ptr<SearchPlanner>> MakeDiscrete(
    const std::string& name, const ObjectSearchModel& model, DiscreteActionSet set,
    bool guessed_target, bool reuse, const std::vector<std::pair<std::string, double>>& options) {
  PomcpOptions o;  // c = reward range, as in the paper's POMCP
  o.search.max_depth = kMaxDepth;
  o.search.num_particles = kParticles;
  o.search.reuse_tree = reuse;
  if (Status s = ApplyAll(&o, options); !s.ok()) return s;
  return std::unique_ptr<SearchPlanner>(new DiscretePlanner(name, model, set, guessed_target, o));
}

}  // namespace

const std::vector<PlannerInfo>& SearchPlanners() {
  static const auto* planners = new std::vector<PlannerInfo>{
      {"npfkct",
       "NPF-kCT: the k-center clustering tree over candidates from Net_sam (the neural filter); "
       "uniform candidates when no filter is loaded",
       true, false},
      {"kct",
       "NPF-kCT's clustering tree without the neural filter: candidates aimed at what is left to "
       "see (proposals.aimed = 0: uniform, as in the paper)",
       false, false},
      {"pomcp",
       "POMCP (Silver & Veness 2010) on the paper's manual set: separate base (4 poses), lift (3) "
       "and head (9) actions; no guessed target, no tree reuse",
       false, false},
      {"gpomcp",
       "GPOMCP (Chen & Kurniawati 2023): the paper's manual set with the guessed target and "
       "belief-tree reuse",
       false, false},
      {"pomcp-joint",
       "POMCP with the guessed target on the 108 joint pose x lift x head configurations "
       "(stronger than the paper's baseline)",
       false, false},
      {"pomcpow",
       "POMCPOW (Sunberg & Kochenderfer 2018): action and observation progressive widening, new "
       "actions drawn from feasible configurations",
       false, false},
      {"vomcpow",
       "VOMCPOW (Lim, Tomlin & Sunberg 2021): POMCPOW with Voronoi optimistic sampling of "
       "feasible new actions",
       false, false},
      {"advt",
       "ADVT-style Voronoi-tree planner (Hoerger et al. 2022), cells represented by feasible "
       "configurations",
       false, false},
      {"oracle",
       "Told the true world: plans the shortest legal action sequence (the ceiling; benchmark "
       "only)",
       false, true},
      {"oracle-cover-unknown",
       "The oracle not told which object covers the target: when nothing more of the target can "
       "be seen it clears the movable object of the largest footprint (a ceiling told the "
       "layout, not the target's box; benchmark only)",
       false, true},
  };
  return *planners;
}

std::vector<std::string> SearchPlannerNames() {
  std::vector<std::string> names;
  for (const PlannerInfo& p : SearchPlanners()) names.push_back(p.name);
  return names;
}

const PlannerInfo* FindSearchPlanner(const std::string& name) {
  for (const PlannerInfo& p : SearchPlanners()) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

StatusOr<std::unique_ptr<SearchPlanner>> MakeSearchPlanner(
    const std::string& name, const ObjectSearchModel& model,
    const std::vector<std::pair<std::string, double>>& options,
    std::shared_ptr<CandidateSampler<State>> sampler) {
  const PlannerInfo* info = FindSearchPlanner(name);
  if (info == nullptr) {
    std::string known;
    for (const auto& n : SearchPlannerNames()) known += (known.empty() ? "" : ", ") + n;
    return InvalidArgumentError("unknown planner '" + name + "' (expected one of " + known + ")");
  }
  if (info->needs_truth) {
    return InvalidArgumentError("planner '" + name +
                                "' must be told the true world; only npfkct-bench can run it");
  }
  const double range = model.MaxReward() - model.MinReward();
  if (name == "npfkct" || name == "kct") {
    KctOptions o;  // paper defaults: k = 3, w1 = sqrt 2, D_lim = 0.2, w1_bar 0.6, w2_bar 0.3
    o.search.max_depth = kMaxDepth;
    o.search.num_particles = kParticles;
    o.observations.enabled = false;
    o.max_feasibility_tries = kFeasibilityTries;
    // proposals.* choose the candidates of kct (and of npfkct without a filter): aimed at what is
    // left to see (default) or uniform (proposals.aimed = 0, the paper's candidates). npfkct's
    // filter draws its own (filter.target_share, filter.object_share): there they would be
    // options given and not used, so they are refused.
    const bool filtered = name == "npfkct" && sampler != nullptr;
    ProposalOptions proposals;
    bool aimed = true;
    std::vector<std::pair<std::string, double>> rest;
    for (const auto& [key, value] : options) {
      if (filtered && key.rfind("proposals.", 0) == 0) {
        return InvalidArgumentError("option " + key +
                                    ": npfkct's candidates come from its filter (filter.* "
                                    "options); proposals.* apply to kct and to npfkct without a "
                                    "model");
      }
      if (key == "proposals.aimed") {
        if (value != 0.0 && value != 1.0) {
          return InvalidArgumentError("option proposals.aimed: 0 (uniform) or 1 (aimed)");
        }
        aimed = value != 0.0;
      } else if (key == "proposals.target_share") {
        proposals.target_share = value;
      } else if (key == "proposals.object_share") {
        proposals.object_share = value;
      } else {
        rest.emplace_back(key, value);
      }
    }
    if (Status s = proposals.Validate(); !s.ok()) return Prefixed("option proposals", s);
    if (Status s = ApplyAll(&o, rest); !s.ok()) return s;
    if (!filtered) {
      sampler = aimed ? std::make_shared<AimedCandidateSampler>(model, proposals) : nullptr;
    }
    return std::unique_ptr<SearchPlanner>(
        new HybridPlanner<KCenterTree<ObjectSearchModel>, KctOptions>(name, model, o, sampler));
  }
  if (name == "pomcp") {
    return MakeDiscrete(name, model, DiscreteActionSet::kPrimitive, /*guessed_target=*/false,
                        /*reuse=*/false, options);
  }
  if (name == "gpomcp") {
    return MakeDiscrete(name, model, DiscreteActionSet::kPrimitive, /*guessed_target=*/true,
                        /*reuse=*/true, options);
  }
  if (name == "pomcp-joint") {
    return MakeDiscrete(name, model, DiscreteActionSet::kJoint, /*guessed_target=*/true,
                        /*reuse=*/false, options);
  }
  if (name == "pomcpow" || name == "vomcpow") {
    PomcpowOptions o;  // POMCPOW.jl defaults for the widening constants
    o.search.max_depth = kMaxDepth;
    o.search.num_particles = kParticles;
    o.search.reuse_tree = false;
    o.use_voo = name == "vomcpow";
    o.voo.proposal_stddev = 0.3;
    o.feasibility_tries = kFeasibilityTries;
    if (Status s = ApplyAll(&o, options); !s.ok()) return s;
    return std::unique_ptr<SearchPlanner>(
        new HybridPlanner<Pomcpow<ObjectSearchModel>, PomcpowOptions>(name, model, o));
  }
  // advt
  AdvtOptions o;
  o.search.max_depth = kMaxDepth;
  o.search.num_particles = kParticles;
  o.search.reuse_tree = false;
  o.observations.enabled = false;
  o.diameter_coefficient = 0.1 * range;
  o.feasibility_tries = kFeasibilityTries;
  if (Status s = ApplyAll(&o, options); !s.ok()) return s;
  return std::unique_ptr<SearchPlanner>(
      new HybridPlanner<Advt<ObjectSearchModel>, AdvtOptions>(name, model, o));
}

}  // namespace npfkct::object_search
