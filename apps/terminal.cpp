#include "apps/terminal.h"

#include <cstdlib>
#include <sstream>
#include <sys/ioctl.h>
#include <vector>

namespace lifmcr::apps {
namespace {

int EnvInt(const char* name) {
  const char* text = std::getenv(name);
  if (text == nullptr) return 0;
  const int value = std::atoi(text);
  return value > 0 && value < 10000 ? value : 0;
}

}  // namespace

TerminalSize QueryTerminalSize(int fd) {
  TerminalSize size;
  winsize ws{};
  if (ioctl(fd, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0 && ws.ws_row > 0) {
    size.columns = ws.ws_col;
    size.rows = ws.ws_row;
    return size;
  }
  if (const int c = EnvInt("COLUMNS")) size.columns = c;
  if (const int r = EnvInt("LINES")) size.rows = r;
  return size;
}

std::string FitToTerminal(const std::string& view, TerminalSize size) {
  const int columns = size.columns > 0 ? size.columns : 80;
  const int max_lines = std::max(1, size.rows - 1);
  std::vector<std::string> lines;
  std::istringstream in(view);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  const bool cut = static_cast<int>(lines.size()) > max_lines;
  if (cut) {
    const int hidden = static_cast<int>(lines.size()) - (max_lines - 1);
    lines.resize(max_lines - 1);
    lines.push_back("(" + std::to_string(hidden) + " more lines: enlarge the terminal)");
  }
  std::string out;
  for (const std::string& line : lines) {
    out.append(line, 0, static_cast<std::size_t>(columns));
    out += '\n';
  }
  return out;
}

std::string DrawFrame(const std::string& fitted) {
  std::string frame = "\x1b[H";
  for (char c : fitted) {
    if (c == '\n') frame += "\x1b[K";
    frame += c;
  }
  return frame + "\x1b[J";
}

}  // namespace lifmcr::apps
