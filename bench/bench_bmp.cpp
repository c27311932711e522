// Reading one raw R32 frame (6560x4948) from BMP: ReadBmpInto into a
// preallocated (pooled) buffer against two baselines measured in the same run:
//   read()  one read of the whole file into a buffer of the file's size: the
//           page-cache-to-memory bandwidth bound for any reader;
//   naive   fopen + per-row fread into a row buffer + memcpy into the image,
//           what a straightforward reader does.
// The page cache is warm (every file is read once before timing), so the
// figures are memory bandwidth, not disk. Each figure is the median of
// several runs (the readers take turns within each run), in MB/s of file bytes (1 MB = 1e6 bytes).
//
// Usage: bench_bmp [runs (default 9)] [folder for the temporary files (default /tmp)]

#include "bench/bench_usage.h"
#include "replay/bmp.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <functional>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

using lifmcr::BmpHeader;
using lifmcr::ImageView;
using lifmcr::OwnedImage;
using lifmcr::PixelFormat;

constexpr int kR32Width = 6560;
constexpr int kR32Height = 4948;

struct Case {
  const char* name;
  PixelFormat format;
  bool top_down;
};

// Times every reader once per run, in turn, so that load from other
// processes on a shared machine falls on all of them alike; returns the
// median seconds of each, or an empty vector when a reader failed.
std::vector<double> InterleavedMedians(int runs,
                                       const std::vector<std::function<bool()>>& readers) {
  std::vector<std::vector<double>> seconds(readers.size());
  for (int r = 0; r < runs; ++r) {
    for (std::size_t i = 0; i < readers.size(); ++i) {
      const auto start = std::chrono::steady_clock::now();
      if (!readers[i]()) return {};
      seconds[i].push_back(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
  }
  std::vector<double> medians;
  for (std::vector<double>& s : seconds) {
    std::sort(s.begin(), s.end());
    medians.push_back(s[s.size() / 2]);
  }
  return medians;
}

bool ReadWholeFile(const std::filesystem::path& path, std::vector<std::uint8_t>& buffer) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  std::size_t done = 0;
  while (done < buffer.size()) {
    const ssize_t got = ::read(fd, buffer.data() + done, buffer.size() - done);
    if (got <= 0) break;
    done += static_cast<std::size_t>(got);
  }
  ::close(fd);
  return done == buffer.size();
}

bool ReadNaive(const std::filesystem::path& path, const BmpHeader& header, ImageView dst) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return false;
  bool ok = std::fseek(file, static_cast<long>(header.pixel_offset), SEEK_SET) == 0;
  std::vector<std::uint8_t> row(header.file_row_bytes);
  for (int r = 0; ok && r < header.height; ++r) {
    ok = std::fread(row.data(), 1, row.size(), file) == row.size();
    const int y = header.top_down ? r : header.height - 1 - r;
    if (ok) std::memcpy(dst.Row(y), row.data(), dst.RowBytes());
  }
  std::fclose(file);
  return ok;
}

void Fill(OwnedImage& image) {
  std::uint32_t state = 2463534242u;
  for (auto& value : image.pixels) {
    state ^= state << 13;
    state ^= state >> 17;
    state ^= state << 5;
    value = static_cast<std::uint8_t>(state);
  }
}

double MBps(std::size_t bytes, double seconds) { return bytes / 1e6 / seconds; }

}  // namespace

constexpr char kUsage[] =
    "usage: bench_bmp [RUNS (default 9)] [DIR for the temporary files (default /tmp)]\n"
    "Reads one raw R32 frame (6560x4948) from BMP with ReadBmpInto into a pooled buffer,\n"
    "against one read() of the whole file and a naive per-row fread reader, page cache warm;\n"
    "prints the median MB/s of each and the ratios (bench/README.md).\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 9;
  const std::filesystem::path base = argc > 2 ? argv[2] : "/tmp";
  std::string pattern = (base / "lifmcr_bench_bmp_XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    std::fprintf(stderr, "cannot create a temporary folder under %s\n", base.c_str());
    return 1;
  }
  const std::filesystem::path dir = pattern;

  std::printf("bench_bmp: one R32 frame %dx%d, median of %d runs, page cache warm\n", kR32Width,
              kR32Height, runs);
  std::printf("%-16s %8s | %10s %10s %10s %10s | %9s %9s\n", "case", "file MB", "read()", "naive",
              "Into", "Hdr+Into", "Into/read", "Into/naive");
  std::printf("%-16s %8s | %10s %10s %10s %10s | %9s %9s\n", "", "", "MB/s", "MB/s", "MB/s", "MB/s",
              "", "");

  const Case cases[] = {{"Mono8 bottom-up", PixelFormat::kMono8, false},
                        {"Mono8 top-down", PixelFormat::kMono8, true},
                        {"BGR8 bottom-up", PixelFormat::kBgr8, false}};
  int status = 0;
  for (const Case& c : cases) {
    OwnedImage source = OwnedImage::Allocate(kR32Width, kR32Height, c.format);
    Fill(source);
    const auto path =
        dir / (std::string(c.name).substr(0, 5) + (c.top_down ? "_td" : "_bu") + ".bmp");
    if (lifmcr::Status written = lifmcr::WriteBmp(path, source.View(), c.top_down); !written.ok()) {
      std::fprintf(stderr, "%s\n", written.error().message.c_str());
      status = 1;
      break;
    }
    lifmcr::Expected<BmpHeader> header = lifmcr::ReadBmpHeader(path);
    if (!header.ok()) {
      std::fprintf(stderr, "%s\n", header.error().message.c_str());
      status = 1;
      break;
    }
    const std::size_t file_bytes = header->file_size;
    std::vector<std::uint8_t> whole(file_bytes);
    OwnedImage into = OwnedImage::Allocate(kR32Width, kR32Height, c.format);
    OwnedImage naive = OwnedImage::Allocate(kR32Width, kR32Height, c.format);

    // Warm the page cache and fault every buffer page in before timing.
    const bool warm = ReadWholeFile(path, whole) && ReadNaive(path, *header, naive.View()) &&
                      lifmcr::ReadBmpInto(path, *header, into.View()).ok();
    if (!warm || into.pixels != source.pixels || naive.pixels != source.pixels) {
      std::fprintf(stderr, "%s: a reader returned wrong pixels\n", c.name);
      status = 1;
      break;
    }

    const std::vector<double> t = InterleavedMedians(
        runs, {[&] { return ReadWholeFile(path, whole); },
               [&] { return ReadNaive(path, *header, naive.View()); },
               [&] { return lifmcr::ReadBmpInto(path, *header, into.View()).ok(); },
               [&] {
                 lifmcr::Expected<BmpHeader> h = lifmcr::ReadBmpHeader(path);
                 return h.ok() && lifmcr::ReadBmpInto(path, *h, into.View()).ok();
               }});
    if (t.empty()) {
      std::fprintf(stderr, "%s: a timed read failed\n", c.name);
      status = 1;
      break;
    }
    const double t_read = t[0], t_naive = t[1], t_into = t[2], t_header_into = t[3];
    if (into.pixels != source.pixels) {
      std::fprintf(stderr, "%s: ReadBmpInto returned wrong pixels\n", c.name);
      status = 1;
      break;
    }
    std::printf("%-16s %8.1f | %10.0f %10.0f %10.0f %10.0f | %9.2f %9.2f\n", c.name,
                file_bytes / 1e6, MBps(file_bytes, t_read), MBps(file_bytes, t_naive),
                MBps(file_bytes, t_into), MBps(file_bytes, t_header_into), t_read / t_into,
                t_naive / t_into);
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  }
  std::printf(
      "Into/read: speed of ReadBmpInto relative to the bandwidth bound (1.00 = as fast);\n"
      "Into/naive: its speed-up over the per-row fread+memcpy reader.\n");
  std::error_code ignored;
  std::filesystem::remove_all(dir, ignored);
  return status;
}
