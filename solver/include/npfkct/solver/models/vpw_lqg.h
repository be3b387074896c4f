// The planner settings of the VPW paper's LQG comparison (Lim, Tomlin & Sunberg 2021;
// VOOTreeSearch.jl scripts/LQG/action_compare.jl), for the benchmark and its test.
#pragma once

#include <cmath>

#include "npfkct/solver/pomcpow.h"

namespace npfkct::models {

/// POMCPOW's tuned constants on the VPW paper's LQG, or VOMCPOW's with `voo`: UCB constant,
/// action and observation widening, Voronoi sampling, depth 3, RolloutFirst; 1,000 particles.
inline PomcpowOptions VpwLqgPomcpowOptions(bool voo) {
  PomcpowOptions o;
  o.exploration_c = 65.0;
  o.k_action = 30.0;
  o.alpha_action = 1.0 / 2.5;
  o.observations.k = 30.0;
  o.observations.alpha = 1.0 / 4.0;
  o.search.max_depth = 3;
  o.search.num_particles = 1000;
  o.search.rollout_first = true;
  if (voo) {
    o.use_voo = true;
    o.exploration_c = 60.0;
    o.k_action = 25.0;
    o.alpha_action = 1.0 / 5.5;
    o.observations.k = 25.0;
    o.observations.alpha = 1.0 / 2.5;
    o.voo.uniform_probability = 0.8;
    o.voo.proposal_stddev = std::sqrt(0.5);  // the script's covariance 0.5 per axis
    o.voo.accept_radius = 0.05;
    o.voo.max_tries = 20;
  }
  return o;
}

}  // namespace npfkct::models
