// Request validation against the JSON Schemas of schemas/ (embedded at build time) with valijson.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "json_util.h"

namespace npfkct::api::internal {

/// The schema files compiled into the server: (file name, text).
const std::vector<std::pair<std::string_view, std::string_view>>& EmbeddedSchemaFiles();

/// The parsed schema file `name` ("common.schema.json"), or null.
const json* SchemaDocument(std::string_view name);

/// Validates `doc` against schemas/`message`.schema.json (or, for "action" and "world", the
/// Action and World definitions of common.schema.json). On failure: INVALID_ARGUMENT whose field
/// violations name the offending fields by their paths in the request ("world.furniture[0].size",
/// "planner.unknownKey"), at most `max_violations` of them, the most specific first. With
/// `planner_names`, planner.name must be one of them (the schema file lists the built-in ones).
Status ValidateAgainstSchema(std::string_view message, const json& doc, size_t max_violations = 8,
                             const std::vector<std::string>* planner_names = nullptr);

}  // namespace npfkct::api::internal
