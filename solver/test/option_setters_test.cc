#include "npfkct/solver/option_setters.h"

#include <gtest/gtest.h>

#include <cmath>

namespace npfkct {
namespace {

TEST(OptionSettersTest, SetsNestedAndBareKeys) {
  KctOptions o;
  ASSERT_TRUE(SetOption(&o, "k", 4).ok());
  ASSERT_TRUE(SetOption(&o, "search.max_depth", 12).ok());
  ASSERT_TRUE(SetOption(&o, "num_particles", 300).ok());  // bare leaf of search.num_particles
  ASSERT_TRUE(SetOptionFromString(&o, "observations.enabled=false").ok());
  ASSERT_TRUE(SetOptionFromString(&o, "backup=1").ok());
  ASSERT_TRUE(SetOptionFromString(&o, "final_choice=2").ok());
  ASSERT_TRUE(SetOptionFromString(&o, "final_lcb=1.5").ok());
  EXPECT_FALSE(SetOptionFromString(&o, "final_choice=3").ok());
  EXPECT_EQ(o.k, 4);
  EXPECT_EQ(o.search.max_depth, 12);
  EXPECT_EQ(o.search.num_particles, 300);
  EXPECT_FALSE(o.observations.enabled);
  EXPECT_EQ(o.backup, KctOptions::Backup::kBellman);
  EXPECT_EQ(o.final_choice, KctOptions::FinalChoice::kLowerBound);
  EXPECT_EQ(o.final_lcb, 1.5);
}

TEST(OptionSettersTest, RejectsUnknownKeysAndBadValues) {
  PomcpowOptions o;
  Status s = SetOption(&o, "k_actoin", 3);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("k_actoin"), std::string::npos);
  s = SetOption(&o, "search.max_depth", 2.5);
  EXPECT_NE(s.message().find("search.max_depth: not an integer"), std::string::npos);
  s = SetOption(&o, "k_action", std::nan(""));
  EXPECT_NE(s.message().find("k_action"), std::string::npos);
  s = SetOption(&o, "use_voo", 2);
  EXPECT_NE(s.message().find("not a boolean"), std::string::npos);
  s = SetOptionFromString(&o, "k_action=abc");
  EXPECT_NE(s.message().find("not a number"), std::string::npos);
  s = SetOptionFromString(&o, "k_action");
  EXPECT_NE(s.message().find("not key=value"), std::string::npos);
  // 'k' alone is ambiguous for POMCPOW? No: only observations.k ends with ".k".
  EXPECT_TRUE(SetOption(&o, "k", 3).ok());
  EXPECT_EQ(o.observations.k, 3);
}

TEST(OptionSettersTest, ListsEveryKey) {
  const auto names = OptionNames(static_cast<const AdvtOptions*>(nullptr));
  EXPECT_NE(std::find(names.begin(), names.end(), "split_coefficient"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "search.num_particles"), names.end());
  PomcpOptions p;
  for (const auto& name : OptionNames(&p)) {
    if (name == "exploration_c") continue;
    EXPECT_TRUE(SetOption(&p, name, 1).ok()) << name;
  }
}

TEST(OptionSettersTest, SetsDespotOptionsByName) {
  DespotOptions o;
  EXPECT_TRUE(SetOptionFromString(&o, "num_scenarios=50").ok());
  EXPECT_TRUE(SetOptionFromString(&o, "pruning_constant=0.1").ok());
  EXPECT_TRUE(SetOptionFromString(&o, "search.max_depth=40").ok());
  EXPECT_EQ(o.num_scenarios, 50);
  EXPECT_EQ(o.pruning_constant, 0.1);
  EXPECT_EQ(o.search.max_depth, 40);
  const Status bad = SetOptionFromString(&o, "scenarios=5");
  EXPECT_EQ(bad.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.message().find("scenarios"), std::string::npos);
  const auto names = OptionNames(&o);
  EXPECT_NE(std::find(names.begin(), names.end(), "xi"), names.end());
}

}  // namespace
}  // namespace npfkct
