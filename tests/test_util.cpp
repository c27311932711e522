#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>
#include <sys/wait.h>
#include <unistd.h>

namespace lifmcr::test {

std::filesystem::path SamplePath(const std::string& name) {
  return std::filesystem::path(LIFMCR_SAMPLES_DIR) / name;
}

std::filesystem::path LifmcrBinary() { return LIFMCR_BINARY; }

TempDir::TempDir() {
  std::random_device device;
  const auto base = std::filesystem::temp_directory_path();
  for (int attempt = 0; attempt < 100; ++attempt) {
    auto candidate =
        base / ("lifmcr_test_" + std::to_string(::getpid()) + "_" + std::to_string(device()));
    if (std::filesystem::create_directory(candidate)) {
      path_ = candidate;
      return;
    }
  }
  throw std::runtime_error("cannot create a temporary directory under " + base.string());
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream content;
  content << in.rdbuf();
  return content.str();
}

void WriteFile(const std::filesystem::path& path, const std::string& content) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << content;
}

std::string ReadSample(const std::string& name) { return ReadFile(SamplePath(name)); }

std::string ReplaceFirst(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "fixture text not found: " << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

void ExpectMessageHas(const Error& error, const std::vector<std::string>& parts) {
  for (const std::string& part : parts) {
    EXPECT_NE(error.message.find(part), std::string::npos)
        << "message: " << error.message << "\nmissing: " << part;
  }
}

CommandResult RunLifmcr(const std::string& args) {
  TempDir dir;
  const auto out_path = dir / "stdout";
  const auto err_path = dir / "stderr";
  const std::string command = "'" + LifmcrBinary().string() + "' " + args + " >'" +
                              out_path.string() + "' 2>'" + err_path.string() + "'";
  const int status = std::system(command.c_str());
  CommandResult result;
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = ReadFile(out_path);
  result.err = ReadFile(err_path);
  return result;
}

std::string MulticastGroupOfThisProcess(int octet) {
  const unsigned pid = static_cast<unsigned>(getpid());
  return "239." + std::to_string(octet) + "." + std::to_string(pid / 250 % 250 + 1) + "." +
         std::to_string(pid % 250 + 1);
}

int MulticastPortOfThisProcess() { return 20000 + static_cast<int>(getpid() % 40000); }

}  // namespace lifmcr::test
