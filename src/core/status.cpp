#include "earshot/core/status.h"

#include <algorithm>
#include <cstdio>

namespace earshot {

const char* statusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kOk: return "ok";
    case StatusCode::kInvalidArgument: return "invalid argument";
    case StatusCode::kNotFound: return "not found";
    case StatusCode::kIoError: return "i/o error";
    case StatusCode::kParseError: return "parse error";
    case StatusCode::kUnsupported: return "unsupported";
    case StatusCode::kOutOfRange: return "out of range";
    case StatusCode::kInternal: return "internal error";
  }
  return "unknown";
}

namespace {

/** Bytes of the UTF-8 character starting at s[i] (1-4), or 0 if the bytes
 *  there are not a well-formed character (RFC 3629: no overlongs, no
 *  surrogates, nothing past U+10FFFF). */
size_t utf8Length(std::string_view s, size_t i) {
  const auto at = [&](size_t k) { return i + k < s.size() ? static_cast<unsigned char>(s[i + k]) : 0u; };
  const unsigned c = at(0);
  if (c < 0x80) return 1;
  size_t n = 0;
  unsigned lo = 0x80, hi = 0xBF;  // the second byte's range
  if (c >= 0xC2 && c <= 0xDF) n = 2;
  else if (c == 0xE0) n = 3, lo = 0xA0;
  else if (c == 0xED) n = 3, hi = 0x9F;
  else if (c >= 0xE1 && c <= 0xEF) n = 3;
  else if (c == 0xF0) n = 4, lo = 0x90;
  else if (c == 0xF4) n = 4, hi = 0x8F;
  else if (c >= 0xF1 && c <= 0xF3) n = 4;
  else return 0;
  if (at(1) < lo || at(1) > hi) return 0;
  for (size_t k = 2; k < n; ++k)
    if (at(k) < 0x80 || at(k) > 0xBF) return 0;
  return n;
}

// The C1 controls U+0080-U+009F (C2 80 - C2 9F): valid UTF-8 that some
// terminals act on (U+009B is CSI, as ESC [ is).
bool isC1(std::string_view s, size_t i, size_t n) {
  return n == 2 && static_cast<unsigned char>(s[i]) == 0xC2 && static_cast<unsigned char>(s[i + 1]) < 0xA0;
}

// Whether s needs no escaping: valid UTF-8 without control characters (and,
// with quotesToo, without `"` and `\`).
bool plain(std::string_view s, bool quotesToo) {
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8Length(s, i);
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (n == 0 || isC1(s, i, n) || (n == 1 && (c < 0x20 || c == 0x7f || (quotesToo && (c == '"' || c == '\\')))))
      return false;
    i += n;
  }
  return true;
}

// Appends s escaped (control characters as JSON does, and `"` and `\` with
// quotesToo; U+FFFD for each byte that starts no character), up to maxBytes
// of s, cut before the character that would pass them; returns the bytes of
// s taken.
size_t appendEscaped(std::string& out, std::string_view s, size_t maxBytes, bool quotesToo) {
  size_t i = 0;
  while (i < s.size()) {
    const size_t n = utf8Length(s, i);
    if (i + (n ? n : 1) > maxBytes) break;
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (n == 0) {
      out += "\xEF\xBF\xBD";  // U+FFFD for a byte that starts no character
      i += 1;
      continue;
    }
    if (isC1(s, i, n)) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\u%04x", unsigned(static_cast<unsigned char>(s[i + 1])));
      out += hex;
    } else if (n > 1) {
      out.append(s.substr(i, n));
    } else if (quotesToo && c == '"') {
      out += "\\\"";
    } else if (quotesToo && c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c == '\b') {
      out += "\\b";
    } else if (c == '\f') {
      out += "\\f";
    } else if (c < 0x20 || c == 0x7f) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\u%04x", unsigned(c));
      out += hex;
    } else {
      out += char(c);
    }
    i += n;
  }
  return i;
}

}  // namespace

std::string quotedName(std::string_view name, size_t maxBytes) {
  std::string out = "\"";
  out.reserve(std::min(name.size(), maxBytes) + 8);
  const size_t taken = appendEscaped(out, name, maxBytes, true);
  out += taken < name.size() ? "\"..." : "\"";
  return out;
}

namespace detail {
void makeOneLine(std::string& m) {
  if (plain(m, false)) return;  // every message but a hostile input's
  std::string out;
  out.reserve(m.size() + 16);
  appendEscaped(out, m, std::string_view::npos, false);  // quotes and backslashes stay
  m = std::move(out);
}
}  // namespace detail

std::string displayPath(std::string_view path) {
  return path.size() <= kQuotedPathBytes && plain(path, true) ? std::string(path) : quotedName(path, kQuotedPathBytes);
}

}  // namespace earshot
