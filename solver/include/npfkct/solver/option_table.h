// The table machinery behind SetOption and OptionValues: the fields of an options struct by name,
// set and read back as numbers, shared by every options struct that is set from command lines and
// request payloads (the solver's planners, the filter).
#pragma once

#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "npfkct/common/status.h"

namespace npfkct::option_table {

/// Sets one field of an options struct from a number.
template <class O>
using Setter = std::function<Status(O*, double)>;
/// Reads one field of an options struct as a number (booleans 0/1, enums their index).
template <class O>
using Getter = std::function<double(const O&)>;

/// One named field of an options struct: how to set it and how to read it back.
template <class O>
struct Field {
  Setter<O> set;
  Getter<O> get;
};

/// A table of fields by snake_case key.
template <class O>
using Table = std::map<std::string, Field<O>, std::less<>>;

/// A double field.
template <class O>
Field<O> Real(double O::*field) {
  return {[field](O* o, double v) {
            o->*field = v;
            return OkStatus();
          },
          [field](const O& o) { return o.*field; }};
}
/// An int field: integral values only.
template <class O>
Field<O> Int(int O::*field) {
  return {[field](O* o, double v) {
            if (v != std::floor(v) || std::abs(v) > 1e9) {
              return InvalidArgumentError("not an integer");
            }
            o->*field = static_cast<int>(v);
            return OkStatus();
          },
          [field](const O& o) { return static_cast<double>(o.*field); }};
}
/// A bool field: 0 or 1.
template <class O>
Field<O> Bool(bool O::*field) {
  return {[field](O* o, double v) {
            if (v != 0.0 && v != 1.0) return InvalidArgumentError("not a boolean (0 or 1)");
            o->*field = v != 0.0;
            return OkStatus();
          },
          [field](const O& o) { return o.*field ? 1.0 : 0.0; }};
}
/// An enum field set by the index of its value in `values`; `what` says which index is which
/// (the error message, e.g. "0 (rollout) or 1 (heuristic)").
template <class O, class E>
Field<O> Enum(E O::*field, std::vector<E> values, std::string what) {
  return {[field, values, what](O* o, double v) {
            for (size_t i = 0; i < values.size(); ++i) {
              if (v == static_cast<double>(i)) {
                o->*field = values[i];
                return OkStatus();
              }
            }
            return InvalidArgumentError(what);
          },
          [field, values](const O& o) {
            for (size_t i = 0; i < values.size(); ++i) {
              if (o.*field == values[i]) return static_cast<double>(i);
            }
            return -1.0;
          }};
}
/// A field of a nested struct.
template <class O, class Inner>
Field<O> Nested(Inner O::*member, Field<Inner> inner) {
  return {[member, set = inner.set](O* o, double v) { return set(&(o->*member), v); },
          [member, get = inner.get](const O& o) { return get(o.*member); }};
}
/// Adds every field of `inner` to `table` under "prefix." + its key, through `member`.
template <class O, class Inner>
void AddNested(Table<O>* table, const std::string& prefix, Inner O::*member,
               const Table<Inner>& inner) {
  for (const auto& [key, field] : inner) (*table)[prefix + "." + key] = Nested(member, field);
}

/// Sets option `key` of `o` from `table` (the bare leaf name of a nested key is accepted when
/// unambiguous); unknown keys, non-numbers and rejected values are INVALID_ARGUMENT naming the key.
template <class O>
Status Apply(const Table<O>& table, O* o, std::string_view key, double value) {
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
  Status s = it->second.set(o, value);
  if (!s.ok()) return InvalidArgumentError("option " + it->first + ": " + s.message());
  return OkStatus();
}

/// The keys of a table.
template <class O>
std::vector<std::string> Keys(const Table<O>& table) {
  std::vector<std::string> keys;
  for (const auto& [k, v] : table) keys.push_back(k);
  return keys;
}

/// Every field of `o` as (key, value), in the table's (alphabetical) order.
template <class O>
std::vector<std::pair<std::string, double>> Values(const Table<O>& table, const O& o) {
  std::vector<std::pair<std::string, double>> values;
  for (const auto& [k, field] : table) values.emplace_back(k, field.get(o));
  return values;
}

}  // namespace npfkct::option_table
