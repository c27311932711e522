#pragma once
// A view that fits the terminal it is drawn in (`lifmcr monitor`): the size
// from the terminal itself (TIOCGWINSZ), else $COLUMNS/$LINES, else 80x24;
// lines clipped to the width and the view to the height, so nothing wraps
// or scrolls and a redraw from the top-left corner overwrites the last one.

#include <string>

namespace lifmcr::apps {

struct TerminalSize {
  int columns = 80;
  int rows = 24;
};

TerminalSize QueryTerminalSize(int fd);

// `view` (lines separated by '\n', ASCII) cut to size.columns characters per
// line and to size.rows - 1 lines (the last row stays empty, so the cursor
// never scrolls the screen); when lines are cut off, the last kept line says
// how many.
std::string FitToTerminal(const std::string& view, TerminalSize size);

// The escape sequences that draw `fitted` over the previous frame: cursor
// home, each line cleared to its end, the rest of the screen cleared.
std::string DrawFrame(const std::string& fitted);

}  // namespace lifmcr::apps
