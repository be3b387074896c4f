#include "npfkct/object_search/planner_registry.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "npfkct/object_search/discrete.h"
#include "npfkct/object_search/policies.h"
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

using Made = StatusOr<std::unique_ptr<SearchPlanner>>;

// Sorted by key, as OptionValues lists them.
OptionList Sorted(OptionList list) {
  std::sort(list.begin(), list.end());
  return list;
}

// ---- kCT (npfkct, kct) ----

KctOptions KctDefaults() {
  KctOptions o;  // paper defaults: k = 3, w1 = sqrt 2, w1_bar 0.6, w2_bar 0.3
  // The paper's tree: spheres whose draws share a subtree, D_lim = 0.2. The library's point
  // children (docs/experiments.md, "Flat points") were measured on VDP Tag, not on the scenes.
  o.point_children = false;
  o.d_lim = 0.2;
  o.search.max_depth = kMaxDepth;
  o.search.num_particles = kParticles;
  o.observations.enabled = false;
  o.max_feasibility_tries = kFeasibilityTries;
  return o;
}

// The aimed proposals' options as kct (and npfkct without a filter) lists them.
OptionList ProposalValues(bool aimed, const ProposalOptions& p) {
  return {{"proposals.aimed", aimed ? 1.0 : 0.0},
          {"proposals.object_share", p.object_share},
          {"proposals.target_share", p.target_share}};
}

OptionList KctDefaultList(const SearchParams&) {
  OptionList list = OptionValues(KctDefaults());
  for (auto& kv : ProposalValues(true, ProposalOptions{})) list.push_back(kv);
  return Sorted(std::move(list));
}

// proposals.* choose the candidates of kct (and of npfkct without a filter): aimed at what is
// left to see (default) or uniform (proposals.aimed = 0, the paper's candidates). A planner that
// takes the filter's sampler draws its own (filter.target_share, filter.object_share): there they
// would be options given and not used, so they are refused.
Made MakeKct(const std::string& name, bool takes_sampler, const PlannerArgs& args) {
  KctOptions o = KctDefaults();
  const bool filtered = takes_sampler && args.sampler != nullptr;
  ProposalOptions proposals;
  bool aimed = true;
  OptionList rest;
  for (const auto& [key, value] : args.options) {
    if (filtered && key.rfind("proposals.", 0) == 0) {
      return InvalidArgumentError("option " + key + ": " + name +
                                  "'s candidates come from its filter (filter.* options); "
                                  "proposals.* apply to kct and to " +
                                  name + " without a model");
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
  if (Status s = ApplyOptions(&o, rest); !s.ok()) return s;
  std::shared_ptr<CandidateSampler<State>> sampler = args.sampler;
  OptionList used = OptionValues(o);
  if (filtered) {
    for (const auto& [key, value] : sampler->Settings()) used.emplace_back("filter." + key, value);
  } else {
    for (auto& kv : ProposalValues(aimed, proposals)) used.push_back(kv);
    sampler = aimed ? std::make_shared<AimedCandidateSampler>(*args.model, proposals) : nullptr;
  }
  return std::unique_ptr<SearchPlanner>(new HybridSearchPlanner<KCenterTree<ObjectSearchModel>>(
      name, *args.model, o, Sorted(std::move(used)), sampler));
}

// ---- POMCP on the manual discrete sets (pomcp, gpomcp, pomcp-joint) ----

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
        reuse_(options.search.reuse_tree),
        used_(OptionValues(options)) {}

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
  OptionList OptionsUsed() const override { return used_; }

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
  OptionList used_;
  int last_action_ = -1;
  HybridAction last_hybrid_;
};

PomcpOptions DiscreteDefaults(bool reuse) {
  PomcpOptions o;  // c = reward range, as in the paper's POMCP
  o.search.max_depth = kMaxDepth;
  o.search.num_particles = kParticles;
  o.search.reuse_tree = reuse;
  return o;
}

PlannerEntry DiscreteEntry(std::string name, std::string summary, DiscreteActionSet set,
                           bool guessed_target, bool reuse) {
  PlannerEntry e;
  e.name = name;
  e.summary = std::move(summary);
  e.defaults = [reuse](const SearchParams&) { return OptionValues(DiscreteDefaults(reuse)); };
  e.make = [name, set, guessed_target, reuse](const PlannerArgs& args) -> Made {
    PomcpOptions o = DiscreteDefaults(reuse);
    if (Status s = ApplyOptions(&o, args.options); !s.ok()) return s;
    return std::unique_ptr<SearchPlanner>(
        new DiscretePlanner(name, *args.model, set, guessed_target, o));
  };
  return e;
}

// ---- POMCPOW, VOMCPOW, ADVT-style ----

PomcpowOptions PomcpowDefaults(bool voo) {
  PomcpowOptions o;  // POMCPOW.jl defaults for the widening constants
  o.search.max_depth = kMaxDepth;
  o.search.num_particles = kParticles;
  o.search.reuse_tree = false;
  o.use_voo = voo;
  o.voo.proposal_stddev = 0.3;
  o.feasibility_tries = kFeasibilityTries;
  return o;
}

PlannerEntry PomcpowEntry(std::string name, std::string summary, bool voo) {
  PlannerEntry e;
  e.name = name;
  e.summary = std::move(summary);
  e.defaults = [voo](const SearchParams&) { return OptionValues(PomcpowDefaults(voo)); };
  e.make = [name, voo](const PlannerArgs& args) -> Made {
    PomcpowOptions o = PomcpowDefaults(voo);
    if (Status s = ApplyOptions(&o, args.options); !s.ok()) return s;
    return std::unique_ptr<SearchPlanner>(
        new HybridSearchPlanner<Pomcpow<ObjectSearchModel>>(name, *args.model, o, OptionValues(o)));
  };
  return e;
}

AdvtOptions AdvtDefaults(const SearchParams& params) {
  AdvtOptions o;
  o.search.max_depth = kMaxDepth;
  o.search.num_particles = kParticles;
  o.search.reuse_tree = false;
  o.observations.enabled = false;
  o.diameter_coefficient = 0.1 * (params.r_max - params.r_ill);  // a tenth of the reward range
  o.feasibility_tries = kFeasibilityTries;
  return o;
}

Made NeedsTruth(const PlannerArgs&, const std::string& name) {
  return InvalidArgumentError("planner '" + name +
                              "' must be told the true world; only npfkct-bench can run it");
}

PlannerEntry OracleEntry(std::string name, std::string summary) {
  PlannerEntry e;
  e.name = name;
  e.summary = std::move(summary);
  e.needs_truth = true;
  e.defaults = [](const SearchParams&) { return OptionList{}; };
  e.make = [name](const PlannerArgs& args) { return NeedsTruth(args, name); };
  return e;
}

PlannerRegistry MakeBuiltIn() {
  PlannerRegistry r;
  auto add = [&r](PlannerEntry e) {
    Status s = r.Add(std::move(e));
    (void)s;  // the built-in names are distinct and well-formed (a unit test checks)
  };
  add({"npfkct",
       "NPF-kCT: the k-center clustering tree over candidates from Net_sam (the neural filter); "
       "uniform candidates when no filter is loaded",
       /*takes_sampler=*/true, /*needs_truth=*/false, KctDefaultList,
       [](const PlannerArgs& args) { return MakeKct("npfkct", true, args); }});
  add({"kct",
       "NPF-kCT's clustering tree without the neural filter: candidates aimed at what is left to "
       "see (proposals.aimed = 0: uniform, as in the paper)",
       false, false, KctDefaultList,
       [](const PlannerArgs& args) { return MakeKct("kct", false, args); }});
  add(DiscreteEntry("pomcp",
                    "POMCP (Silver & Veness 2010) on the paper's manual set: separate base (4 "
                    "poses), lift (3) and head (9) actions; no guessed target, no tree reuse",
                    DiscreteActionSet::kPrimitive, /*guessed_target=*/false, /*reuse=*/false));
  add(DiscreteEntry("gpomcp",
                    "GPOMCP (Chen & Kurniawati 2023): the paper's manual set with the guessed "
                    "target and belief-tree reuse",
                    DiscreteActionSet::kPrimitive, /*guessed_target=*/true, /*reuse=*/true));
  add(DiscreteEntry("pomcp-joint",
                    "POMCP with the guessed target on the 108 joint pose x lift x head "
                    "configurations (stronger than the paper's baseline)",
                    DiscreteActionSet::kJoint, /*guessed_target=*/true, /*reuse=*/false));
  add(PomcpowEntry("pomcpow",
                   "POMCPOW (Sunberg & Kochenderfer 2018): action and observation progressive "
                   "widening, new actions drawn from feasible configurations",
                   /*voo=*/false));
  add(PomcpowEntry("vomcpow",
                   "VOMCPOW (Lim, Tomlin & Sunberg 2021): POMCPOW with Voronoi optimistic "
                   "sampling of feasible new actions",
                   /*voo=*/true));
  add({"advt",
       "ADVT-style Voronoi-tree planner (Hoerger et al. 2022), cells represented by feasible "
       "configurations",
       false, false, [](const SearchParams& p) { return OptionValues(AdvtDefaults(p)); },
       [](const PlannerArgs& args) -> Made {
         AdvtOptions o = AdvtDefaults(args.model->world().params);
         if (Status s = ApplyOptions(&o, args.options); !s.ok()) return s;
         return std::unique_ptr<SearchPlanner>(new HybridSearchPlanner<Advt<ObjectSearchModel>>(
             "advt", *args.model, o, OptionValues(o)));
       }});
  add({"nbv",
       "A greedy next-best view over the same belief, no search tree: remove what was declared, "
       "declare the target once confirmed, else the view that sees the most of the target or "
       "clearing the movable object with the most of its mass inside (the reference every "
       "search must beat)",
       false, false,
       [](const SearchParams&) {
         return option_table::Values(NextBestViewTable(), NextBestViewOptions{});
       },
       [](const PlannerArgs& args) -> Made {
         NextBestViewOptions o;
         if (Status s = ApplyOptions(&o, args.options); !s.ok()) return s;
         return std::unique_ptr<SearchPlanner>(new NextBestView(*args.model, o));
       }});
  add({"rollout",
       "The model's rollout policy executed with no search: a legal declare or remove when the "
       "odds allow it, else a view aimed at a placement of the target, else a random one",
       false, false, [](const SearchParams&) { return OptionList{}; },
       [](const PlannerArgs& args) -> Made {
         if (!args.options.empty()) {
           return InvalidArgumentError("option " + args.options[0].first +
                                       ": the rollout policy takes no options");
         }
         return std::unique_ptr<SearchPlanner>(new RolloutPolicy(*args.model));
       }});
  add(OracleEntry("oracle",
                  "Told the true world: plans the shortest legal action sequence (the ceiling; "
                  "benchmark only)"));
  add(OracleEntry("oracle-cover-unknown",
                  "The oracle not told which object covers the target: when nothing more of the "
                  "target can be seen it clears the movable object of the largest footprint (a "
                  "ceiling told the layout, not the target's box; benchmark only)"));
  return r;
}

}  // namespace

bool IsPlannerName(std::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-';
  });
}

const PlannerRegistry& PlannerRegistry::BuiltIn() {
  static const auto* registry = new PlannerRegistry(MakeBuiltIn());
  return *registry;
}

Status PlannerRegistry::Add(PlannerEntry entry) {
  if (!IsPlannerName(entry.name)) {
    return InvalidArgumentError("planner name '" + entry.name +
                                "': 1-64 lower-case letters, digits and '-'");
  }
  if (Find(entry.name) != nullptr) {
    return InvalidArgumentError("planner '" + entry.name + "' is registered already");
  }
  if (!entry.make || !entry.defaults) {
    return InvalidArgumentError("planner '" + entry.name + "': an entry needs make and defaults");
  }
  entries_.push_back(std::move(entry));
  return OkStatus();
}

Status PlannerRegistry::SetFactory(
    std::string_view name,
    std::function<StatusOr<std::unique_ptr<SearchPlanner>>(const PlannerArgs&)> make) {
  for (PlannerEntry& e : entries_) {
    if (e.name == name) {
      e.make = std::move(make);
      return OkStatus();
    }
  }
  return NotFoundError("no planner '" + std::string(name) + "'");
}

const PlannerEntry* PlannerRegistry::Find(std::string_view name) const {
  for (const PlannerEntry& e : entries_) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

std::vector<std::string> PlannerRegistry::Names(bool servable_only) const {
  std::vector<std::string> names;
  for (const PlannerEntry& e : entries_) {
    if (!servable_only || !e.needs_truth) names.push_back(e.name);
  }
  return names;
}

Made PlannerRegistry::Make(std::string_view name, const PlannerArgs& args) const {
  const PlannerEntry* entry = Find(name);
  if (entry == nullptr) {
    std::string known;
    for (const auto& n : Names()) known += (known.empty() ? "" : ", ") + n;
    return InvalidArgumentError("unknown planner '" + std::string(name) + "' (expected one of " +
                                known + ")");
  }
  if (entry->needs_truth && args.truth == nullptr) return NeedsTruth(args, entry->name);
  if (args.model == nullptr) return InvalidArgumentError("planner '" + entry->name + "': no model");
  return entry->make(args);
}

}  // namespace npfkct::object_search
