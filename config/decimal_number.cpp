#include "config/decimal_number.h"

#include <cstdint>
#include <system_error>

namespace lifmcr {
namespace {

bool IsDigit(char c) { return c >= '0' && c <= '9'; }

// True when the number in [first, last) (a span from_chars matched) has
// magnitude below 1: its first non-zero digit sits after the decimal point
// once the exponent is applied. Such a number can only underflow.
bool BelowOne(const char* first, const char* last) {
  const char* p = first;
  if (p < last && (*p == '-' || *p == '+')) ++p;
  std::int64_t integer_digits = 0;  // significant digits before the point
  std::int64_t leading_zeros = 0;   // zeros after the point before the first non-zero digit
  bool seen_nonzero = false;
  for (; p < last && IsDigit(*p); ++p) {
    if (*p != '0') seen_nonzero = true;
    if (seen_nonzero) ++integer_digits;
  }
  if (p < last && *p == '.') {
    for (++p; p < last && IsDigit(*p); ++p) {
      if (*p != '0') seen_nonzero = true;
      if (!seen_nonzero) ++leading_zeros;
    }
  }
  if (!seen_nonzero) return true;  // zero: from_chars does not report it out of range
  std::int64_t exponent = 0;
  if (p < last && (*p == 'e' || *p == 'E')) {
    ++p;
    const bool negative = p < last && *p == '-';
    if (p < last && (*p == '-' || *p == '+')) ++p;
    // Saturated: any exponent past a billion decides alone.
    for (; p < last && IsDigit(*p); ++p)
      if (exponent < 1000000000) exponent = exponent * 10 + (*p - '0');
    if (negative) exponent = -exponent;
  }
  // The decimal exponent of the first significant digit.
  const std::int64_t magnitude =
      integer_digits > 0 ? integer_digits - 1 + exponent : -(leading_zeros + 1) + exponent;
  return magnitude < 0;
}

}  // namespace

std::from_chars_result FromCharsRounded(const char* first, const char* last, double& value) {
  std::from_chars_result result = std::from_chars(first, last, value);
  if (result.ec == std::errc::result_out_of_range && BelowOne(first, result.ptr)) {
    value = 0.0;
    result.ec = std::errc();
  }
  return result;
}

}  // namespace lifmcr
