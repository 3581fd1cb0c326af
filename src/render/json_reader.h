#pragma once
// Internal: JSON text to an nlohmann::json tree through a SAX handler that
// knows the JSON path of every event, so that the errors nlohmann's DOM
// parser reports without a field (a number that overflows a double, a key
// given twice in one object, nesting too deep) name the field, with the
// line and column.
#include <nlohmann/json.hpp>

#include <string>

#include "earshot/core/status.h"

namespace earshot::render_detail {

/** Parses `text`; errors are one line prefixed `displayName:LINE:COLUMN: `.
 *  Limits: nesting depth 64. Thread-safe. */
Result<nlohmann::json> parseJsonWithPaths(const std::string& text, const std::string& displayName);

/** `parent.key`, or `parent["odd key"]` when the key is not an identifier
 *  (`key` alone when parent is empty). */
std::string jsonKeyPath(const std::string& parent, const std::string& key);

/** `s` as a JSON string literal, quotes included: control characters,
 *  quotes and backslashes escaped (invalid UTF-8 replaced), so text from the
 *  file keeps an error message on one line. quotedName (core/status.h)
 *  without its length cut: paths are quoted whole. */
std::string jsonQuoted(const std::string& s);

/** `parent[index]`. */
std::string jsonIndexPath(const std::string& parent, size_t index);

}  // namespace earshot::render_detail
