#pragma once
// XXH64 (the 64-bit hash of xxHash, Yann Collet's published algorithm
// specification, seed 0), the checksum of every output file a batch unit
// writes (batch/manifest.h). Chosen over SHA-256 because the manifest guards
// against torn and truncated writes and changed files, not against an
// attacker, and a unit's outputs (an R32 depth unit writes several hundred MB
// of TIFFs) must hash in a small fraction of the unit's time: XXH64 runs at
// memory speed, SHA-256 in plain C++ at a few hundred MB/s. The digests are
// the ones `xxhsum -H1` prints (tests/batch/test_checksum.cpp compares).

#include "config/error.h"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace lifmcr::batch {

// Streaming XXH64: Update any number of times, then Digest (which does not
// change the state, so Update may go on).
class Xxh64 {
 public:
  explicit Xxh64(std::uint64_t seed = 0);
  void Update(const void* data, std::size_t size);
  std::uint64_t Digest() const;

 private:
  std::uint64_t v_[4];
  std::uint64_t seed_;
  std::uint64_t total_ = 0;
  unsigned char buffer_[32];
  std::size_t buffered_ = 0;
};

// XXH64 of one buffer.
std::uint64_t Xxh64Of(const void* data, std::size_t size, std::uint64_t seed = 0);

// 16 lower-case hex digits, as xxhsum prints it.
std::string Xxh64Hex(std::uint64_t digest);

struct FileDigest {
  std::uint64_t bytes = 0;
  std::string xxh64;  // Xxh64Hex of the content
};

// Size and XXH64 of a regular file's content, read in 1 MiB blocks; an error
// names the file and what failed.
Expected<FileDigest> DigestFile(const std::filesystem::path& path);

}  // namespace lifmcr::batch
