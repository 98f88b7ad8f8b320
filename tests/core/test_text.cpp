// core::quoted_value and core::printable: how a user's value appears in a message.
#include <gtest/gtest.h>

#include "core/text.h"

namespace ddhgs::core {
namespace {

TEST(Text, QuotedKeepsShortValuesWhole) {
  EXPECT_EQ(quoted_value("550"), "'550'");
  EXPECT_EQ(quoted_value(""), "''");
  EXPECT_EQ(quoted_value(std::string(kQuotedChars, 'a')),
            "'" + std::string(kQuotedChars, 'a') + "'");
}

TEST(Text, QuotedClipsLongValuesAndCountsTheRest) {
  const std::string number(50'000'000, '9');
  const std::string shown = quoted_value(number);
  EXPECT_EQ(shown, "'" + std::string(kQuotedChars, '9') + "...' (and 49999920 more characters)");
  // One past the limit is clipped too.
  EXPECT_EQ(quoted_value(std::string(kQuotedChars + 1, 'x')),
            "'" + std::string(kQuotedChars, 'x') + "...' (and 1 more characters)");
}

TEST(Text, QuotedNeverSplitsAUtf8Character) {
  // 79 ASCII bytes then "é" (2 bytes): the cut at 80 would fall inside it.
  const std::string value = std::string(79, 'a') + "\xC3\xA9" + std::string(10, 'b');
  EXPECT_EQ(quoted_value(value), "'" + std::string(79, 'a') + "...' (and 12 more characters)");
}

TEST(Text, ControlCharactersAreEscapesNotCuts) {
  const std::string with_nul(
      "1\0"
      "2",
      3);
  EXPECT_EQ(quoted_value(with_nul), "'1\\02'");
  EXPECT_EQ(printable("a\tb\nc\rd\x1b"
                      "e\x7f"),
            "a\\tb\\nc\\rd\\x1be\\x7f");
  // UTF-8 passes as it is.
  EXPECT_EQ(printable("\xC3\xA9"), "\xC3\xA9");
  // A NUL no longer ends the text: what follows it is still there.
  EXPECT_NE(("cell " + quoted_value(with_nul) + " is not a number").find("is not a number"),
            std::string::npos);
}

}  // namespace
}  // namespace ddhgs::core
