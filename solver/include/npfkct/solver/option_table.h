// The table machinery behind SetOption: setters of option fields by name, shared by every options
// struct that is set from command lines and request payloads (the solver's planners, the filter).
#pragma once

#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "npfkct/common/status.h"

namespace npfkct::option_table {

/// Sets one field of an options struct from a number.
template <class O>
using Setter = std::function<Status(O*, double)>;

/// A table of setters by snake_case key.
template <class O>
using Table = std::map<std::string, Setter<O>, std::less<>>;

/// A setter of a double field.
template <class O>
Setter<O> Real(double O::*field) {
  return [field](O* o, double v) {
    o->*field = v;
    return OkStatus();
  };
}
/// A setter of an int field: integral values only.
template <class O>
Setter<O> Int(int O::*field) {
  return [field](O* o, double v) {
    if (v != std::floor(v) || std::abs(v) > 1e9) return InvalidArgumentError("not an integer");
    o->*field = static_cast<int>(v);
    return OkStatus();
  };
}
/// A setter of a bool field: 0 or 1.
template <class O>
Setter<O> Bool(bool O::*field) {
  return [field](O* o, double v) {
    if (v != 0.0 && v != 1.0) return InvalidArgumentError("not a boolean (0 or 1)");
    o->*field = v != 0.0;
    return OkStatus();
  };
}
/// A setter of a nested struct's field.
template <class O, class Inner>
Setter<O> Nested(Inner O::*member, Setter<Inner> inner) {
  return [member, inner](O* o, double v) { return inner(&(o->*member), v); };
}

/// Sets option `key` of `o` from `table` (the bare leaf name of a nested key is accepted when
/// unambiguous); unknown keys, non-numbers and rejected values are INVALID_ARGUMENT naming the key.
template <class O>
Status Apply(const std::map<std::string, Setter<O>, std::less<>>& table, O* o, std::string_view key,
             double value) {
  auto it = table.find(key);
  if (it == table.end()) {
    // Allow the bare leaf name when exactly one nested key ends with it.
    // Built by appends: GCC 12 warns falsely (-Wrestrict) on "." + std::string when inlined.
    std::string suffix(1, '.');
    suffix.append(key);
    int matches = 0;
    for (auto j = table.begin(); j != table.end(); ++j) {
      if (j->first.size() > suffix.size() &&
          j->first.compare(j->first.size() - suffix.size(), suffix.size(), suffix) == 0) {
        it = j;
        ++matches;
      }
    }
    if (matches != 1) return InvalidArgumentError("unknown option '" + std::string(key) + "'");
  }
  // NaN selects the automatic value of the options that have one (the reward range, appendix J's
  // rules); everywhere else it is an error.
  const std::string_view leaf = std::string_view(it->first).substr(it->first.rfind('.') + 1);
  const bool nan_means_auto =
      leaf == "exploration_c" || leaf == "value_scale" || leaf == "w2" || leaf == "c_r";
  if (std::isnan(value) && !nan_means_auto) {
    return InvalidArgumentError("option " + it->first + ": value must be a number");
  }
  if (std::isinf(value)) return InvalidArgumentError("option " + it->first + ": value is infinite");
  Status s = it->second(o, value);
  if (!s.ok()) return InvalidArgumentError("option " + it->first + ": " + s.message());
  return OkStatus();
}

/// The keys of a table.
template <class O>
std::vector<std::string> Keys(const std::map<std::string, Setter<O>, std::less<>>& table) {
  std::vector<std::string> keys;
  for (const auto& [k, v] : table) keys.push_back(k);
  return keys;
}

}  // namespace npfkct::option_table
