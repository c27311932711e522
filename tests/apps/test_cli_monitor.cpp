// `lifmcr monitor` in a pseudo-terminal of 80x24, as over ssh: every frame it
// draws fits (no line wider than the terminal, no more lines than it has),
// and after the terminal shrinks to 40x6 (SIGWINCH) the frames fit the new
// size. Also the pure parts: clipping and the note on lines cut off.

#include "apps/terminal.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <poll.h>
#include <pty.h>
#include <regex>
#include <string>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace lifmcr::apps {
namespace {

TEST(Terminal, FitClipsLinesAndSaysWhatIsCutOff) {
  const std::string view = "0123456789\nab\n" + std::string(3, 'x') + "\nfour\nfive\n";
  EXPECT_EQ(FitToTerminal(view, {4, 24}), "0123\nab\nxxx\nfour\nfive\n");
  const std::string small = FitToTerminal(view, {80, 4});  // 3 lines fit
  EXPECT_EQ(small, "0123456789\nab\n(3 more lines: enlarge the terminal)\n");
  EXPECT_EQ(DrawFrame("a\nb\n"), "\x1b[Ha\x1b[K\nb\x1b[K\n\x1b[J");
}

// The frames (cursor home to clear-to-end) of a terminal stream, with
// every escape sequence removed.
std::vector<std::vector<std::string>> Frames(const std::string& stream) {
  std::vector<std::vector<std::string>> frames;
  std::size_t at = 0;
  while ((at = stream.find("\x1b[H", at)) != std::string::npos) {
    at += 3;
    const std::size_t end = stream.find("\x1b[H", at);
    std::string text = stream.substr(at, end == std::string::npos ? std::string::npos : end - at);
    text = text.substr(0, text.find("\x1b[J"));  // a frame ends by clearing the rest
    text = std::regex_replace(text, std::regex("\x1b\\[[0-9;?]*[A-Za-z]"), "");
    std::vector<std::string> lines;
    std::size_t start = 0;
    for (std::size_t nl; (nl = text.find('\n', start)) != std::string::npos; start = nl + 1) {
      std::string line = text.substr(start, nl - start);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      lines.push_back(line);
    }
    if (start < text.size()) lines.push_back(text.substr(start));
    frames.push_back(lines);
  }
  return frames;
}

TEST(CliMonitor, FitsAnEightyByTwentyFourTerminalAndFollowsAResize) {
  winsize size{};
  size.ws_col = 80;
  size.ws_row = 24;
  int master = -1;
  const pid_t child = forkpty(&master, nullptr, nullptr, &size);
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string binary = test::LifmcrBinary().string();
    execl(binary.c_str(), binary.c_str(), "monitor", "--lcm", "memq://", "--duration", "3",
          nullptr);
    _exit(127);
  }
  std::string before, after;
  bool resized = false;
  for (;;) {
    pollfd fd{master, POLLIN, 0};
    if (poll(&fd, 1, 100) > 0) {
      char buffer[4096];
      const ssize_t n = read(master, buffer, sizeof buffer);
      if (n <= 0) break;  // the child exited: EIO on the master
      (resized ? after : before).append(buffer, static_cast<std::size_t>(n));
    }
    // Resized once a whole first frame is drawn (it ends by clearing the
    // rest of the screen), not after a fixed time: a loaded host may take
    // longer than that to start the binary.
    if (!resized && before.find("\x1b[J") != std::string::npos) {
      size.ws_col = 40;
      size.ws_row = 6;
      ASSERT_EQ(ioctl(master, TIOCSWINSZ, &size), 0);  // the kernel sends SIGWINCH
      resized = true;
    }
  }
  int status = 0;
  waitpid(child, &status, 0);
  close(master);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  const auto first = Frames(before), second = Frames(after);
  ASSERT_FALSE(first.empty()) << before;
  ASSERT_FALSE(second.empty()) << after;
  for (const auto& frame : first) {
    EXPECT_LE(frame.size(), 23u);
    for (const std::string& line : frame) EXPECT_LE(line.size(), 80u) << line;
  }
  bool clipped = false;
  for (const auto& frame : second) {
    EXPECT_LE(frame.size(), 5u);
    for (const std::string& line : frame) {
      EXPECT_LE(line.size(), 40u) << line;
      clipped = clipped || line.size() == 40;
    }
  }
  // The header line is longer than 40 columns: it was cut, not wrapped.
  EXPECT_TRUE(clipped) << after;
  EXPECT_NE(second.back().back().find("more lines"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr::apps
