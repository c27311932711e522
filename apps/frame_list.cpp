#include "apps/frame_list.h"

#include <algorithm>
#include <charconv>

namespace lifmcr::apps {

Expected<std::set<std::int64_t>> ParseFrameList(const std::string& text, const std::string& option) {
  std::set<std::int64_t> frames;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    const std::string part = text.substr(at, end - at);
    const std::size_t dash = part.find('-', 1);
    std::int64_t a = 0, b = 0;
    auto parse = [](const std::string& s, std::int64_t* v) {
      const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
      return ec == std::errc() && p == s.data() + s.size() && *v >= 0;
    };
    const bool ok = dash == std::string::npos
                        ? parse(part, &a) && (b = a, true)
                        : parse(part.substr(0, dash), &a) && parse(part.substr(dash + 1), &b);
    if (!ok || b < a)
      return Error{option + ": expected frame numbers and ranges such as 0-9,12, got '" + part +
                   "'"};
    for (std::int64_t f = a; f <= b; ++f) frames.insert(f);
    at = end + 1;
  }
  return frames;
}

}  // namespace lifmcr::apps
