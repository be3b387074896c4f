#include "npfkct/server/filter_samplers.h"

#include <algorithm>
#include <map>
#include <mutex>

#include "npfkct/filter/filter.h"

namespace npfkct::server {

bool IsFilterOption(const std::string& key) { return key.rfind("filter.", 0) == 0; }

namespace {

// planner.options "filter.*" keys (snake_case) applied to Net_sam's options.
Status ApplyFilterOptions(const PlannerSpec& spec, filter::FilterOptions* o) {
  for (const auto& [key, value] : spec.options) {
    if (!IsFilterOption(key)) continue;
    if (Status s = filter::SetOption(o, key.substr(7), value); !s.ok()) {
      return InvalidArgumentError("planner.options." + key + ": " + s.message());
    }
  }
  if (Status s = o->Validate(); !s.ok()) {
    return InvalidArgumentError("planner.options.filter." + s.message());
  }
  return OkStatus();
}

}  // namespace

SamplerFactory FilterSamplerFactory() {
  struct Cache {
    std::mutex mu;
    std::map<std::string, std::shared_ptr<const filter::NeuralFilter>> models;
  };
  auto cache = std::make_shared<Cache>();
  return [cache](const PlannerSpec& spec, const object_search::ObjectSearchModel& model)
             -> StatusOr<std::shared_ptr<CandidateSampler<object_search::State>>> {
    const bool has_filter_options =
        std::any_of(spec.options.begin(), spec.options.end(),
                    [](const auto& kv) { return IsFilterOption(kv.first); });
    if (spec.model_path.empty()) {
      if (has_filter_options) {
        return InvalidArgumentError("planner.options: filter options need planner.modelPath");
      }
      return std::shared_ptr<CandidateSampler<object_search::State>>();
    }
    if (spec.name != "npfkct") {
      return InvalidArgumentError("planner.modelPath: only the npfkct planner uses a filter model");
    }
    std::shared_ptr<const filter::NeuralFilter> net;
    {
      // Loaded once per path; a file that fails to load is not cached, so it can be fixed.
      std::lock_guard<std::mutex> lock(cache->mu);
      auto it = cache->models.find(spec.model_path);
      if (it != cache->models.end()) {
        net = it->second;
      } else {
        auto loaded = filter::NeuralFilter::Load(spec.model_path);
        if (!loaded.ok()) {
          return InvalidArgumentError("planner.modelPath: " + loaded.status().message());
        }
        net = *loaded;
        cache->models.emplace(spec.model_path, net);
      }
    }
    filter::FilterOptions options;
    if (Status s = ApplyFilterOptions(spec, &options); !s.ok()) return s;
    auto sampler = filter::MakeNetSam(net, model, options);
    if (!sampler.ok())
      return InvalidArgumentError("planner.modelPath: " + sampler.status().message());
    return *sampler;
  };
}

}  // namespace npfkct::server
