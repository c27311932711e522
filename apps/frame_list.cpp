#include "apps/frame_list.h"

#include "config/text_escape.h"

#include <algorithm>
#include <charconv>

namespace lifmcr::apps {
namespace {
constexpr std::size_t kMaxFrames = 1'000'000;
}  // namespace

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
      return Error{option + ": expected frame numbers and ranges such as 0-9,12, got '" +
                   EscapeText(part.substr(0, 40)) + (part.size() > 40 ? "...'" : "'")};
    // Bounded before it is expanded: "0-99999999999" is a typo, not a
    // request for 10^11 frames (a sequence of a day at 10 Hz has 864000).
    const auto listed = static_cast<std::size_t>(b - a) + 1;
    if (listed > kMaxFrames || frames.size() + listed > kMaxFrames)
      return Error{option + ": " + std::to_string(frames.size() + listed) +
                   "+ frames listed, more than " + std::to_string(kMaxFrames) +
                   "; expected at most that many"};
    for (std::int64_t f = a; f <= b; ++f) frames.insert(f);
    at = end + 1;
  }
  return frames;
}

}  // namespace lifmcr::apps
