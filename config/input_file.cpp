#include "config/input_file.h"

#include "config/memory_policy.h"
#include "config/text_escape.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

// Closes on every path out unless released.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }

 private:
  int fd_;
};

std::string Label(const fs::path& path) { return EscapeText(path.string()); }

std::string TypeName(mode_t mode) {
  if (S_ISDIR(mode)) return "is a folder";
  if (S_ISFIFO(mode)) return "is a FIFO (named pipe)";
  if (S_ISCHR(mode)) return "is a character device";
  if (S_ISBLK(mode)) return "is a block device";
  if (S_ISSOCK(mode)) return "is a socket";
  if (S_ISREG(mode)) return "";
  return "is not a regular file";
}

Error OpenError(const fs::path& path, int error, std::string_view what) {
  std::string reason;
  if (error == ENOENT || error == ELOOP || error == ENOTDIR) {
    reason = DescribeMissingPath(path);
    if (reason.empty()) reason = std::strerror(error);
  } else if (error == EACCES || error == EPERM) {
    reason = "permission denied";
  } else {
    reason = std::string("cannot open: ") + std::strerror(error);
  }
  return MakeError(Label(path), 0, 0, reason + "; expected " + std::string(what));
}

// Opens without blocking, checks the type and size, leaves the descriptor
// blocking for the reads.
Expected<InputFile> Open(const fs::path& path, const InputLimits& limits) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY));
  if (fd.get() < 0) return OpenError(path, errno, limits.what);
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0) {
    return MakeError(Label(path), 0, 0, std::string("cannot stat: ") + std::strerror(errno));
  }
  const bool fifo = S_ISFIFO(info.st_mode);
  if (!S_ISREG(info.st_mode) && !(fifo && limits.allow_fifo)) {
    return MakeError(Label(path), 0, 0,
                     TypeName(info.st_mode) + ", expected a regular file holding " +
                         std::string(limits.what));
  }
  const auto size = static_cast<std::uint64_t>(info.st_size);
  if (!fifo && size > limits.max_bytes) {
    return MakeError(Label(path), 0, 0,
                     "is " + FormatBytes(size) + ", more than the " + FormatBytes(limits.max_bytes) +
                         " " + std::string(limits.what) + " can be; is this the right file?");
  }
  const int flags = ::fcntl(fd.get(), F_GETFL);
  if (flags < 0 || ::fcntl(fd.get(), F_SETFL, flags & ~O_NONBLOCK) != 0) {
    return MakeError(Label(path), 0, 0, std::string("cannot set up reading: ") + std::strerror(errno));
  }
  return InputFile{fd.release(), fifo ? 0 : size};
}

}  // namespace

std::string FormatBytes(std::uint64_t bytes) {
  char buffer[48];
  if (bytes < 1024) return std::to_string(bytes) + " bytes";
  const double kib = static_cast<double>(bytes) / 1024.0;
  if (kib < 1024) {
    std::snprintf(buffer, sizeof(buffer), "%.1f KiB", kib);
  } else if (kib < 1024.0 * 1024.0) {
    std::snprintf(buffer, sizeof(buffer), "%.1f MiB", kib / 1024.0);
  } else {
    std::snprintf(buffer, sizeof(buffer), "%.1f GiB", kib / (1024.0 * 1024.0));
  }
  return buffer;
}

std::string DescribeMissingPath(const fs::path& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) == 0) return "";
  const int stat_error = errno;
  if (stat_error == ELOOP) return "a symbolic link loop (too many levels of links)";
  if (stat_error == EACCES) return "permission denied on a folder on the way";
  if (stat_error == ENOTDIR) return "a part of the path is a file, not a folder";
  if (stat_error == ENAMETOOLONG) return "the path is too long";
  if (::lstat(path.c_str(), &info) == 0 && S_ISLNK(info.st_mode)) {
    std::error_code ec;
    const fs::path target = fs::read_symlink(path, ec);
    return "a dangling symbolic link" + (ec ? std::string() : " to '" + EscapeText(target.string()) + "'");
  }
  if (stat_error == ENOENT) return "no such file or folder";
  return std::strerror(stat_error);
}

std::string DescribeNonRegular(const fs::path& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return DescribeMissingPath(path);
  return TypeName(info.st_mode);
}

Status CheckTextEncoding(std::string_view text, const std::string& label, std::string_view what) {
  const auto starts = [&](std::string_view bom) { return text.substr(0, bom.size()) == bom; };
  // UTF-32 first: its little-endian BOM starts with UTF-16's.
  if (starts(std::string_view("\xFF\xFE\0\0", 4)) || starts(std::string_view("\0\0\xFE\xFF", 4))) {
    return MakeError(label, 0, 0,
                     "is UTF-32 text; expected " + std::string(what) +
                         " in UTF-8 (or ASCII): convert it, e.g. iconv -f UTF-32 -t UTF-8");
  }
  if (starts("\xFF\xFE") || starts("\xFE\xFF")) {
    return MakeError(label, 0, 0,
                     "is UTF-16 text; expected " + std::string(what) +
                         " in UTF-8 (or ASCII): convert it, e.g. iconv -f UTF-16 -t UTF-8");
  }
  const std::size_t nul = text.find('\0');
  if (nul != std::string_view::npos) {
    // UTF-16 without a BOM has a NUL in every other byte of ASCII text.
    const bool utf16 = nul <= 1 && text.size() >= 4 && (text[nul + 2] == '\0');
    return MakeError(label, 0, 0,
                     (utf16 ? std::string("looks like UTF-16 text (no byte-order mark)")
                            : "holds a NUL byte at byte " + std::to_string(nul) +
                                  " (binary data)") +
                         "; expected " + std::string(what) + " as UTF-8 text");
  }
  return Status::Ok();
}

Expected<InputFile> OpenInputFile(const fs::path& path, const InputLimits& limits) {
  return Open(path, limits);
}

namespace {

// Follows line breaks through the chunks of a read ('\n', '\r' and "\r\n"
// each end one line) and says where the first line longer than the bound
// starts. Every byte is looked at once; the tokenizers after it do more per
// byte, so this costs a fraction of a parse.
class LineBound {
 public:
  explicit LineBound(std::uint64_t max_line_bytes) : max_(max_line_bytes) {}

  // Scans text[from, to); false once a line is over the bound.
  bool Scan(const std::string& text, std::size_t from, std::size_t to) {
    if (max_ == 0) return true;
    for (std::size_t i = from; i < to; ++i) {
      const char c = text[i];
      if (c == '\n' || c == '\r') {
        // The '\n' of a "\r\n" ends no second line.
        if (!(c == '\n' && previous_cr_)) ++line_;
        line_bytes_ = 0;
        previous_cr_ = c == '\r';
        continue;
      }
      previous_cr_ = false;
      if (++line_bytes_ > max_) return false;
    }
    return true;
  }
  int line() const { return line_; }

 private:
  std::uint64_t max_;
  std::uint64_t line_bytes_ = 0;
  int line_ = 1;
  bool previous_cr_ = false;
};

// Bytes per read(): the line bound stops a one-line file after about this
// much more than the bound; a larger chunk saves no measurable time.
constexpr std::size_t kReadChunkBytes = 1 << 20;

}  // namespace

Expected<std::string> ReadInputText(const fs::path& path, const InputLimits& limits) {
  Expected<InputFile> opened = Open(path, limits);
  if (!opened) return opened.error();
  Fd fd(opened->fd);
  // Never more than the bound plus one byte (to see that there is more):
  // a file that grows after fstat, or a FIFO, cannot exceed it. The whole
  // size is reserved (address space only) and the string grows chunk by
  // chunk inside it, so a read that stops early touched only what it read.
  const std::uint64_t cap = limits.max_bytes + 1;
  const auto expected_size = static_cast<std::size_t>(
      std::min<std::uint64_t>(opened->size_bytes > 0 ? opened->size_bytes + 1 : 64 * 1024, cap));
  std::string text;
  text.reserve(expected_size);
  AdviseHugePages(text.data(), expected_size);  // before the pages are written
  LineBound lines(limits.max_line_bytes);
  std::size_t used = 0;
  while (used < cap) {
    const std::size_t want = static_cast<std::size_t>(
        std::min<std::uint64_t>(kReadChunkBytes, cap - used));
    // Within the reservation this only zero-fills the new chunk; past it
    // (a file that grew, a FIFO) the string reallocates geometrically.
    if (text.size() < used + want) text.resize(used + want);
    const ssize_t got = ::read(fd.get(), text.data() + used, want);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) {
      return MakeError(Label(path), 0, 0,
                       std::string("read failed: ") + std::strerror(errno) + " (" +
                           (errno == EISDIR ? "a folder" : "expected " + std::string(limits.what)) +
                           ")");
    }
    if (got == 0) break;
    if (!lines.Scan(text, used, used + static_cast<std::size_t>(got))) {
      return MakeError(Label(path), lines.line(), 0,
                       "a line longer than " + FormatBytes(limits.max_line_bytes) +
                           ", more than a line of " + std::string(limits.what) +
                           " can be; is this the right file?");
    }
    used += static_cast<std::size_t>(got);
  }
  if (used > limits.max_bytes) {
    return MakeError(Label(path), 0, 0,
                     "holds more than the " + FormatBytes(limits.max_bytes) + " " +
                         std::string(limits.what) + " can be; is this the right file?");
  }
  text.resize(used);
  if (Status s = CheckTextEncoding(text, Label(path), limits.what); !s) return s.error();
  return text;
}

}  // namespace lifmcr
