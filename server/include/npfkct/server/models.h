// Neural filter models by name: the server lists its model folder once at start, clients name a
// file of that listing (planner.model), and nothing a client sends ever becomes a path.
#pragma once

#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "npfkct/api/types.h"
#include "npfkct/common/status.h"
#include "npfkct/object_search/model.h"
#include "npfkct/solver/candidates.h"

namespace npfkct::filter {
class NeuralFilter;
}  // namespace npfkct::filter

namespace npfkct::server {

/// The model files of one folder, loaded on first use and kept in a bounded cache; a model
/// dropped from it is loaded again only once no session holds it.
class ModelRegistry {
 public:
  /// Lists `dir` once: regular files named like api::IsModelName ending in ".pt", of at most
  /// `max_file_bytes`. An unreadable folder gives an empty registry (no model can be named).
  static std::shared_ptr<ModelRegistry> Open(const std::string& dir, size_t max_loaded = 4,
                                             size_t max_file_bytes = 64 << 20);
  /// The names clients may use.
  std::vector<std::string> names() const;
  /// `name` when it is in the listing (the model npfkct sessions that name none plan with);
  /// otherwise "" and a warning in the log (they plan with uniform candidates).
  std::string DefaultModel(const std::string& name) const;
  /// The loaded model `name`: INVALID_ARGUMENT naming planner.model for a name not in the listing
  /// or a file that does not load (not cached, so the operator can fix it).
  StatusOr<std::shared_ptr<const filter::NeuralFilter>> Get(const std::string& name);

 private:
  ModelRegistry() = default;
  std::string dir_;
  std::map<std::string, std::string> files_;  // name -> path, fixed at Open()
  size_t max_loaded_ = 4;
  std::mutex mutex_;
  std::list<std::pair<std::string, std::shared_ptr<const filter::NeuralFilter>>> loaded_;  // LRU
  // Models dropped from the cache, while sessions still hold them: reused instead of loading a
  // second copy (with --max-models 1, sessions alternating two models each held their own copy).
  std::map<std::string, std::weak_ptr<const filter::NeuralFilter>> dropped_;
};

/// Supplies the candidate sampler of a session whose planner takes one (Net_sam over a named
/// model), or null for uniform candidates.
using SamplerFactory =
    std::function<StatusOr<std::shared_ptr<CandidateSampler<object_search::State>>>(
        const api::PlannerSpec& spec, const object_search::ObjectSearchModel& model)>;

/// Whether a planner option is one of Net_sam's ("filter.explore"), which the sampler takes and
/// the planner never sees.
bool IsFilterOption(const std::string& key);

/// The factory of the server: Net_sam over `models`' model spec.model with the "filter.*"
/// options; errors are INVALID_ARGUMENT naming planner.model or planner.options.filter.<key>
/// (the key as the filter takes it, snake_case).
SamplerFactory FilterSamplerFactory(std::shared_ptr<ModelRegistry> models);

}  // namespace npfkct::server
