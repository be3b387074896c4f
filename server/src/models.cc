#include "npfkct/server/models.h"

#include <dirent.h>
#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <algorithm>

#include "npfkct/api/api.h"
#include "npfkct/filter/filter.h"

namespace npfkct::server {

std::shared_ptr<ModelRegistry> ModelRegistry::Open(const std::string& dir, size_t max_loaded,
                                                   size_t max_file_bytes) {
  std::shared_ptr<ModelRegistry> r(new ModelRegistry());
  r->max_loaded_ = std::max<size_t>(1, max_loaded);
  r->dir_ = dir;
  DIR* d = dir.empty() ? nullptr : ::opendir(dir.c_str());
  if (d == nullptr) return r;
  while (dirent* e = ::readdir(d)) {
    const std::string name = e->d_name;
    if (!api::IsModelName(name) || !filter::CanLoadModel(name)) continue;
    struct stat st {};
    if (::fstatat(::dirfd(d), e->d_name, &st, 0) != 0 || !S_ISREG(st.st_mode) ||
        static_cast<uint64_t>(st.st_size) > max_file_bytes) {
      continue;
    }
    r->files_[name] = dir + "/" + name;
  }
  ::closedir(d);
  return r;
}

std::vector<std::string> ModelRegistry::names() const {
  std::vector<std::string> out;
  for (const auto& [name, path] : files_) out.push_back(name);
  return out;
}

std::string ModelRegistry::DefaultModel(const std::string& name) const {
  if (name.empty() || files_.count(name) > 0) return name;
  spdlog::warn(
      "the default model {} is not in the model folder '{}': npfkct sessions that name no model "
      "plan with uniform candidates",
      name, dir_);
  return "";
}

StatusOr<std::shared_ptr<const filter::NeuralFilter>> ModelRegistry::Get(const std::string& name) {
  auto file = files_.find(name);
  if (file == files_.end()) {
    std::string known;
    for (const auto& [n, path] : files_) known += (known.empty() ? "" : ", ") + n;
    return InvalidFieldError("planner.model", "no model '" + name + "' on this server (models: " +
                                                  (known.empty() ? "none" : known) + ")");
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = loaded_.begin(); it != loaded_.end(); ++it) {
    if (it->first == name) {
      loaded_.splice(loaded_.begin(), loaded_, it);
      return loaded_.front().second;
    }
  }
  std::shared_ptr<const filter::NeuralFilter> held;
  if (auto it = dropped_.find(name); it != dropped_.end()) {
    held = it->second.lock();
    dropped_.erase(it);
  }
  if (!held) {
    auto net = filter::NeuralFilter::Load(file->second);
    if (!net.ok()) {
      return InvalidFieldError("planner.model",
                               "model '" + name + "' does not load: " + net.status().message());
    }
    held = *net;
  }
  loaded_.emplace_front(name, held);
  while (loaded_.size() > max_loaded_) {
    dropped_[loaded_.back().first] = loaded_.back().second;  // names of the listing only
    loaded_.pop_back();
  }
  return loaded_.front().second;
}

bool IsFilterOption(const std::string& key) { return key.rfind("filter.", 0) == 0; }

SamplerFactory FilterSamplerFactory(std::shared_ptr<ModelRegistry> models) {
  return [models](const api::PlannerSpec& spec, const object_search::ObjectSearchModel& model)
             -> StatusOr<std::shared_ptr<CandidateSampler<object_search::State>>> {
    const bool filter_options =
        std::any_of(spec.options.begin(), spec.options.end(),
                    [](const auto& kv) { return IsFilterOption(kv.first); });
    if (spec.model.empty()) {
      if (filter_options) {
        return InvalidFieldError("planner.options", "filter options need planner.model");
      }
      return std::shared_ptr<CandidateSampler<object_search::State>>();
    }
    auto net = models->Get(spec.model);
    if (!net.ok()) return net.status();
    filter::FilterOptions options;
    for (const auto& [key, value] : spec.options) {
      if (!IsFilterOption(key)) continue;
      const std::string field = "planner.options." + key;
      if (Status s = filter::SetOption(&options, key.substr(7), value); !s.ok()) {
        return InvalidFieldError(field, s.message());
      }
      filter::FilterOptions alone;
      (void)filter::SetOption(&alone, key.substr(7), value);
      if (Status s = alone.Validate(); !s.ok()) return InvalidFieldError(field, s.message());
    }
    if (Status s = options.Validate(); !s.ok()) {
      return InvalidFieldError("planner.options", "filter." + s.message());
    }
    auto sampler = filter::MakeNetSam(*net, model, options);
    if (!sampler.ok()) return InvalidFieldError("planner.model", sampler.status().message());
    return *sampler;
  };
}

}  // namespace npfkct::server
