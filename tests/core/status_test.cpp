// quotedName: names from input in one bounded line.
#include <gtest/gtest.h>

#include <string>

#include "earshot/core/status.h"

namespace earshot {
namespace {

TEST(QuotedName, AnOrdinaryNameIsOnlyQuoted) {
  EXPECT_EQ(quotedName("concrete"), "\"concrete\"");
  EXPECT_EQ(quotedName(""), "\"\"");
  EXPECT_EQ(quotedName("Béton brut"), "\"Béton brut\"");  // UTF-8 kept as it is
}

TEST(QuotedName, ControlCharactersQuotesAndBackslashesAreEscaped) {
  EXPECT_EQ(quotedName("a\nFAKE LOG LINE"), "\"a\\nFAKE LOG LINE\"");
  EXPECT_EQ(quotedName("\r\t\"\\"), "\"\\r\\t\\\"\\\\\"");
  EXPECT_EQ(quotedName(std::string("\x1b[2J\x7f", 5)), "\"\\u001b[2J\\u007f\"");
  EXPECT_EQ(quotedName(std::string("a\0b", 3)), "\"a\\u0000b\"");
}

TEST(QuotedName, InvalidUtf8BecomesReplacementCharacters) {
  // A lone continuation byte, a truncated 3-byte character, an overlong "/"
  // (C0 AF), a surrogate (ED A0 80) and a byte never in UTF-8 (FF): each byte
  // that starts no character is one U+FFFD; the valid "é" and "€" stay.
  const std::string r = "\xEF\xBF\xBD";
  EXPECT_EQ(quotedName("a\x80" "b"), "\"a" + r + "b\"");
  EXPECT_EQ(quotedName("\xE2\x82"), "\"" + r + r + "\"");
  EXPECT_EQ(quotedName("\xC0\xAF"), "\"" + r + r + "\"");
  EXPECT_EQ(quotedName("\xED\xA0\x80"), "\"" + r + r + r + "\"");
  EXPECT_EQ(quotedName("\xFF" "é€"), "\"" + r + "é€\"");
  EXPECT_EQ(quotedName("\b\f"), "\"\\b\\f\"");
}

TEST(QuotedName, APathIsQuotedWhole) {
  const std::string path = "/" + std::string(300, 'p') + "/a\nb.json";
  EXPECT_EQ(quotedName(path, std::string_view::npos), "\"/" + std::string(300, 'p') + "/a\\nb.json\"");
}

TEST(QuotedName, ALongNameIsCutAtACharacterBoundary) {
  const std::string exact(kQuotedNameBytes, 'x');
  EXPECT_EQ(quotedName(exact), "\"" + exact + "\"");
  EXPECT_EQ(quotedName(exact + "y"), "\"" + exact + "\"...");
  const std::string huge(1 << 20, 'z');
  EXPECT_EQ(quotedName(huge).size(), kQuotedNameBytes + 5);
  // "é" is two bytes; its first at the limit's last place goes, not half of it.
  const std::string ascii(kQuotedNameBytes - 1, 'a');
  EXPECT_EQ(quotedName(ascii + "é"), "\"" + ascii + "\"...");
  EXPECT_EQ(quotedName(ascii + "a" + "é"), "\"" + ascii + "a\"...");
}

}  // namespace
}  // namespace earshot
