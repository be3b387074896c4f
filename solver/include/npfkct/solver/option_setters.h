// Setting and reading planner options by name, for command lines, request payloads and reports.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/solver/advt.h"
#include "npfkct/solver/despot.h"
#include "npfkct/solver/kct.h"
#include "npfkct/solver/pomcp.h"
#include "npfkct/solver/pomcpow.h"

namespace npfkct {

/// Sets option `key` (snake_case field name; nested fields as "search.max_depth" or the bare leaf
/// name when unambiguous) to `value`. Booleans take 0/1; enums take the values documented by
/// OptionNames(). Unknown keys and non-finite numbers are INVALID_ARGUMENT naming the key.
Status SetOption(SearchOptions* o, std::string_view key, double value);
Status SetOption(PomcpOptions* o, std::string_view key, double value);
Status SetOption(DespotOptions* o, std::string_view key, double value);
Status SetOption(PomcpowOptions* o, std::string_view key, double value);
Status SetOption(AdvtOptions* o, std::string_view key, double value);
Status SetOption(KctOptions* o, std::string_view key, double value);

/// The keys SetOption accepts for each options struct.
std::vector<std::string> OptionNames(const SearchOptions*);
std::vector<std::string> OptionNames(const PomcpOptions*);
std::vector<std::string> OptionNames(const DespotOptions*);
std::vector<std::string> OptionNames(const PomcpowOptions*);
std::vector<std::string> OptionNames(const AdvtOptions*);
std::vector<std::string> OptionNames(const KctOptions*);

/// Option values as (key, value), keyed as SetOption's keys.
using OptionValueList = std::vector<std::pair<std::string, double>>;
/// Every option of an options struct as SetOption would set it (booleans 0/1, enums the number
/// SetOption takes), in key order: what a planner runs with.
OptionValueList OptionValues(const SearchOptions& o);
OptionValueList OptionValues(const PomcpOptions& o);
OptionValueList OptionValues(const DespotOptions& o);
OptionValueList OptionValues(const PomcpowOptions& o);
OptionValueList OptionValues(const AdvtOptions& o);
OptionValueList OptionValues(const KctOptions& o);

/// Parses "key=value" and applies it with SetOption.
template <class Options>
Status SetOptionFromString(Options* o, std::string_view assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string_view::npos) {
    return InvalidArgumentError("option '" + std::string(assignment) + "' is not key=value");
  }
  const std::string value(assignment.substr(eq + 1));
  char* end = nullptr;
  const double v = std::strtod(value.c_str(), &end);
  if (value.empty() || end != value.c_str() + value.size()) {
    if (value == "true") return SetOption(o, assignment.substr(0, eq), 1.0);
    if (value == "false") return SetOption(o, assignment.substr(0, eq), 0.0);
    return InvalidArgumentError("option " + std::string(assignment.substr(0, eq)) + ": '" + value +
                                "' is not a number");
  }
  return SetOption(o, assignment.substr(0, eq), v);
}

}  // namespace npfkct
