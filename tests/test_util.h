#pragma once
// Helpers shared by every test: where the real sample files are, a temporary
// folder that cleans up after itself, and running the built `lifmcr`.

#include "config/error.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::test {

// Path of a file in tests/data/samples (their origins: tests/data/samples/SOURCES.md).
std::filesystem::path SamplePath(const std::string& name);

// Path of the built `lifmcr` executable.
std::filesystem::path LifmcrBinary();

// A fresh directory under the system temp dir, removed on destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

std::string ReadFile(const std::filesystem::path& path);
// The content of a file in tests/data/samples.
std::string ReadSample(const std::string& name);
// `text` with the first occurrence of `from` replaced by `to`; a test failure
// when `from` is absent (the fixture no longer says what the test thinks).
std::string ReplaceFirst(std::string text, const std::string& from, const std::string& to);
// A test failure for every part the error message lacks.
void ExpectMessageHas(const Error& error, const std::vector<std::string>& parts);
void WriteFile(const std::filesystem::path& path, const std::string& content);

struct CommandResult {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};
// Runs `lifmcr <args>` (args are passed to /bin/sh, quote them yourself).
CommandResult RunLifmcr(const std::string& args);

// An administratively scoped multicast group (239.<octet>.x.y) of this
// process's own: two checkouts' suites running one test at once on one host
// would otherwise receive each other's LCM messages. octet (1..254) keeps
// tests apart from each other.
std::string MulticastGroupOfThisProcess(int octet);
// A UDP port of this process's own (20000..59999), for the same reason: LCM
// binds its receive socket to INADDR_ANY:port, and Linux delivers to it every
// datagram for that port of ANY group some socket on the host joined
// (IP_MULTICAST_ALL), so a group of one's own is not enough on a shared port.
int MulticastPortOfThisProcess();

}  // namespace lifmcr::test
