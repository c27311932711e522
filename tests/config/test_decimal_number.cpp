// config/decimal_number.h: an underflow is a finite number that rounds to
// zero; only an overflow is out of range.

#include "config/decimal_number.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace lifmcr {
namespace {

std::from_chars_result Parse(const std::string& text, double* value) {
  return FromCharsRounded(text.data(), text.data() + text.size(), *value);
}

TEST(DecimalNumber, UnderflowIsZeroOverflowIsOutOfRange) {
  for (const std::string text :
       {"1e-400", "-1e-400", "2e-324", "0.0000001e-320", "123e-99999999999999999999"}) {
    double value = 42;
    const auto [end, ec] = Parse(text, &value);
    EXPECT_EQ(ec, std::errc()) << text;
    EXPECT_EQ(end, text.data() + text.size()) << text;
    EXPECT_EQ(value, 0.0) << text;
    EXPECT_FALSE(std::signbit(value)) << text;
  }
  for (const std::string text : {"1e400", "-1e400", "0.5e309", "1000e306", "1e99999999999999999999"}) {
    double value = 42;
    EXPECT_EQ(Parse(text, &value).ec, std::errc::result_out_of_range) << text;
  }
  // Everything else as std::from_chars: subnormals, ordinary numbers, junk.
  double value = 0;
  EXPECT_EQ(Parse("1e-310", &value).ec, std::errc());
  EXPECT_EQ(value, 1e-310);
  EXPECT_EQ(Parse("-12.5e3", &value).ec, std::errc());
  EXPECT_EQ(value, -12500.0);
  EXPECT_EQ(Parse("0e-999", &value).ec, std::errc());
  EXPECT_EQ(value, 0.0);
  EXPECT_EQ(Parse("x1", &value).ec, std::errc::invalid_argument);
  const std::string trailing = "1e-400mm";
  const auto [end, ec] = Parse(trailing, &value);
  EXPECT_EQ(ec, std::errc());
  EXPECT_EQ(end, trailing.data() + 6);  // the caller sees the junk after the number
}

}  // namespace
}  // namespace lifmcr
