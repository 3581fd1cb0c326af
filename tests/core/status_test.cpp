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
