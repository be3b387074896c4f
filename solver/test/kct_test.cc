#include "npfkct/solver/kct.h"

#include <gtest/gtest.h>

#include <limits>
#include <thread>

#include "npfkct/solver/models/vdp_tag.h"
#include "test_models.h"

namespace npfkct {
namespace {

using models::VdpTag;
using testing::PeakSearch;

KctOptions PeakOptions() {
  KctOptions o;
  o.observations.enabled = false;
  o.search.max_depth = 4;
  o.d_lim = 0.05;
  o.c_r = 0.5;
  o.w2 = 0.5;
  o.num_candidates = 64;
  return o;
}

TEST(KctOptionsTest, ValidateNamesTheOption) {
  KctOptions o;
  o.k = 1;
  EXPECT_NE(o.Validate().message().find("k must be >= 2"), std::string::npos);
  o = {};
  o.d_lim = 0.0;
  EXPECT_NE(o.Validate().message().find("d_lim"), std::string::npos);
  o = {};
  o.c_r = -1.0;
  EXPECT_NE(o.Validate().message().find("c_r"), std::string::npos);
  o = {};
  o.w1_bar = 0.2;  // below w2_bar
  EXPECT_NE(o.Validate().message().find("w1_bar"), std::string::npos);
  o = {};
  o.search.num_particles = 0;
  EXPECT_NE(o.Validate().message().find("search.num_particles"), std::string::npos);
  o = {};
  o.value_scale = 0.0;
  EXPECT_NE(o.Validate().message().find("value_scale"), std::string::npos);
  o = {};
  o.regression_reach = 0.0;
  EXPECT_NE(o.Validate().message().find("regression_reach"), std::string::npos);
  o = {};
  o.regression_trust = -1.0;
  EXPECT_NE(o.Validate().message().find("regression_trust"), std::string::npos);
  o = {};
  o.regression_min_r2 = 1.5;
  EXPECT_NE(o.Validate().message().find("regression_min_r2"), std::string::npos);
  o = {};
  o.final_lcb = -1.0;
  EXPECT_NE(o.Validate().message().find("final_lcb"), std::string::npos);
  o.final_lcb = 101.0;
  EXPECT_NE(o.Validate().message().find("final_lcb"), std::string::npos);
  o.final_lcb = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(o.Validate().message().find("final_lcb"), std::string::npos);
  o = {};
  o.point_k = 0.0;
  EXPECT_NE(o.Validate().message().find("point_k"), std::string::npos);
  o = {};
  o.point_alpha = 1.5;
  EXPECT_NE(o.Validate().message().find("point_alpha"), std::string::npos);
}

TEST(KctTest, FLimClampsToTheRefinementRate) {
  KctOptions o;  // w1_bar 0.6, w2_bar 0.3
  o.d_lim = 0.2;
  EXPECT_DOUBLE_EQ(FLim(0.9, 1.0, o), 0.6);
  EXPECT_DOUBLE_EQ(FLim(0.45, 1.0, o), 0.45);
  EXPECT_DOUBLE_EQ(FLim(0.1, 1.0, o), 0.3);
  EXPECT_DOUBLE_EQ(FLim(0.1, 0.5, o), 0.2);  // 0.15 is below d_lim
}

TEST(KctTest, RefinesTowardsThePeakAndKeepsStatisticsConsistent) {
  PeakSearch model;
  Rng rng(1);
  KctOptions o = PeakOptions();
  o.point_children = false;  // the paper's tree: refinement copies the subtree
  KCenterTree<PeakSearch> planner(model, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20000), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  EXPECT_GT(d.stats.refinements, 5);
  ASSERT_EQ(d.action.kind, 0);
  EXPECT_LT((d.action.x - model.Peak(0)).norm(), 0.15);
  EXPECT_GT(d.value, 0.8);
  // The executed action lies in the chosen sphere.
  const Hypersphere h = planner.last_sphere();
  EXPECT_LE((d.action.x - h.center).norm(), h.range + 1e-12);
  Status invariants = planner.CheckInvariants();
  EXPECT_TRUE(invariants.ok()) << invariants.ToString();
  int64_t visits = 0;
  for (const auto& r : d.root) visits += r.visits;
  EXPECT_EQ(visits, planner.RootVisits());
}

TEST(KctTest, BellmanBackupAlsoFindsThePeak) {
  PeakSearch model;
  Rng rng(2);
  KctOptions o = PeakOptions();
  o.backup = KctOptions::Backup::kBellman;
  KCenterTree<PeakSearch> planner(model, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20000), rng);
  ASSERT_TRUE(d.status.ok());
  ASSERT_EQ(d.action.kind, 0);
  EXPECT_LT((d.action.x - model.Peak(0)).norm(), 0.15);
  EXPECT_TRUE(planner.CheckInvariants().ok());
}

TEST(KctTest, LowerBoundFinalChoiceWeighsTheSpreadOfTheReturns) {
  // A probe at the likelier peak earns about 0.9 in expectation but 0 or 1 by the hidden state;
  // stopping earns 0.2 every time. The lower bound with one standard error still probes the peak;
  // with a hundred it prefers the sure 0.2, which the highest Qhat never does.
  PeakSearch model;
  auto run = [&](KctOptions::FinalChoice choice, double lcb) {
    Rng rng(4);
    KctOptions o = PeakOptions();
    o.point_children = false;  // the final choice among spheres is the paper's tree's
    o.final_choice = choice;
    o.final_lcb = lcb;
    KCenterTree<PeakSearch> planner(model, o);
    planner.Reset(rng);
    auto d = planner.Plan(Budget::Simulations(2000), rng);
    EXPECT_TRUE(d.status.ok()) << d.status.ToString();
    EXPECT_TRUE(planner.CheckInvariants().ok());
    return d;
  };
  auto max_value = run(KctOptions::FinalChoice::kMaxValue, 1.0);
  auto one = run(KctOptions::FinalChoice::kLowerBound, 1.0);
  auto hundred = run(KctOptions::FinalChoice::kLowerBound, 100.0);
  ASSERT_EQ(max_value.action.kind, 0);
  ASSERT_EQ(one.action.kind, 0);
  EXPECT_LT((one.action.x - model.Peak(0)).norm(), 0.15);
  EXPECT_EQ(hundred.action.kind, 1);
}

TEST(KctTest, ExecutedActionsPassTheReasonabilityCheck) {
  // The best probe is at (0.95, 0.05), inside the infeasible corner x > 0.9, y < 0.1.
  PeakSearch model(1.0, MakeActionVec({0.95, 0.05}));
  Rng rng(3);
  KCenterTree<PeakSearch> planner(model, PeakOptions());
  for (int trial = 0; trial < 5; ++trial) {
    planner.Reset(rng);
    auto d = planner.Plan(Budget::Simulations(5000), rng);
    ASSERT_TRUE(d.status.ok());
    EXPECT_TRUE(model.IsFeasible(0, d.action)) << d.action.ToString();
  }
}

TEST(KctTest, DeterministicUnderAFixedSeed) {
  PeakSearch model;
  auto run = [&](uint64_t seed) {
    Rng rng(seed);
    KCenterTree<PeakSearch> planner(model, PeakOptions());
    planner.Reset(rng);
    return planner.Plan(Budget::Simulations(4000), rng);
  };
  auto a = run(5), b = run(5);
  EXPECT_EQ(a.action, b.action);
  EXPECT_EQ(a.value, b.value);
  EXPECT_EQ(a.stats.refinements, b.stats.refinements);
  ASSERT_EQ(a.root.size(), b.root.size());
  for (size_t i = 0; i < a.root.size(); ++i) EXPECT_EQ(a.root[i].visits, b.root[i].visits);
}

TEST(KctTest, TreeReuseKeepsTheSubtreeAndAddsNewSpheres) {
  PeakSearch model;
  Rng rng(6);
  KCenterTree<PeakSearch> planner(model, PeakOptions());
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(8000), rng);
  ASSERT_TRUE(d.status.ok());
  Rng sim(7);
  auto step = model.Step(0, d.action, sim);
  planner.Advance(d.action, step.observation, rng);
  const int64_t kept = planner.RootVisits();
  EXPECT_GT(kept, 100);
  EXPECT_TRUE(planner.CheckInvariants().ok());
  const size_t list_before = planner.RootList().size();
  auto d2 = planner.Plan(Budget::Simulations(1000), rng);
  ASSERT_TRUE(d2.status.ok());
  EXPECT_EQ(d2.stats.reused_visits, kept);
  EXPECT_EQ(d2.stats.root_visits, kept + 1000);
  size_t new_spheres = 0;
  for (const auto& [kind, list] : planner.spheres()) new_spheres += list.size();
  EXPECT_GE(planner.RootList().size(), list_before + new_spheres);
  EXPECT_TRUE(planner.CheckInvariants().ok());
}

TEST(KctTest, PointChildrenFindThePeakAndRefineTheirSpheresWithoutCopies) {
  PeakSearch model;
  Rng rng(17);
  KctOptions o = PeakOptions();  // point children by default
  o.point_k = 8.0;
  o.point_alpha = 0.25;
  for (int threads : {1, 2}) {
    o.search.threads = threads;
    KCenterTree<PeakSearch> planner(model, o);
    planner.Reset(rng);
    auto d = planner.Plan(Budget::Simulations(20000), rng);
    ASSERT_TRUE(d.status.ok()) << d.status.ToString();
    EXPECT_GT(d.stats.refinements, 3);
    ASSERT_EQ(d.action.kind, 0);
    EXPECT_LT((d.action.x - model.Peak(0)).norm(), 0.15);
    // The spheres' visits and records are their points', through the refinements.
    Status invariants = planner.CheckInvariants();
    EXPECT_TRUE(invariants.ok()) << invariants.ToString();
    // The root list and the decision's statistics (one tree's) hold spheres only.
    int64_t visits = 0;
    for (const auto& r : d.root) visits += r.visits;
    if (threads == 1) {
      EXPECT_EQ(visits, planner.RootVisits());
      EXPECT_EQ(d.root.size(), planner.RootList().size());
    }
    // The executed action is a point the search tried: its subtree is kept.
    Rng sim(18);
    auto step = model.Step(0, d.action, sim);
    planner.Advance(d.action, step.observation, rng);
    if (threads == 1) {
      EXPECT_GT(planner.RootVisits(), 100);
    }
    EXPECT_TRUE(planner.CheckInvariants().ok());
    auto d2 = planner.Plan(Budget::Simulations(1000), rng);
    ASSERT_TRUE(d2.status.ok());
    EXPECT_TRUE(planner.CheckInvariants().ok());
  }
}

// A sampler that proposes only points near one spot, as a trained filter would.
class SpotSampler : public CandidateSampler<int> {
 public:
  explicit SpotSampler(ActionVec spot, bool outside = false) : spot_(spot), outside_(outside) {}
  Status Sample(const ParticleBelief<int>&, int, const BoxSpace& box, int count,
                const TerminationCondition&, Rng& rng, std::vector<ActionVec>* out,
                CandidateStats* stats) override {
    ++calls;
    for (int i = 0; i < count; ++i) {
      out->push_back(outside_ ? MakeActionVec({2.0, 2.0}) : box.SampleInBall(spot_, 0.05, rng));
    }
    stats->sampled += count;
    stats->accepted += count;
    return OkStatus();
  }
  int calls = 0;

 private:
  ActionVec spot_;
  bool outside_;
};

TEST(KctTest, CandidateSamplerShapesTheInitialSpheres) {
  PeakSearch model;
  Rng rng(8);
  auto sampler = std::make_shared<SpotSampler>(MakeActionVec({0.7, 0.3}));
  KCenterTree<PeakSearch> planner(model, PeakOptions(), sampler);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(500), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(sampler->calls, 1);
  EXPECT_EQ(planner.candidate_stats().accepted, 64);
  ASSERT_FALSE(planner.spheres().at(0).empty());
  for (const Hypersphere& h : planner.spheres().at(0)) {
    EXPECT_LT((h.center - MakeActionVec({0.7, 0.3})).norm(), 0.06);
    EXPECT_LE(h.range, 0.11);
  }
  auto bad = std::make_shared<SpotSampler>(MakeActionVec({0.5, 0.5}), /*outside=*/true);
  KCenterTree<PeakSearch> broken(model, PeakOptions(), bad);
  broken.Reset(rng);
  auto e = broken.Plan(Budget::Simulations(10), rng);
  EXPECT_EQ(e.status.code(), StatusCode::kInternal);
  EXPECT_NE(e.status.message().find("outside the action box"), std::string::npos);
}

TEST(KctTest, RootParallelSearchMergesTheTreesAndFindsThePeak) {
  PeakSearch model;
  Rng rng(10);
  KctOptions o = PeakOptions();
  o.search.threads = 2;
  KCenterTree<PeakSearch> planner(model, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20000), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  EXPECT_EQ(d.stats.simulations, 20000);  // shared out between the two trees
  EXPECT_EQ(planner.used().threads, 2);
  ASSERT_EQ(d.action.kind, 0);
  EXPECT_LT((d.action.x - model.Peak(0)).norm(), 0.15);
  EXPECT_EQ(planner.RootVisits(), 20000);
  EXPECT_TRUE(planner.CheckInvariants().ok());
  // Both trees follow the executed step.
  Rng sim(11);
  auto step = model.Step(0, d.action, sim);
  planner.Advance(d.action, step.observation, rng);
  EXPECT_GT(planner.RootVisits(), 0);
  auto d2 = planner.Plan(Budget::Simulations(2000), rng);
  ASSERT_TRUE(d2.status.ok());
  EXPECT_TRUE(planner.CheckInvariants().ok());
  // A cancellation reaches every thread.
  TerminationCondition stop(Budget::Time(30000.0));
  std::thread canceller([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    stop.Terminate();
  });
  auto d3 = planner.Plan(stop, rng);
  canceller.join();
  EXPECT_EQ(d3.status.code(), StatusCode::kCancelled);
  EXPECT_LT(d3.stats.elapsed_ms, 5000.0);
}

// The caller's condition is not read while the worker threads search: its extra condition and
// its resource limit must reach them through their own conditions.
TEST(KctTest, RootParallelSearchPollsTheCallersConditionAndLimit) {
  PeakSearch model;
  Rng rng(12);
  KctOptions o = PeakOptions();
  o.search.threads = 2;
  KCenterTree<PeakSearch> planner(model, o);
  planner.Reset(rng);
  const auto t0 = Clock::now();
  TerminationCondition hung_up(
      Budget::Time(30000.0), [&] { return MillisSince(t0) > 30.0; }, 1.0);
  auto cancelled = planner.Plan(hung_up, rng);
  EXPECT_EQ(cancelled.status.code(), StatusCode::kCancelled);
  EXPECT_LT(cancelled.stats.elapsed_ms, 5000.0);

  planner.Reset(rng);
  const auto t1 = Clock::now();
  TerminationCondition full(Budget::Time(30000.0), {}, 1.0);
  full.StopAtLimit([&] { return MillisSince(t1) > 30.0; });
  auto ended = planner.Plan(full, rng);
  ASSERT_TRUE(ended.status.ok()) << ended.status.ToString();  // an early end, not a cancellation
  EXPECT_TRUE(full.limit_reached());
  EXPECT_FALSE(full.cancelled());
  EXPECT_FALSE(ended.stats.budget_exhausted);
  EXPECT_GT(ended.stats.simulations, 0);
  EXPECT_LT(ended.stats.elapsed_ms, 5000.0);
  EXPECT_TRUE(planner.CheckInvariants().ok());
}

TEST(KctTest, VdpTagWithObservationWideningHonoursTheCpuBudget) {
  VdpTag tag;
  Rng rng(9);
  KctOptions o;
  o.search.max_depth = 10;
  o.search.num_particles = 2000;
  o.observations.k = 5.0;
  o.observations.alpha = 1.0 / 100.0;
  KCenterTree<VdpTag> planner(tag, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Cpu(40.0), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_GE(d.stats.cpu_ms, 40.0);
  EXPECT_LT(d.stats.cpu_ms, 40.0 + 60.0);  // CPU time: a loaded machine does not stretch it
  EXPECT_GT(d.stats.simulations, 100);
  EXPECT_TRUE(planner.CheckInvariants().ok());
}

}  // namespace
}  // namespace npfkct
