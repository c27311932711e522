#pragma once
// The one way lifmcr opens a file a user names or a folder holds (MLA XML,
// VSK, Vicon CSV, rig and intrinsics YAML, raw BMP). Bad input must give a
// clear error, never a hang, an unbounded read or a misleading message:
//
// - Only a regular file is read; a FIFO only where the caller streams
//   (InputLimits::allow_fifo). Folders, FIFOs, devices (/dev/zero through a
//   link), sockets, symlink loops, missing and unreadable paths each get
//   their own message ("is a folder, expected <what>").
// - The size is checked against the format's bound (InputLimits::max_bytes)
//   from fstat, before a byte is read; the read itself stops at the bound
//   too, so a file that grows while it is read cannot exhaust memory.
// - Opening never blocks: O_NONBLOCK until the type is known (opening a FIFO
//   with no writer would otherwise wait forever).
// - A text format may bound its lines (InputLimits::max_line_bytes): the
//   read stops at the first longer line, so a file that is one huge line
//   costs the bound, not the file ("<path>:<line>: a line longer than ...").
// - Text formats are UTF-8 (or ASCII): a UTF-16/UTF-32 byte-order mark or a
//   NUL byte is "UTF-16 text" or "binary data", not a confusing parse error.
//
// Every error reads "<path>: <what>, expected <what the caller reads>".

#include "config/error.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace lifmcr {

struct InputLimits {
  std::string_view what;          // "an MLA calibration XML (RayCalibData)", for messages
  std::uint64_t max_bytes = 0;    // the format's size bound; a larger file is an error
  bool allow_fifo = false;        // streaming readers may take a named pipe
  // ReadInputText only: the longest line the format can hold (bytes between
  // line breaks, '\n', '\r' or both); 0 for no bound.
  std::uint64_t max_line_bytes = 0;
};

// Reads a whole text file (see above). Also rejects UTF-16/32 and binary
// (NUL bytes) content; a UTF-8 byte-order mark is kept for the parser.
Expected<std::string> ReadInputText(const std::filesystem::path& path, const InputLimits& limits);

// An open descriptor of a checked regular file (binary formats read it
// with pread). The caller owns `fd` and closes it.
struct InputFile {
  int fd = -1;
  std::uint64_t size_bytes = 0;
};
Expected<InputFile> OpenInputFile(const std::filesystem::path& path, const InputLimits& limits);

// What is wrong with a path that should exist, from lstat/stat: "no such file
// or folder", "a symbolic link loop", "a dangling symbolic link to '...'",
// "permission denied on a parent folder", or empty when it exists.
std::string DescribeMissingPath(const std::filesystem::path& path);

// "is a folder", "is a FIFO (named pipe)", "is a character device", ... for a
// path that exists but is not a regular file; empty for a regular file.
std::string DescribeNonRegular(const std::filesystem::path& path);

// "12.5 MiB" style size for messages.
std::string FormatBytes(std::uint64_t bytes);

// Text checks shared by ReadInputText and the parsers that take text from
// memory: a UTF-16/32 BOM or a NUL byte is an error naming the byte offset.
Status CheckTextEncoding(std::string_view text, const std::string& label, std::string_view what);

}  // namespace lifmcr
