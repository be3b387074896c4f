// npfkct-scenegen: writes a procedurally generated scenario file, reproducible from its seed.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include "npfkct/sim/scenegen.h"

int main(int argc, char** argv) {
  uint64_t seed = 1;
  uint64_t count = 1;
  std::string out;
  CLI::App app{
      "npfkct-scenegen: a procedurally generated object-search scenario (1-4 pieces of furniture, "
      "3-40 objects, the target in the open, hidden or covered, Fetch or Stretch), reproducible "
      "from its seed. Seeds above " +
      std::to_string(npfkct::sim::kHeldOutSeedBase) +
      " are the benchmark's held-out scenes; train on seeds below it."};
  app.add_option("--seed", seed, "the scene's seed (default 1)");
  app.add_option("--count", count, "write this many scenes, seeds seed .. seed + count - 1")
      ->check(CLI::Range(1, 100000));
  int version = 1;
  app.add_option("--version", version,
                 "the generator's laws: 1 (the first held-out set) or 2 (decoy covers and wall "
                 "pockets, immovable large boxes, any yaw, clutter near the target, stacked and "
                 "walled covers; seeds " +
                     std::to_string(npfkct::sim::kTuningV2SeedBase + 1) + "-" +
                     std::to_string(npfkct::sim::kTuningV2SeedBase + 30) + " tune, " +
                     std::to_string(npfkct::sim::kHeldOutV2SeedBase + 1) + "-" +
                     std::to_string(npfkct::sim::kHeldOutV2SeedBase + 60) +
                     " are held out, 20 each in the open, hidden and covered)")
      ->check(CLI::Range(1, 2));
  std::string placement;
  app.add_option("--placement", placement, "force the target's placement: open, hidden, covered")
      ->check(CLI::IsMember({"open", "hidden", "covered"}));
  app.add_option("--out", out,
                 "output file (one scene), or directory (gen-SEED.json per scene); default: "
                 "stdout")
      ->check(CLI::NonexistentPath | CLI::ExistingDirectory);
  CLI11_PARSE(app, argc, argv);
  const bool to_dir = !out.empty() && std::filesystem::is_directory(out);
  if (count > 1 && !to_dir) {
    std::cerr << "npfkct-scenegen: --count needs --out DIRECTORY\n";
    return 2;
  }
  for (uint64_t s = seed; s < seed + count; ++s) {
    npfkct::sim::SceneOptions options;
    if (version == 2) options = npfkct::sim::V2Options(s);
    if (!placement.empty()) {
      options.placement = placement == "open"     ? npfkct::sim::TargetPlacement::kOpen
                          : placement == "hidden" ? npfkct::sim::TargetPlacement::kHidden
                                                  : npfkct::sim::TargetPlacement::kCovered;
    }
    const std::string text = npfkct::sim::GenerateScenarioJson(s, nullptr, options);
    if (out.empty()) {
      std::fwrite(text.data(), 1, text.size(), stdout);
      continue;
    }
    const std::string path = to_dir ? out + "/gen-" + std::to_string(s) + ".json" : out;
    std::ofstream file(path);
    file << text;
    if (!file) {
      std::cerr << "npfkct-scenegen: cannot write " << path << "\n";
      return 1;
    }
  }
  return 0;
}
