#pragma once
// Reading decimal numbers from text files (Vicon CSV, MLA XML, VSK, YAML).
// std::from_chars reports a number too small for a double (1e-400) and one
// too large (1e400) alike, as result_out_of_range. The first is a finite
// number that rounds to zero, as strtod rounds it; only the second cannot be
// held. Every reader of the formats above goes through this one function so
// that 1e-400 means 0 in all of them and only an overflow is an error.

#include <charconv>

namespace lifmcr {

// std::from_chars(first, last, value) in the general format, except that a
// number whose magnitude is below the smallest subnormal double reads as 0
// (positive zero, so a report never prints "-0") with ec == std::errc().
// result_out_of_range then means an overflow only.
std::from_chars_result FromCharsRounded(const char* first, const char* last, double& value);

}  // namespace lifmcr
