#include "config/error.h"

namespace lifmcr {

Error MakeError(const std::string& file, int line, int column, const std::string& what) {
  std::string message = file;
  if (line > 0) {
    message += ":" + std::to_string(line);
    if (column > 0) message += ":" + std::to_string(column);
  }
  message += ": " + what;
  return Error{std::move(message)};
}

Error MakeErrorAt(const std::string& file, const std::string& where, const std::string& what) {
  return Error{file + ": " + where + ": " + what};
}

}  // namespace lifmcr
