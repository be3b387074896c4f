#include "npfkct/solver/object_search/search_planner.h"

#include <cmath>

#include "npfkct/solver/advt.h"
#include "npfkct/solver/kct.h"
#include "npfkct/solver/option_setters.h"
#include "npfkct/solver/pomcp.h"
#include "npfkct/solver/pomcpow.h"

namespace npfkct::object_search {
namespace {

// Shared defaults of the object-search experiments (appendix J; 1 s per step).
constexpr int kMaxDepth = 12;
constexpr int kParticles = 300;

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
      : name_(std::move(name)), planner_(model, options), reuse_(options.search.reuse_tree) {}
  HybridPlanner(std::string name, const ObjectSearchModel& model, Options options,
                std::shared_ptr<CandidateSampler<State>> sampler)
      : name_(std::move(name)),
        planner_(model, options, std::move(sampler)),
        reuse_(options.search.reuse_tree) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override { planner_.SetBelief(std::move(belief)); }
  Decision<HybridAction> Plan(const Budget& budget, Rng& rng) override {
    return planner_.Plan(budget, rng);
  }
  void AdvanceTo(const HybridAction& a, const Observation& o,
                 ParticleBelief<State> belief) override {
    planner_.AdvanceTo(a, o, std::move(belief));
  }
  int64_t TreeSize() const override { return planner_.TreeSize(); }
  bool ReusesTree() const override { return reuse_; }
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
};

// POMCP / GPOMCP over the manual discrete action set.
class DiscretePlanner final : public SearchPlanner {
 public:
  DiscretePlanner(std::string name, const ObjectSearchModel& model, PomcpOptions options)
      : name_(std::move(name)),
        discrete_(model),
        planner_(discrete_, options),
        reuse_(options.search.reuse_tree) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override { planner_.SetBelief(std::move(belief)); }
  Decision<HybridAction> Plan(const Budget& budget, Rng& rng) override {
    Decision<int> d = planner_.Plan(budget, rng);
    Decision<HybridAction> out;
    out.status = d.status;
    out.value = d.value;
    out.stats = d.stats;
    if (d.status.ok()) out.action = discrete_.ToHybrid(d.action);
    for (const auto& r : d.root)
      out.root.push_back({discrete_.ToHybrid(r.action), r.visits, r.value});
    return out;
  }
  void AdvanceTo(const HybridAction& a, const Observation& o,
                 ParticleBelief<State> belief) override {
    int index = -1;
    if (a.kind == kMoveKind) {
      for (int m = 0; m < discrete_.num_configs(); ++m) {
        if (discrete_.ToHybrid(m) == a) index = m;
      }
    } else {
      index = discrete_.FromKind(a.kind);
    }
    if (index < 0) {
      planner_.SetBelief(std::move(belief));
    } else {
      planner_.AdvanceTo(index, o, std::move(belief));
    }
  }
  void OnWorldChanged() override { discrete_.Refresh(); }
  int64_t TreeSize() const override { return planner_.TreeSize(); }
  bool ReusesTree() const override { return reuse_; }

 private:
  std::string name_;
  DiscreteObjectSearch discrete_;
  Pomcp<DiscreteObjectSearch> planner_;
  bool reuse_;
};

}  // namespace

const std::vector<std::string>& SearchPlannerNames() {
  static const std::vector<std::string> names = {"npfkct",  "kct",     "pomcp", "gpomcp",
                                                 "pomcpow", "vomcpow", "advt"};
  return names;
}

StatusOr<std::unique_ptr<SearchPlanner>> MakeSearchPlanner(
    const std::string& name, const ObjectSearchModel& model,
    const std::vector<std::pair<std::string, double>>& options,
    std::shared_ptr<CandidateSampler<State>> sampler) {
  const double range = model.MaxReward() - model.MinReward();
  if (name == "npfkct" || name == "kct") {
    KctOptions o;  // paper defaults: k = 3, w1 = sqrt 2, D_lim = 0.2, w1_bar 0.6, w2_bar 0.3
    o.search.max_depth = kMaxDepth;
    o.search.num_particles = kParticles;
    o.observations.enabled = false;
    if (Status s = ApplyAll(&o, options); !s.ok()) return s;
    if (name == "kct") sampler = nullptr;
    return std::unique_ptr<SearchPlanner>(
        new HybridPlanner<KCenterTree<ObjectSearchModel>, KctOptions>(name, model, o, sampler));
  }
  if (name == "pomcp" || name == "gpomcp") {
    PomcpOptions o;  // c = reward range; GPOMCP adds belief-tree reuse
    o.search.max_depth = kMaxDepth;
    o.search.num_particles = kParticles;
    o.search.reuse_tree = name == "gpomcp";
    if (Status s = ApplyAll(&o, options); !s.ok()) return s;
    return std::unique_ptr<SearchPlanner>(new DiscretePlanner(name, model, o));
  }
  if (name == "pomcpow" || name == "vomcpow") {
    PomcpowOptions o;  // POMCPOW.jl defaults for the widening constants
    o.search.max_depth = kMaxDepth;
    o.search.num_particles = kParticles;
    o.search.reuse_tree = false;
    o.use_voo = name == "vomcpow";
    o.voo.proposal_stddev = 0.3;
    if (Status s = ApplyAll(&o, options); !s.ok()) return s;
    return std::unique_ptr<SearchPlanner>(
        new HybridPlanner<Pomcpow<ObjectSearchModel>, PomcpowOptions>(name, model, o));
  }
  if (name == "advt") {
    AdvtOptions o;
    o.search.max_depth = kMaxDepth;
    o.search.num_particles = kParticles;
    o.search.reuse_tree = false;
    o.observations.enabled = false;
    o.diameter_coefficient = 0.1 * range;
    if (Status s = ApplyAll(&o, options); !s.ok()) return s;
    return std::unique_ptr<SearchPlanner>(
        new HybridPlanner<Advt<ObjectSearchModel>, AdvtOptions>(name, model, o));
  }
  std::string known;
  for (const auto& n : SearchPlannerNames()) known += (known.empty() ? "" : ", ") + n;
  return InvalidArgumentError("unknown planner '" + name + "' (expected one of " + known + ")");
}

}  // namespace npfkct::object_search
