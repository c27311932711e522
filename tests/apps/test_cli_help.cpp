// Every subcommand's --help ends with what it reads, what it writes and its
// exit codes, and `lifmcr --help` lists only subcommands that run.

#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

TEST(CliHelp, EverySubcommandSaysWhatItReadsWritesAndReturns) {
  const test::CommandResult top = test::RunLifmcr("--help");
  ASSERT_EQ(top.exit_code, 0) << top.err;
  const std::string subcommands = top.out.substr(top.out.find("Subcommands:"));
  std::vector<std::string> names;
  const std::regex row(R"(\n  ([a-z]+) )");
  for (auto it = std::sregex_iterator(subcommands.begin(), subcommands.end(), row);
       it != std::sregex_iterator(); ++it)
    names.push_back((*it)[1]);
  ASSERT_GE(names.size(), 9u) << top.out;
  for (const std::string& name : names) {
    const test::CommandResult help = test::RunLifmcr(name + " --help");
    EXPECT_EQ(help.exit_code, 0) << name;
    const std::string& text = help.out;
    const std::size_t reads = text.find("Reads:"), writes = text.find("Writes:"),
                      codes = text.find("Exit codes:");
    EXPECT_NE(reads, std::string::npos) << name << "\n" << text;
    EXPECT_NE(writes, std::string::npos) << name << "\n" << text;
    EXPECT_NE(codes, std::string::npos) << name << "\n" << text;
    // The exit codes come last, after the options.
    EXPECT_GT(codes, text.find("Options:")) << name;
  }
}

}  // namespace
}  // namespace lifmcr
