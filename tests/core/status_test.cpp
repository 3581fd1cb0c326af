// quotedName, displayPath and Status: names, paths and messages from input
// in one bounded line.
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
  // The C1 controls (valid UTF-8): U+009B is CSI to some terminals.
  EXPECT_EQ(quotedName("\xC2\x9B" "2J\xC2\x80\xC2\xA0"), "\"\\u009b2J\\u0080\xC2\xA0\"");
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

// A path a user types is shown as it is; one from a file that holds a
// control character, a quote or a backslash is quoted (and cut at PATH_MAX).
TEST(DisplayPath, OnlyAnUnusualPathIsQuoted) {
  EXPECT_EQ(displayPath("/home/ann/Räume/room 1.gltf"), "/home/ann/Räume/room 1.gltf");
  EXPECT_EQ(displayPath("dir/x\nearshot: error: forged.bin"), "\"dir/x\\nearshot: error: forged.bin\"");
  EXPECT_EQ(displayPath("a\"b"), "\"a\\\"b\"");
  EXPECT_EQ(displayPath("a\xFF"), "\"a\xEF\xBF\xBD\"");
  EXPECT_EQ(displayPath(std::string(1 << 20, 'p')).size(), kQuotedPathBytes + 5);
}

// Whatever goes into a Status's message comes out one line of valid UTF-8:
// control characters escaped, bytes that are not UTF-8 replaced, the rest
// (quotes, backslashes, UTF-8) as it was.
TEST(StatusMessage, IsOneLineWhateverWentIn) {
  EXPECT_EQ(invalidArgument("plain \"quoted\" C:\\dir é").message(), "plain \"quoted\" C:\\dir é");
  EXPECT_EQ(notFound("x\nearshot: error: forged").message(), "x\\nearshot: error: forged");
  EXPECT_EQ(ioError(std::string("\x1b[2J\r\"q\"\\", 9)).message(), "\\u001b[2J\\r\"q\"\\");
  EXPECT_EQ(parseError("a\x80" "b").message(), "a\xEF\xBF\xBD" "b");
  EXPECT_EQ(Status(StatusCode::kInternal, std::string("n\0l", 3)).message(), "n\\u0000l");
  EXPECT_EQ(ioError("csi \xC2\x9B" "2J").message(), "csi \\u009b2J");
  EXPECT_TRUE(Status::ok().message().empty());
}

}  // namespace
}  // namespace earshot
