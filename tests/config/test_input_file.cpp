// config/input_file.h and config/text_escape.h: what every reader relies on
// to refuse bad input clearly (issue 17).

#include "config/input_file.h"
#include "config/text_escape.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sys/stat.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

const InputLimits kText{"a test file", 1000};

std::string ErrorOf(const fs::path& path, const InputLimits& limits = kText) {
  Expected<std::string> text = ReadInputText(path, limits);
  EXPECT_FALSE(text.ok()) << path;
  return text.ok() ? "" : text.error().message;
}

TEST(InputFile, ReadsARegularFile) {
  test::TempDir dir;
  test::WriteFile(dir / "a.txt", "hello");
  Expected<std::string> text = ReadInputText(dir / "a.txt", kText);
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_EQ(*text, "hello");
  test::WriteFile(dir / "empty.txt", "");
  EXPECT_EQ(*ReadInputText(dir / "empty.txt", kText), "");
}

TEST(InputFile, NamesWhatIsThereInsteadOfAFile) {
  test::TempDir dir;
  fs::create_directory(dir / "folder");
  mkfifo((dir / "fifo").c_str(), 0600);
  fs::create_symlink("/dev/zero", dir / "zero");
  fs::create_symlink("loop", dir / "loop");
  fs::create_symlink("nowhere", dir / "dangling");
  test::WriteFile(dir / "file", "x");
  const std::pair<std::string, std::string> cases[] = {
      {"folder", "is a folder, expected a regular file holding a test file"},
      {"fifo", "is a FIFO (named pipe), expected a regular file"},
      {"zero", "is a character device, expected a regular file"},
      {"loop", "a symbolic link loop"},
      {"dangling", "a dangling symbolic link to 'nowhere'"},
      {"missing", "no such file or folder; expected a test file"},
      {"file/below", "a part of the path is a file, not a folder"},
  };
  for (const auto& [name, expected] : cases) {
    const std::string message = ErrorOf(dir / name);
    EXPECT_NE(message.find((dir / name).string()), std::string::npos) << message;
    EXPECT_NE(message.find(expected), std::string::npos) << name << ": " << message;
  }
}

TEST(InputFile, FifoOnlyWhereStreamingIsMeantAndNeverBlocksOnOpen) {
  test::TempDir dir;
  mkfifo((dir / "fifo").c_str(), 0600);
  // Opening a FIFO without a writer would block; OpenInputFile must not.
  InputLimits streaming = kText;
  streaming.allow_fifo = true;
  Expected<InputFile> opened = OpenInputFile(dir / "fifo", streaming);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  close(opened->fd);
}

TEST(InputFile, SizeBoundCheckedBeforeReading) {
  test::TempDir dir;
  test::WriteFile(dir / "big", "");
  fs::resize_file(dir / "big", 10ull << 30);  // sparse 10 GiB
  EXPECT_NE(ErrorOf(dir / "big").find("is 10.0 GiB, more than the 1000 bytes a test file can be"),
            std::string::npos);
}

TEST(InputFile, Utf16Utf32AndBinaryAreNamed) {
  test::TempDir dir;
  test::WriteFile(dir / "le", std::string("\xFF\xFEh\0i\0", 6));
  test::WriteFile(dir / "be", std::string("\xFE\xFF\0h\0i", 6));
  test::WriteFile(dir / "nobom", std::string("h\0i\0!\0", 6));
  test::WriteFile(dir / "utf32", std::string("\xFF\xFE\0\0h\0\0\0", 8));
  test::WriteFile(dir / "bin", std::string("abc\0def", 7));
  EXPECT_NE(ErrorOf(dir / "le").find("is UTF-16 text"), std::string::npos);
  EXPECT_NE(ErrorOf(dir / "be").find("is UTF-16 text"), std::string::npos);
  EXPECT_NE(ErrorOf(dir / "nobom").find("looks like UTF-16 text"), std::string::npos);
  EXPECT_NE(ErrorOf(dir / "utf32").find("is UTF-32 text"), std::string::npos);
  EXPECT_NE(ErrorOf(dir / "bin").find("NUL byte at byte 3"), std::string::npos);
}

// Bytes this process has read through read() so far (/proc/self/io rchar).
std::uint64_t BytesReadSoFar() {
  const std::string io = test::ReadFile("/proc/self/io");
  const std::size_t at = io.find("rchar: ");
  return at == std::string::npos ? 0 : std::stoull(io.substr(at + 7));
}

TEST(InputFile, LineBoundNamesTheLineWithEveryKindOfLineBreak) {
  test::TempDir dir;
  InputLimits limits = kText;
  limits.max_line_bytes = 4;
  const std::pair<std::string, std::string> cases[] = {
      {"1234\n1234\n12345\n", ":3: a line longer than 4 bytes, more than a line of a test file"},
      {"1234\r\n1234\r\n12345\r\n", ":3: a line longer"},
      {"1234\r1234\r\r12345", ":4: a line longer"},  // lone CRs, an empty line
      {"12345", ":1: a line longer"},
  };
  for (const auto& [content, expected] : cases) {
    test::WriteFile(dir / "t", content);
    const std::string message = ErrorOf(dir / "t", limits);
    EXPECT_NE(message.find((dir / "t").string() + expected), std::string::npos)
        << EscapeText(content) << ": " << message;
  }
  // At the bound, with every kind of break, the text comes back whole.
  test::WriteFile(dir / "ok", "1234\r\n1234\r1234\n\n1234");
  Expected<std::string> text = ReadInputText(dir / "ok", limits);
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_EQ(*text, "1234\r\n1234\r1234\n\n1234");
}

TEST(InputFile, LineBoundStopsReadingAtTheLongLine) {
  test::TempDir dir;
  // Many short lines across several read chunks, a CRLF split across a
  // chunk boundary (1 MiB), then one line of 64 MiB.
  std::string lines;
  while (lines.size() < (3u << 20)) lines += "0123456789abcde\r\n";
  lines.resize((1u << 20) - 1);
  lines += "\r\nx";
  while (lines.size() < (3u << 20)) lines += "0123456789abcde\n";
  const std::size_t short_lines = 1 + static_cast<std::size_t>(std::count(lines.begin(), lines.end(), '\n'));
  InputLimits limits{"a test file", 128u << 20, false, 4096};
  test::WriteFile(dir / "lines", lines);
  Expected<std::string> text = ReadInputText(dir / "lines", limits);
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_EQ(*text, lines);

  test::WriteFile(dir / "long", lines + std::string(64u << 20, ','));
  const std::uint64_t before = BytesReadSoFar();
  const std::string message = ErrorOf(dir / "long", limits);
  const std::uint64_t read_bytes = BytesReadSoFar() - before;
  EXPECT_NE(message.find(":" + std::to_string(short_lines) + ": a line longer than 4.0 KiB"),
            std::string::npos)
      << message;
  // The short lines, the bound and at most one more chunk: not the 64 MiB.
  EXPECT_LT(read_bytes, lines.size() + (2u << 20)) << message;
}

TEST(TextEscape, ControlCharactersInvalidUtf8AndBidiAreEscaped) {
  EXPECT_EQ(EscapeText("plain ASCII, ümlaut, 日本"), "plain ASCII, ümlaut, 日本");
  EXPECT_EQ(EscapeText("a\nb\tc\rd"), "a\\nb\\tc\\rd");
  EXPECT_EQ(EscapeText("\x1b[31mred"), "\\x1B[31mred");
  EXPECT_EQ(EscapeText("\x7f"), "\\x7F");
  EXPECT_EQ(EscapeText("bad\xff\xfe"), "bad\\xFF\\xFE");
  EXPECT_EQ(EscapeText("\xc2\x85"), "\\u0085");          // C1 control
  EXPECT_EQ(EscapeText("\xe2\x80\xae"), "\\u202E");      // right-to-left override
  EXPECT_EQ(EscapeText("\xc0\xaf"), "\\xC0\\xAF");       // overlong '/'
  EXPECT_EQ(EscapeText("\xed\xa0\x80"), "\\xED\\xA0\\x80");  // surrogate
  EXPECT_EQ(EscapeText("\xe6\x97"), "\\xE6\\x97");       // cut sequence
  const std::string once = EscapeText("x\n\xff");
  EXPECT_EQ(EscapeText(once), once);  // idempotent
  EXPECT_TRUE(IsValidUtf8(once));
}

TEST(TextEscape, JsonKeepsControlsButNeverInvalidUtf8) {
  EXPECT_EQ(ToValidUtf8("a\nb"), "a\nb");
  EXPECT_EQ(ToValidUtf8("a\xff" "b"), "a\\xFFb");
  EXPECT_TRUE(IsValidUtf8(ToValidUtf8("\xf4\x90\x80\x80")));  // above U+10FFFF
}

TEST(TextEscape, InvalidUtf8AtNamesTheFirstBadByte) {
  EXPECT_EQ(InvalidUtf8At("plain ascii"), std::string_view::npos);
  EXPECT_EQ(InvalidUtf8At("caf\xC3\xA9"), std::string_view::npos);
  EXPECT_EQ(InvalidUtf8At("caf\xE9"), 3u);                // Latin-1
  EXPECT_EQ(InvalidUtf8At("ab\xC0\xAF"), 2u);             // overlong '/'
  EXPECT_EQ(InvalidUtf8At("x\xED\xA0\x80"), 1u);         // a surrogate
  EXPECT_EQ(InvalidUtf8At("\xE6\x97"), 0u);               // cut short
}

TEST(TextEscape, ExcerptIsShortAndSaysHowLong) {
  EXPECT_EQ(Excerpt("short"), "short");
  const std::string excerpt = Excerpt(std::string(200 << 20, 'y'));
  EXPECT_EQ(excerpt, std::string(40, 'y') + "... (209715200 bytes)");
  // Cut at a character boundary, never inside a UTF-8 sequence.
  const std::string cut = Excerpt(std::string(39, 'a') + "日本", 40);
  EXPECT_TRUE(IsValidUtf8(cut)) << cut;
}

}  // namespace
}  // namespace lifmcr
