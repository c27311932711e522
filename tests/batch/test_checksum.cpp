// XXH64 against the digests `xxhsum -H1` (Debian package xxhash) printed for
// the same bytes, the streaming form against the one-shot one at every split,
// and the atomic writer (batch/atomic_file.h).

#include "batch/atomic_file.h"
#include "batch/checksum.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace lifmcr::batch {
namespace {

std::vector<unsigned char> Pattern(std::size_t n) {
  std::vector<unsigned char> bytes(n);
  for (std::size_t i = 0; i < n; ++i) bytes[i] = static_cast<unsigned char>((i * 7 + 3) & 255);
  return bytes;
}

TEST(Checksum, Xxh64MatchesXxhsum) {
  EXPECT_EQ(Xxh64Hex(Xxh64Of("", 0)), "ef46db3751d8e999");
  EXPECT_EQ(Xxh64Hex(Xxh64Of("a", 1)), "d24ec4f1a98c6e5b");
  EXPECT_EQ(Xxh64Hex(Xxh64Of("abc", 3)), "44bc2cf5ad770999");
  const std::vector<unsigned char> p37 = Pattern(37), p1000 = Pattern(1000);
  EXPECT_EQ(Xxh64Hex(Xxh64Of(p37.data(), p37.size())), "e32ef63802f5a3fd");
  EXPECT_EQ(Xxh64Hex(Xxh64Of(p1000.data(), p1000.size())), "5f235fa033f1a3fb");
}

TEST(Checksum, StreamingEqualsOneShotAtEverySplit) {
  const std::vector<unsigned char> bytes = Pattern(200);
  const std::uint64_t whole = Xxh64Of(bytes.data(), bytes.size());
  for (std::size_t a = 0; a <= bytes.size(); a += 3)
    for (std::size_t b = a; b <= bytes.size(); b += 17) {
      Xxh64 h;
      h.Update(bytes.data(), a);
      h.Update(bytes.data() + a, b - a);
      h.Update(bytes.data() + b, bytes.size() - b);
      ASSERT_EQ(h.Digest(), whole) << "split at " << a << ", " << b;
    }
}

TEST(Checksum, DigestFileAndAtomicWrite) {
  test::TempDir dir;
  const std::vector<unsigned char> p1000 = Pattern(1000);
  const std::string content(p1000.begin(), p1000.end());
  ASSERT_TRUE(WriteFileAtomically(dir / "sub/v.bin", content));
  Expected<FileDigest> d = DigestFile(dir / "sub/v.bin");
  ASSERT_TRUE(d) << d.error().message;
  EXPECT_EQ(d->bytes, 1000u);
  EXPECT_EQ(d->xxh64, "5f235fa033f1a3fb");
  // Overwritten whole; no temporary file left beside it.
  ASSERT_TRUE(WriteFileAtomically(dir / "sub/v.bin", "abc"));
  EXPECT_EQ(DigestFile(dir / "sub/v.bin")->xxh64, "44bc2cf5ad770999");
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir / "sub"))
    files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  Expected<FileDigest> missing = DigestFile(dir / "nope.bin");
  ASSERT_FALSE(missing);
  test::ExpectMessageHas(missing.error(), {"nope.bin", "cannot open"});
}

}  // namespace
}  // namespace lifmcr::batch
