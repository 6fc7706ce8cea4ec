#include "dicom/decimal_string.h"

#include <gtest/gtest.h>

namespace typemerge::dicom {
namespace {

TEST(DecimalString, ParsesDicomDecimals) {
  EXPECT_DOUBLE_EQ(*parse_decimal("1.0742"), 1.0742);
  EXPECT_DOUBLE_EQ(*parse_decimal(" +18.5 "), 18.5);
  EXPECT_DOUBLE_EQ(*parse_decimal("-1.5e2"), -150.0);
  EXPECT_DOUBLE_EQ(*parse_decimal("3"), 3.0);
}

TEST(DecimalString, RejectsNonFiniteAndGarbage) {
  for (const char* text : {"NaN", "nan", "inf", "-Infinity", "", "  ", "1,5", "0x10", "1e999",
                           "abc", "1.0.0"}) {
    EXPECT_FALSE(parse_decimal(text).has_value()) << text;
  }
}

TEST(DecimalString, ListNeedsExactCount) {
  const auto pair = parse_decimal_list("0.488\\0.488", 2);
  ASSERT_TRUE(pair.has_value());
  EXPECT_DOUBLE_EQ((*pair)[1], 0.488);
  EXPECT_FALSE(parse_decimal_list("0.488", 2).has_value());
  EXPECT_FALSE(parse_decimal_list("1\\2\\3", 2).has_value());
  EXPECT_FALSE(parse_decimal_list("1\\NaN", 2).has_value());
}

TEST(DecimalString, IntegerStrings) {
  EXPECT_EQ(*parse_integer(" 42 "), 42);
  EXPECT_EQ(*parse_integer("+7"), 7);
  EXPECT_FALSE(parse_integer("4.2").has_value());
  EXPECT_FALSE(parse_integer("").has_value());
}

}  // namespace
}  // namespace typemerge::dicom
