// core::format_names: the list a one-line message names, cut after `most`.
#include <gtest/gtest.h>

#include "core/log.h"

using namespace ddhgs;

TEST(Log, FormatNames) {
  EXPECT_EQ(core::format_names({}), "");
  EXPECT_EQ(core::format_names({"a"}), "a");
  EXPECT_EQ(core::format_names({"a", "b", "c", "d", "e"}), "a, b, c, d, e");
  EXPECT_EQ(core::format_names({"a", "b", "c", "d", "e", "f", "g"}), "a, b, c, d, e and 2 more");
  EXPECT_EQ(core::format_names({"a", "b", "c"}, 1), "a and 2 more");
}
