#pragma once
// Text from files, folder listings and datagrams reaches terminals, reports
// and JSON. Any of it may hold control characters (a file named
// "x\n    PROBLEM: none" would forge report lines; ESC sequences would drive
// the terminal), invalid UTF-8 (nlohmann::json throws on it when dumping)
// or be megabytes long (a 200 MB XML text node in an error message).
//
// EscapeText is applied where text leaves lifmcr (the report renderers, the
// commands' error output); Excerpt where a reader quotes input in a message.
// Both are idempotent on their own output (escapes are plain ASCII; '\' is
// left as is so an already escaped text is not escaped twice).

#include <cstddef>
#include <string>
#include <string_view>

namespace lifmcr {

// Printable ASCII and valid UTF-8 stay; "\n", "\r", "\t" become the two
// characters \n, \r, \t; other C0/C1 control characters and DEL become \xNN
// (C1 as \u0085); Unicode bidirectional overrides and isolates become \u202E
// and so on; every byte of an invalid UTF-8 sequence becomes \xNN.
std::string EscapeText(std::string_view text);

// Valid UTF-8 for JSON: invalid bytes become the text \xNN, everything else
// (control characters too; JSON escapes them itself) is kept.
std::string ToValidUtf8(std::string_view text);

// A message-sized quote of user input: EscapeText of at most `max_bytes`
// bytes (cut at a character boundary), then "... (N bytes)" when cut.
std::string Excerpt(std::string_view text, std::size_t max_bytes = 40);

// True when `text` is valid UTF-8 (no overlong forms, surrogates or code
// points above U+10FFFF).
bool IsValidUtf8(std::string_view text);
// Byte offset of the first byte that starts no valid UTF-8 sequence, npos
// when `text` is valid UTF-8.
std::size_t InvalidUtf8At(std::string_view text);

}  // namespace lifmcr
