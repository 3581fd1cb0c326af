#include "json_reader.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <set>
#include <vector>

#include "earshot/io/input_file.h"

namespace earshot::render_detail {

namespace {

using json = nlohmann::json;

constexpr size_t kMaxDepth = 64;

// Builds the tree like nlohmann's DOM parser, tracking the path.
class PathSax : public nlohmann::json_sax<json> {
 public:
  PathSax(const std::string& text, const std::string& displayName) : mText(text), mName(displayName) {}

  json root;
  std::string error;  // first error, complete message; empty when none

  bool null() override { return insert(json(nullptr)) != nullptr; }
  bool boolean(bool v) override { return insert(json(v)) != nullptr; }
  bool number_integer(number_integer_t v) override { return insert(json(v)) != nullptr; }
  bool number_unsigned(number_unsigned_t v) override { return insert(json(v)) != nullptr; }
  bool number_float(number_float_t v, const string_t&) override { return insert(json(v)) != nullptr; }
  bool string(string_t& v) override { return insert(json(std::move(v))) != nullptr; }
  bool binary(binary_t& v) override { return insert(json::binary(std::move(v))) != nullptr; }

  bool start_object(std::size_t) override { return open(json::object()); }
  bool start_array(std::size_t) override { return open(json::array()); }
  bool end_object() override { return close(); }
  bool end_array() override { return close(); }

  bool key(string_t& k) override {
    Frame& f = mStack.back();
    if (!f.seen.insert(k).second) {
      error = mName + ": " + jsonKeyPath(pathTo(mStack.size() - 1), k) +
              ": duplicate key (each key may appear once per object)";
      return false;
    }
    f.key = k;
    return true;
  }

  bool parse_error(std::size_t position, const std::string& lastToken,
                   const nlohmann::detail::exception& ex) override {
    std::string what = ex.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 7: syntax error ..."
    if (!what.empty() && what[0] == '[') {
      size_t close = what.find("] ");
      if (close != std::string::npos) what.erase(0, close + 2);
    }
    // Syntax errors carry nlohmann's line and column; otherwise (a number that
    // overflows) count them up to the token, which ends at `position`.
    size_t line = 0, column = 0;
    if (std::sscanf(what.c_str(), "parse error at line %zu, column %zu", &line, &column) != 2) {
      line = 1;
      size_t lineStart = 0;
      const size_t end = std::min(position, mText.size());
      for (size_t i = 0; i < end; ++i)
        if (mText[i] == '\n') {
          ++line;
          lineStart = i + 1;
        }
      column = end - lineStart;  // 1-based column of the token's last character
      if (!lastToken.empty() && lastToken.size() <= column) column -= lastToken.size() - 1;
      column = std::max<size_t>(column, 1);
    }
    const std::string where = mName + ":" + std::to_string(line) + ":" + std::to_string(column) + ": ";
    if (ex.id == 406) {  // out_of_range: number overflow; lastToken is the number
      const std::string p = currentPath();
      error = where + (p.empty() ? "" : p + ": ") + "the number " + lastToken.substr(0, 40) +
              " is too large (it overflows a double; expected a finite number)";
      return false;
    }
    if (what.rfind("parse error", 0) == 0) {
      size_t colon = what.find(": ");
      if (colon != std::string::npos) what.erase(0, colon + 2);
    }
    error = where + "malformed JSON: " + jsonErrorWithoutContent(what);
    return false;
  }

 private:
  struct Frame {
    json* node;
    std::string key;  // objects: the key being read
    std::set<std::string> seen;
  };

  // Path of the value being read inside frame `depth` (the element of an
  // array that is being parsed, or the current key of an object).
  std::string pathTo(size_t depth) const {
    std::string p;
    for (size_t i = 0; i < depth; ++i) p = step(p, i);
    return p;
  }
  std::string step(const std::string& p, size_t i) const {
    const Frame& f = mStack[i];
    if (f.node->is_object()) return jsonKeyPath(p, f.key);
    const bool childOpen = i + 1 < mStack.size();
    return jsonIndexPath(p, f.node->size() - (childOpen ? 1 : 0));
  }
  std::string currentPath() const { return pathTo(mStack.size()); }

  json* insert(json&& v) {
    if (mStack.empty()) {
      root = std::move(v);
      return &root;
    }
    json& parent = *mStack.back().node;
    if (parent.is_object()) {
      json& slot = parent[mStack.back().key];
      slot = std::move(v);
      return &slot;
    }
    parent.push_back(std::move(v));
    return &parent.back();
  }

  bool open(json&& container) {
    if (mStack.size() >= kMaxDepth) {
      error = mName + ": " + currentPath() + ": nested deeper than " + std::to_string(kMaxDepth) + " levels";
      return false;
    }
    json* node = insert(std::move(container));
    mStack.push_back({node, {}, {}});
    return true;
  }

  bool close() {
    mStack.pop_back();
    return true;
  }

  const std::string& mText;
  const std::string& mName;
  std::vector<Frame> mStack;
};

bool isIdentifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_' || s[0] == '$')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'
                                                             || c == '$'; });
}

}  // namespace

Result<nlohmann::json> parseJsonWithPaths(const std::string& text, const std::string& displayName) {
  PathSax sax(text, displayName);
  bool ok = false;
  try {
    ok = json::sax_parse(text, &sax);
  } catch (const std::exception& e) {  // defensive: the SAX interface reports through parse_error
    return parseError(displayName + ": malformed JSON: " + e.what());
  }
  if (!ok || !sax.error.empty())
    return parseError(sax.error.empty() ? displayName + ": malformed JSON" : sax.error);
  return std::move(sax.root);
}

std::string jsonKeyPath(const std::string& parent, const std::string& key) {
  if (!isIdentifier(key)) return parent + "[" + jsonQuoted(key) + "]";
  return parent.empty() ? key : parent + "." + key;
}

std::string jsonQuoted(const std::string& s) { return quotedName(s, std::string_view::npos); }

std::string jsonIndexPath(const std::string& parent, size_t index) {
  return parent + "[" + std::to_string(index) + "]";
}

}  // namespace earshot::render_detail
