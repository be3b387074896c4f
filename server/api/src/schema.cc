#include "schema.h"

#include <algorithm>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <valijson/adapters/nlohmann_json_adapter.hpp>
#include <valijson/schema.hpp>
#include <valijson/schema_parser.hpp>
#include <valijson/validation_results.hpp>
#include <valijson/validator.hpp>

namespace npfkct::api::internal {
namespace {

using Adapter = valijson::adapters::NlohmannJsonAdapter;

bool StartsWith(const std::string& s, std::string_view prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

// The text between the last pair of single quotes ("... constraints: 'x'.").
std::string Quoted(const std::string& s) {
  const size_t b = s.find_last_of('\'');
  const size_t a =
      b == std::string::npos || b == 0 ? std::string::npos : s.find_last_of('\'', b - 1);
  return a == std::string::npos ? "" : s.substr(a + 1, b - a - 1);
}

// A field path cut to 96 bytes (at a UTF-8 character boundary) and marked "...": an error never
// echoes a long unknown key, which a client could otherwise make the server write back twice.
std::string Shortened(const std::string& field) {
  constexpr size_t kMax = 96;
  if (field.size() <= kMax) return field;
  size_t cut = kMax;
  while (cut > 0 && (static_cast<unsigned char>(field[cut]) & 0xC0) == 0x80) --cut;
  return field.substr(0, cut) + "...";
}

// The number at the end of a valijson message ("Expected number less than 5.000000").
std::string TrailingNumber(const std::string& s) {
  size_t end = s.size();
  while (end > 0 && (s[end - 1] == '.' || s[end - 1] == ' ')) --end;
  size_t begin = s.find_last_of(' ', end - 1);
  begin = begin == std::string::npos ? 0 : begin + 1;
  const std::string text = s.substr(begin, end - begin);
  char* stop = nullptr;
  const double v = std::strtod(text.c_str(), &stop);
  if (stop == text.c_str()) return text;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// The integer after `prefix` ("Array should contain no fewer than 2 elements.").
std::string CountAfter(const std::string& s, std::string_view prefix) {
  size_t i = prefix.size();
  size_t j = i;
  while (j < s.size() && std::isdigit(static_cast<unsigned char>(s[j]))) ++j;
  return s.substr(i, j - i);
}

// (message, definition of common.schema.json) validated as if it had a schema file.
constexpr std::pair<const char*, const char*> kDefinitionSchemas[] = {{"action", "Action"},
                                                                      {"world", "World"}};

struct Documents {
  std::map<std::string, json, std::less<>> files;
  std::map<std::string, std::unique_ptr<valijson::Schema>, std::less<>> schemas;
};

std::string FileOf(const std::string& uri) {
  const size_t slash = uri.find_last_of('/');
  std::string name = slash == std::string::npos ? uri : uri.substr(slash + 1);
  const size_t hash = name.find('#');
  return hash == std::string::npos ? name : name.substr(0, hash);
}

// The schema files, compiled; with `planner_names`, the create request's PlannerSpec.name lists
// those names instead of the file's (a server whose registry differs from the built-in one). One
// set of documents per list of names, kept for the process's life (a process has one or two).
const Documents& Docs(const std::vector<std::string>* planner_names = nullptr) {
  static std::mutex mutex;
  static auto* cache = new std::map<std::vector<std::string>, std::unique_ptr<Documents>>();
  static const std::vector<std::string> kAsInTheFiles;
  const std::vector<std::string>& key = planner_names ? *planner_names : kAsInTheFiles;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache->find(key);
  if (it != cache->end()) return *it->second;
  auto d = std::make_unique<Documents>();
  for (const auto& [name, text] : EmbeddedSchemaFiles()) {
    d->files[std::string(name)] = json::parse(text);
  }
  // Definitions of common.schema.json that decoders check on their own, as documents of their
  // own: an action as the plan reply has it (npfkct-sim-robot's input lines) and a world spec
  // (the world part of a scenario file).
  for (const auto& [message, definition] : kDefinitionSchemas) {
    const std::string name = std::string(message) + ".schema.json";
    if (d->files.count(name) > 0) continue;
    json ref = json::object();
    ref["$ref"] = std::string("common.schema.json#/$defs/") + definition;
    json doc = json::object();
    doc["$id"] = name;
    doc["allOf"] = json::array({ref});
    d->files[name] = std::move(doc);
  }
  if (planner_names != nullptr) {
    json& names = d->files.at("common.schema.json")["$defs"]["PlannerSpec"]["properties"]["name"];
    names["enum"] = *planner_names;
  }
  for (const auto& [name, doc] : d->files) {
    auto schema = std::make_unique<valijson::Schema>();
    valijson::SchemaParser parser(valijson::SchemaParser::kDraft7);
    Adapter adapter(doc);
    const Documents* docs = d.get();
    parser.populateSchema(
        adapter, *schema,
        [docs](const std::string& uri) -> const json* {
          auto f = docs->files.find(FileOf(uri));
          return f == docs->files.end() ? nullptr : &f->second;
        },
        [](const json*) {});
    d->schemas[name] = std::move(schema);
  }
  return *cache->emplace(key, std::move(d)).first->second;
}

const json* FileIn(const Documents& d, std::string_view name) {
  auto it = d.files.find(name);
  return it == d.files.end() ? nullptr : &it->second;
}

// ---- finding the schema of an instance path, to describe violations ----

struct Node {
  const json* schema = nullptr;
  const json* doc = nullptr;  // the file it lives in (for local $refs)
};

Node Resolve(Node n, const Documents& d) {
  for (int guard = 0; guard < 16 && n.schema && n.schema->is_object(); ++guard) {
    auto ref = n.schema->find("$ref");
    if (ref == n.schema->end() || !ref->is_string()) break;
    const std::string r = ref->get<std::string>();
    const size_t hash = r.find('#');
    const std::string file = r.substr(0, hash);
    if (!file.empty()) {
      const json* f = FileIn(d, FileOf(file));
      if (!f) return {};
      n.doc = f;
    }
    const std::string pointer = hash == std::string::npos ? "" : r.substr(hash + 1);
    const json::json_pointer p(pointer);
    if (!n.doc->contains(p)) return {};
    n.schema = &n.doc->at(p);
  }
  return n;
}

Node Child(Node n, const std::string& key, bool index, const Documents& d) {
  n = Resolve(n, d);
  if (!n.schema || !n.schema->is_object()) return {};
  const json& s = *n.schema;
  if (index) {
    auto items = s.find("items");
    return items != s.end() && items->is_object() ? Node{&*items, n.doc} : Node{};
  }
  auto props = s.find("properties");
  if (props != s.end() && props->contains(key)) return {&props->at(key), n.doc};
  auto all = s.find("allOf");
  if (all != s.end() && all->is_array()) {
    for (const json& part : *all) {
      Node c = Child({&part, n.doc}, key, false, d);
      if (c.schema) return c;
    }
  }
  auto extra = s.find("additionalProperties");
  if (extra != s.end() && extra->is_object()) return {&*extra, n.doc};
  return {};
}

std::string TypeWords(const json& type) {
  auto one = [](const std::string& t) -> std::string {
    if (t == "number") return "a number";
    if (t == "integer") return "an integer";
    if (t == "string") return "a string";
    if (t == "boolean") return "true or false";
    if (t == "object") return "an object";
    if (t == "array") return "an array";
    return t;
  };
  if (type.is_string()) return one(type.get<std::string>());
  std::string out;
  for (size_t i = 0; type.is_array() && i < type.size(); ++i) {
    if (!type[i].is_string()) continue;
    out += (out.empty() ? "" : " or ") + one(type[i].get<std::string>());
  }
  return out;
}

struct Violation {
  std::string field;
  std::string description;
  int depth = 0;
};

// The path of the first string (value or key) of `v` holding U+0000, if any. valijson counts a
// string's characters up to its first NUL (over c_str()), so such a string would pass every
// maxLength of the schemas; no field of the API has a use for one.
std::optional<std::string> StringWithNul(const json& v, const std::string& path) {
  if (v.is_string()) {
    const auto& text = v.get_ref<const std::string&>();
    if (text.find('\0') != std::string::npos) return path;
  } else if (v.is_array()) {
    for (size_t i = 0; i < v.size(); ++i) {
      if (auto p = StringWithNul(v[i], At(path, i))) return p;
    }
  } else if (v.is_object()) {
    for (const auto& [key, child] : v.items()) {
      if (key.find('\0') != std::string::npos) return Join(path, "(a key)");
      if (auto p = StringWithNul(child, Join(path, key))) return p;
    }
  }
  return std::nullopt;
}

// Where a valijson error points: the instance's field path, the schema there (resolved) and the
// depth of the path.
struct Located {
  std::string path;
  Node schema;
  Node here;
  int depth = 0;
};

Located Locate(const valijson::ValidationResults::Error& e, const json& doc, const Documents& d,
               const std::string& root_file) {
  // The instance path: "<root>", then "[key]" or "[index]" per level.
  Located l;
  const json* at = &doc;
  l.schema = Node{FileIn(d, root_file), FileIn(d, root_file)};
  for (size_t i = 1; i < e.context.size(); ++i) {
    std::string token = e.context[i];
    if (token.size() >= 2 && token.front() == '[' && token.back() == ']') {
      token = token.substr(1, token.size() - 2);
    }
    const bool index = at && at->is_array();
    if (index) {
      const size_t k = std::strtoul(token.c_str(), nullptr, 10);
      l.path = At(l.path, k);
      at = k < at->size() ? &(*at)[k] : nullptr;
    } else {
      l.path = Join(l.path, token);
      at = at && at->is_object() && at->contains(token) ? &at->at(token) : nullptr;
    }
    l.schema = Child(l.schema, token, index, d);
    ++l.depth;
  }
  l.here = Resolve(l.schema, d);
  return l;
}

// Whether valijson's message `m` is only the consequence of a more specific error.
bool IsConsequence(const std::string& m) {
  return StartsWith(m, "Failed to validate against schema associated with property") ||
         StartsWith(m, "Failed to validate item #") ||
         StartsWith(m, "Failed to validate against child schema") ||
         StartsWith(m, "Failed to validate against a conditional schema") ||
         StartsWith(m, "Failed to validate against additional properties schema") ||
         StartsWith(m, "Failed to validate against schema associated with pattern");
}

// The member a consequence names, kept in case valijson reports nothing more specific: a key
// that breaks `propertyNames` is reported by nothing else.
Violation ConsequenceOf(const std::string& m, const Located& at, const Documents& d) {
  const std::string key = Quoted(m);
  const Node member = Resolve(Child(at.schema, key, false, d), d);
  std::string why = "does not match its schema";
  if (member.schema && member.schema->is_object()) {
    const auto names = member.schema->find("propertyNames");
    if (names != member.schema->end() && names->is_object() && names->contains("maxLength") &&
        names->at("maxLength").is_number_unsigned()) {
      why = "keys must be at most " + std::to_string(names->at("maxLength").get<uint64_t>()) +
            " characters";
    }
  }
  return {Join(at.path, key), why, at.depth + 1};
}

// valijson's messages of a bound, in a caller's words: `before`, then the bound (the number
// ending the message) or, for a size, the count right after `prefix`, then `after`. A prefix
// that another begins with comes after it.
struct BoundWords {
  std::string_view prefix;
  bool count;
  std::string_view before;
  std::string_view after;
};
constexpr BoundWords kBoundWords[] = {
    {"Expected number greater than or equal to", false, "must be >= ", ""},
    {"Expected number greater than", false, "must be > ", ""},
    {"Expected number less than or equal to", false, "must be <= ", ""},
    {"Expected number less than", false, "must be < ", ""},
    {"Array should contain no fewer than ", true, "expected at least ", " items"},
    {"Array should contain no more than ", true, "expected at most ", " items"},
    {"String should be no more than ", true, "expected at most ", " characters"},
    {"String should be no fewer than ", true, "expected at least ", " characters"},
    {"Object should have no more than ", true, "expected at most ", " entries"},
};

// valijson's message `m` about `at` in words a caller reads, into `out` (or, for an alternative
// that failed as a whole, into `alternatives`).
void Describe(const std::string& m, const Located& at, std::vector<Violation>* out,
              std::vector<Violation>* alternatives) {
  auto add = [&](std::string field, std::string description, int extra_depth = 0) {
    out->push_back({std::move(field), std::move(description), at.depth + extra_depth});
  };
  for (const BoundWords& b : kBoundWords) {
    if (StartsWith(m, b.prefix)) {
      std::string words(b.before);
      words += b.count ? CountAfter(m, b.prefix) : TrailingNumber(m);
      words += b.after;
      add(at.path, std::move(words));
      return;
    }
  }
  if (StartsWith(m, "Failed to validate against any") ||
      StartsWith(m, "Failed to validate against exactly one")) {
    const json* s = at.here.schema;
    alternatives->push_back({at.path,
                             s && s->contains("description") && s->at("description").is_string()
                                 ? s->at("description").get<std::string>()
                                 : "does not match any accepted form",
                             at.depth});
  } else if (StartsWith(m, "Object contains a property that could not be validated")) {
    add(Join(at.path, Quoted(m)), "unknown field", 1);
  } else if (StartsWith(m, "Missing required property")) {
    add(Join(at.path, Quoted(m)), "missing", 1);
  } else if (StartsWith(m, "Value type not permitted")) {
    const std::string words = at.here.schema && at.here.schema->contains("type")
                                  ? TypeWords(at.here.schema->at("type"))
                                  : "";
    add(at.path, words.empty() ? "wrong type" : "expected " + words);
  } else if (StartsWith(m, "Failed to match against any enum values")) {
    std::string values;
    if (at.here.schema && at.here.schema->contains("enum")) {
      for (const json& v : at.here.schema->at("enum"))
        values += (values.empty() ? "" : ", ") + Dump(v);
    }
    add(at.path, values.empty() ? "not an accepted value" : "expected one of " + values);
  } else if (StartsWith(m, "Failed to match expected value set by 'const'")) {
    add(at.path, at.here.schema && at.here.schema->contains("const")
                     ? "expected " + Dump(at.here.schema->at("const"))
                     : "not the expected value");
  } else if (StartsWith(m, "Target should not validate against schema specified in 'not'")) {
    const json* s = at.here.schema;
    const json* n = s && s->contains("not") ? &s->at("not") : nullptr;
    std::string field = at.path;
    if (n && n->contains("required") && n->at("required").is_array() &&
        !n->at("required").empty() && n->at("required")[0].is_string()) {
      field = Join(at.path, n->at("required")[0].get<std::string>());
    }
    add(field.empty() ? "body" : field,
        n && n->contains("description") && n->at("description").is_string()
            ? n->at("description").get<std::string>()
            : "not allowed here",
        1);
  } else {
    add(at.path.empty() ? "body" : at.path, m);
  }
}

// The violations to report: those inside an alternative that failed as a whole dropped, the
// deepest first, each once, at most `max_violations`.
std::vector<Violation> Collapse(std::vector<Violation> out,
                                const std::vector<Violation>& alternatives, size_t max_violations) {
  // Inside an alternative that failed as a whole, the per-alternative errors say little.
  for (const Violation& alt : alternatives) {
    const std::string& a = alt.field;
    out.erase(std::remove_if(out.begin(), out.end(),
                             [&](const Violation& v) {
                               const std::string& f = v.field;
                               return a.empty() || f == a ||
                                      (f.size() > a.size() && f.compare(0, a.size(), a) == 0 &&
                                       (f[a.size()] == '.' || f[a.size()] == '['));
                             }),
              out.end());
  }
  for (Violation alt : alternatives) {
    if (alt.field.empty()) alt.field = "body";
    out.push_back(std::move(alt));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Violation& a, const Violation& b) { return a.depth > b.depth; });
  std::vector<Violation> unique;
  for (const Violation& v : out) {
    const bool seen = std::any_of(unique.begin(), unique.end(), [&](const Violation& u) {
      return u.field == v.field && u.description == v.description;
    });
    if (!seen) unique.push_back(v);
    if (unique.size() >= max_violations) break;
  }
  return unique;
}

}  // namespace

const json* SchemaDocument(std::string_view name) { return FileIn(Docs(), name); }

Status ValidateAgainstSchema(std::string_view message, const json& doc, size_t max_violations,
                             const std::vector<std::string>* planner_names) {
  const Documents& d = Docs(planner_names);
  auto it = d.schemas.find(std::string(message) + ".schema.json");
  if (it == d.schemas.end()) return InternalError("no schema for " + std::string(message));
  const std::string root_file = std::string(message) + ".schema.json";
  if (auto field = StringWithNul(doc, "")) {
    const std::string name = field->empty() ? "body" : Shortened(*field);
    return Status(StatusCode::kInvalidArgument, name + ": must not contain U+0000")
        .WithFieldViolation(name, "must not contain U+0000");
  }
  Adapter adapter(doc);
  {
    valijson::Validator fast;  // stops at the first failure
    if (fast.validate(*it->second, adapter, nullptr)) return OkStatus();
  }
  valijson::Validator validator;
  valijson::ValidationResults results;
  validator.validate(*it->second, adapter, &results);

  std::vector<Violation> out;
  std::vector<Violation> alternatives;  // oneOf/anyOf that failed as a whole
  Violation consequence{"", "", -1};
  valijson::ValidationResults::Error e;
  while (results.popError(e)) {
    const Located at = Locate(e, doc, d, root_file);
    if (!IsConsequence(e.description)) {
      Describe(e.description, at, &out, &alternatives);
    } else if (StartsWith(e.description,
                          "Failed to validate against schema associated with property") &&
               at.depth + 1 > consequence.depth) {
      consequence = ConsequenceOf(e.description, at, d);
    }
  }
  std::vector<Violation> unique = Collapse(std::move(out), alternatives, max_violations);
  if (unique.empty() && consequence.depth >= 0) unique.push_back(consequence);
  if (unique.empty()) unique.push_back({"body", "does not match the request schema", 0});
  Status s(StatusCode::kInvalidArgument, Shortened(unique[0].field) + ": " + unique[0].description);
  for (const Violation& v : unique) s.WithFieldViolation(Shortened(v.field), v.description);
  return s;
}

}  // namespace npfkct::api::internal
